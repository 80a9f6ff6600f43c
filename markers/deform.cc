#include "markers/deform.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "core/error.h"
#include "core/geometry.h"

namespace bodymodel {
namespace {

using Quadratic = Eigen::Matrix<double, 10, 1>;

Quadratic quadratic_vector(const Eigen::Vector3d& p) {
  Quadratic q;
  q << p.x(), p.y(), p.z(), p.x() * p.x(), p.y() * p.y(), p.z() * p.z(), p.x() * p.y(), p.y() * p.z(),
      p.z() * p.x(), 1;
  return q;
}

Eigen::Matrix<double, 3, 10> identity_quadratic() {
  Eigen::Matrix<double, 3, 10> A = Eigen::Matrix<double, 3, 10>::Zero();
  A.leftCols<3>().setIdentity();
  return A;
}

void check_weights(const Eigen::MatrixXd& W, Eigen::Index rows, Eigen::Index parts, const std::string& what) {
  if (W.rows() != rows || W.cols() != parts)
    throw InputError(what + " weights must be " + std::to_string(rows) + " by " + std::to_string(parts) + ", found " +
                     std::to_string(W.rows()) + " by " + std::to_string(W.cols()));
  for (Eigen::Index i = 0; i < W.rows(); ++i)
    for (Eigen::Index p = 0; p < W.cols(); ++p)
      if (!std::isfinite(W(i, p)) || W(i, p) < 0)
        throw InputError(what + " " + std::to_string(i) + ": weight for part " + std::to_string(p) +
                         " is negative or not finite");
}

// The markers of part p: weight ≥ membership or their largest weight; at least min_members (the
// nearest to the part's weighted vertex centroid are added).
std::vector<int> part_members(const Eigen::MatrixX3d& markers, const Eigen::MatrixXd& mw, int p,
                              const Eigen::Vector3d& centroid, const MarkerSkinOptions& o) {
  std::vector<int> members;
  for (int i = 0; i < markers.rows(); ++i) {
    Eigen::Index best = 0;
    mw.row(i).maxCoeff(&best);
    if (mw(i, p) >= o.membership || (best == p && mw(i, p) > 0)) members.push_back(i);
  }
  if (static_cast<int>(members.size()) >= o.min_members) return members;
  std::vector<int> order(static_cast<size_t>(markers.rows()));
  std::iota(order.begin(), order.end(), 0);
  auto dist = [&](int i) { return (markers.row(i).transpose() - centroid).squaredNorm(); };
  std::sort(order.begin(), order.end(), [&](int a, int b) { return dist(a) < dist(b); });
  for (int i : order) {
    if (static_cast<int>(members.size()) >= o.min_members) break;
    if (std::find(members.begin(), members.end(), i) == members.end()) members.push_back(i);
  }
  return members;
}

// The part's local reference frame (§5.3) and its dilation factor.
void part_frame(MarkerSkinPart& part, const Eigen::MatrixX3d& markers, double dilation) {
  const int m = static_cast<int>(part.members.size());
  Eigen::MatrixX3d P(m, 3);
  for (int k = 0; k < m; ++k) P.row(k) = markers.row(part.members[static_cast<size_t>(k)]);
  part.origin = P.colwise().mean().transpose();
  const Eigen::MatrixX3d C = P.rowwise() - part.origin.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(C.transpose() * C);
  part.axes = eig.eigenvectors().transpose();
  if (part.axes.determinant() < 0) part.axes.row(0) *= -1;
  part.member_local = C * part.axes.transpose();
  part.scale = std::max(std::sqrt(C.rowwise().squaredNorm().mean()), 1e-12);
  double largest = 0;
  for (int a = 0; a < m; ++a) {
    double nearest = std::numeric_limits<double>::infinity();
    for (int b = 0; b < m; ++b)
      if (a != b) nearest = std::min(nearest, (P.row(a) - P.row(b)).norm());
    largest = std::max(largest, nearest);
  }
  part.dilation = std::max(dilation * largest, 1e-12);
}

// The vertex weights (#V by parts kept, rows summing to one) without the parts that have no marker
// within reach × dilation of the vertex: a quadratic far outside its markers extrapolates wildly
// (an SSD rig may give a vertex small weights on distant bones). A vertex no part reaches keeps the
// part whose nearest member is nearest in units of its dilation.
Eigen::MatrixXd reachable_weights(const MarkerSkin& skin, const Eigen::MatrixX3d& rest, const Eigen::MatrixXd& vertex_weights,
                                  const std::vector<Eigen::Index>& index, double reach) {
  Eigen::MatrixXd W = Eigen::MatrixXd::Zero(rest.rows(), static_cast<Eigen::Index>(index.size()));
  for (Eigen::Index j = 0; j < rest.rows(); ++j) {
    double best = std::numeric_limits<double>::infinity();
    Eigen::Index nearest = 0;
    for (size_t q = 0; q < index.size(); ++q) {
      const double w = vertex_weights(j, index[q]);
      if (!(w > 0)) continue;
      const MarkerSkinPart& part = skin.parts[q];
      const Eigen::Vector3d local = part.axes * (rest.row(j).transpose() - part.origin);
      const double d = std::sqrt((part.member_local.rowwise() - local.transpose()).rowwise().squaredNorm().minCoeff()) / part.dilation;
      if (!(reach > 0) || d <= reach) W(j, static_cast<Eigen::Index>(q)) = w;
      if (d < best) best = d, nearest = static_cast<Eigen::Index>(q);
    }
    if (!(W.row(j).sum() > 0)) W(j, nearest) = 1;
    W.row(j) /= W.row(j).sum();
  }
  return W;
}

}  // namespace

double cubic_bspline(double r) {
  r = std::abs(r);
  if (r < 1) return (4 - 6 * r * r + 3 * r * r * r) / 6;
  if (r < 2) return (2 - r) * (2 - r) * (2 - r) / 6;
  return 0;
}

MarkerSkin build_marker_skin(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3d& reference_markers,
                             const Eigen::MatrixXd& vertex_weights, const Eigen::MatrixXd& marker_weights,
                             const MarkerSkinOptions& o) {
  const Eigen::Index P = vertex_weights.cols();
  check_weights(vertex_weights, rest.rows(), P, "vertex");
  check_weights(marker_weights, reference_markers.rows(), P, "marker");
  if (o.min_members < 3 || reference_markers.rows() < o.min_members)
    throw InputError("markers: need at least " + std::to_string(std::max(o.min_members, 3)) + " markers, found " +
                     std::to_string(reference_markers.rows()));
  if (!rest.allFinite() || !reference_markers.allFinite())
    throw InputError("markers: the reference mesh and markers must be finite");
  MarkerSkin skin;
  skin.vertex_count = static_cast<int>(rest.rows());
  skin.marker_count = static_cast<int>(reference_markers.rows());
  skin.quadratic_ridge = o.quadratic_ridge;
  skin.rbf_ridge = o.rbf_ridge;
  skin.rbf_min_confidence = o.rbf_min_confidence;
  skin.outlier_factor = o.outlier_factor;
  skin.outlier_floor = o.outlier_floor;
  for (Eigen::Index j = 0; j < rest.rows(); ++j)
    if (!(vertex_weights.row(j).sum() > 0)) throw InputError("vertex " + std::to_string(j) + " has no part weight");
  std::vector<Eigen::Index> index;  // the parts kept (those with vertices)
  for (Eigen::Index p = 0; p < P; ++p) {
    if (!(vertex_weights.col(p).maxCoeff() > 0)) continue;
    MarkerSkinPart part;
    const Eigen::Vector3d centroid = (vertex_weights.col(p).transpose() * rest).transpose() / vertex_weights.col(p).sum();
    part.members = part_members(reference_markers, marker_weights, static_cast<int>(p), centroid, o);
    part_frame(part, reference_markers, o.dilation);
    skin.parts.push_back(std::move(part));
    index.push_back(p);
  }
  const Eigen::MatrixXd W = reachable_weights(skin, rest, vertex_weights, index, o.reach);
  for (size_t q = 0; q < skin.parts.size(); ++q) {
    MarkerSkinPart& part = skin.parts[q];
    for (Eigen::Index j = 0; j < rest.rows(); ++j)
      if (W(j, static_cast<Eigen::Index>(q)) > 0) part.vertices.push_back(static_cast<int>(j));
    const Eigen::Index n = static_cast<Eigen::Index>(part.vertices.size());
    part.vertex_weight.resize(n);
    part.vertex_local.resize(n, 3);
    for (Eigen::Index k = 0; k < n; ++k) {
      const int j = part.vertices[static_cast<size_t>(k)];
      part.vertex_weight(k) = W(j, static_cast<Eigen::Index>(q));
      part.vertex_local.row(k) = (part.axes * (rest.row(j).transpose() - part.origin)).transpose();
    }
  }
  return skin;
}

namespace {

// Eq. 6 with weights and a ridge towards the identity: A = (LᵀWQ + μ I₀)(QᵀWQ + μ I)⁻¹.
Eigen::Matrix<double, 3, 10> fit_quadratic(const Eigen::MatrixXd& Q, const Eigen::MatrixX3d& local,
                                           const Eigen::VectorXd& w, double ridge) {
  Eigen::Matrix<double, 10, 10> H = Q.transpose() * w.asDiagonal() * Q;
  const double mu = ridge * std::max(H.trace() / 10, 1e-12);
  H.diagonal().array() += mu;
  const Eigen::Matrix<double, 10, 3> rhs = Q.transpose() * w.asDiagonal() * local + mu * identity_quadratic().transpose();
  return H.ldlt().solve(rhs).transpose();
}

// Eq. 7 over the members with w > 0 (the inliers, and with a confidence, those trusted enough): RBF
// weights interpolating the residual there (exactly when the ridge is 0); the others get none. A
// member's ridge is divided by its confidence c: a less certain residual is followed less closely.
Eigen::MatrixX3d fit_rbf(const MarkerSkinPart& part, const Eigen::MatrixX3d& residual, const Eigen::VectorXd& w,
                         const Eigen::VectorXd& c, double ridge) {
  std::vector<Eigen::Index> in;
  for (Eigen::Index k = 0; k < w.size(); ++k)
    if (w(k) > 0) in.push_back(k);
  const auto n = static_cast<Eigen::Index>(in.size());
  if (n == 0) return Eigen::MatrixX3d::Zero(w.size(), 3);
  Eigen::MatrixXd Phi(n, n), R(n, 3);
  for (Eigen::Index a = 0; a < n; ++a) {
    R.row(a) = residual.row(in[static_cast<size_t>(a)]);
    for (Eigen::Index b = 0; b < n; ++b)
      Phi(a, b) = cubic_bspline(
          (part.member_local.row(in[static_cast<size_t>(a)]) - part.member_local.row(in[static_cast<size_t>(b)])).norm() /
          part.dilation);
  }
  for (Eigen::Index a = 0; a < n; ++a) Phi(a, a) += ridge / c(in[static_cast<size_t>(a)]);
  const Eigen::MatrixXd sol = Phi.completeOrthogonalDecomposition().solve(R);
  Eigen::MatrixX3d out = Eigen::MatrixX3d::Zero(w.size(), 3);
  for (Eigen::Index a = 0; a < n; ++a) out.row(in[static_cast<size_t>(a)]) = sol.row(a);
  return out;
}

}  // namespace

Eigen::VectorXd inlier_weights(const Eigen::VectorXd& r, double factor, double floor) {
  Eigen::VectorXd w = Eigen::VectorXd::Ones(r.size());
  if (!(factor > 0) || r.size() < 4) return w;
  std::vector<double> s(r.data(), r.data() + r.size());
  std::nth_element(s.begin(), s.begin() + static_cast<long>(s.size() / 2), s.end());
  const double limit = std::max(factor * s[s.size() / 2], floor);
  for (Eigen::Index i = 0; i < r.size(); ++i) w(i) = r(i) <= limit ? 1 : 0;
  return w.sum() >= 3 ? w : Eigen::VectorXd::Ones(r.size());
}

RigidMotion fit_rigid_robust(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B, double factor, double floor,
                             Eigen::VectorXd* weights, const Eigen::VectorXd& prior) {
  const Eigen::VectorXd c = prior.size() == A.rows() ? prior : Eigen::VectorXd::Ones(A.rows());
  Eigen::VectorXd w = Eigen::VectorXd::Ones(A.rows());
  RigidMotion g = fit_rigid_motion(A, B, c);
  for (int round = 0; round < 3 && factor > 0; ++round) {
    const Eigen::VectorXd next = inlier_weights((apply(g, A) - B).rowwise().norm(), factor, floor);
    if (next == w) break;
    w = next;
    g = fit_rigid_motion(A, B, w.cwiseProduct(c));
  }
  if (weights) *weights = w;
  return g;
}

namespace {

// A part's rigid and quadratic fit in one frame, before the RBF: the members weighed by their
// confidence c, the outliers (w = 0) left out; each member's residual in local / scale units.
struct PartFit {
  PartMotion motion;
  Eigen::MatrixX3d residual;
  Eigen::VectorXd w, c;
};

PartFit fit_part(const MarkerSkinPart& part, const Eigen::MatrixX3d& markers, MarkerSkinStage stage, const MarkerSkin& skin,
                 const Eigen::VectorXd& confidence) {
  const Eigen::Index m = static_cast<Eigen::Index>(part.members.size());
  Eigen::MatrixX3d C(m, 3);
  Eigen::MatrixXd Q(m, 10);
  PartFit out;
  out.c = Eigen::VectorXd::Ones(m);
  for (Eigen::Index k = 0; k < m; ++k) {
    C.row(k) = markers.row(part.members[static_cast<size_t>(k)]);
    if (confidence.size()) out.c(k) = confidence(part.members[static_cast<size_t>(k)]);
    Q.row(k) = quadratic_vector(part.member_local.row(k).transpose() / part.scale).transpose();
  }
  // Markers that the part's motion does not explain (a wrong merge or a bad fill of the cleaning)
  // are left out of the fits, a few rounds (our addition; the paper's markers are checked by hand).
  out.w = Eigen::VectorXd::Ones(m);
  out.motion = {Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), identity_quadratic(), Eigen::MatrixX3d::Zero(m, 3)};
  for (int round = 0; round < 4; ++round) {
    const RigidMotion g = fit_rigid_motion(C, part.member_local, out.w.cwiseProduct(out.c));
    out.motion.R = g.R, out.motion.t = g.t;
    const Eigen::MatrixX3d local = apply(g, C) / part.scale;
    if (stage != MarkerSkinStage::rigid) out.motion.A = fit_quadratic(Q, local, out.w.cwiseProduct(out.c), skin.quadratic_ridge);
    out.residual = local - Q * out.motion.A.transpose();
    const Eigen::VectorXd next = inlier_weights(out.residual.rowwise().norm() * part.scale, skin.outlier_factor,
                                                skin.outlier_floor * part.scale);
    if (next == out.w) break;
    out.w = next;
  }
  return out;
}

void add_part(Eigen::MatrixX3d& V, const MarkerSkinPart& part, const PartMotion& m) {
  for (size_t k = 0; k < part.vertices.size(); ++k) {
    const auto kk = static_cast<Eigen::Index>(k);
    V.row(part.vertices[k]) += part.vertex_weight(kk) * part_position(part, m, part.vertex_local.row(kk).transpose()).transpose();
  }
}

}  // namespace

PartMotion fit_part_motion(const MarkerSkinPart& part, const Eigen::MatrixX3d& markers, MarkerSkinStage stage,
                           const MarkerSkin& skin, const Eigen::VectorXd& confidence) {
  PartFit f = fit_part(part, markers, stage, skin, confidence);
  // A filled marker far from a seen sample is not interpolated: its residual is the cleaning's
  // error more than the skin's.
  if (stage == MarkerSkinStage::full)
    f.motion.rbf = fit_rbf(part, f.residual, (f.c.array() < skin.rbf_min_confidence).select(0.0, f.w), f.c, skin.rbf_ridge);
  return f.motion;
}

Eigen::Vector3d part_position(const MarkerSkinPart& part, const PartMotion& m, const Eigen::Vector3d& local) {
  Eigen::Vector3d x = m.A * quadratic_vector(local / part.scale);
  for (Eigen::Index k = 0; k < m.rbf.rows(); ++k) {
    const double phi = cubic_bspline((local - part.member_local.row(k).transpose()).norm() / part.dilation);
    if (phi != 0) x += phi * m.rbf.row(k).transpose();
  }
  return m.R.transpose() * (part.scale * x - m.t);
}

void check_confidence(const Eigen::VectorXd& confidence, Eigen::Index markers) {
  if (confidence.size() == 0) return;
  if (confidence.size() != markers)
    throw InputError("markers: " + std::to_string(confidence.size()) + " confidences given for " + std::to_string(markers) + " markers");
  for (Eigen::Index i = 0; i < confidence.size(); ++i)
    if (!(confidence(i) > 0 && confidence(i) <= 1))
      throw InputError("markers: the confidence of marker " + std::to_string(i) + " is " + std::to_string(confidence(i)) +
                       ", not in (0, 1]");
}

Eigen::MatrixX3d deform_by_markers(const MarkerSkin& skin, const Eigen::MatrixX3d& markers, MarkerSkinStage stage,
                                   const Eigen::VectorXd& confidence) {
  if (markers.rows() != skin.marker_count)
    throw InputError("markers: " + std::to_string(markers.rows()) + " markers given, the skin was built with " +
                     std::to_string(skin.marker_count));
  if (!markers.allFinite()) throw InputError("markers: every marker must be present (clean the capture first)");
  check_confidence(confidence, markers.rows());
  Eigen::MatrixX3d V = Eigen::MatrixX3d::Zero(skin.vertex_count, 3);
  for (const MarkerSkinPart& part : skin.parts) {
    add_part(V, part, fit_part_motion(part, markers, stage, skin, confidence));
  }
  return V;
}

}  // namespace bodymodel
