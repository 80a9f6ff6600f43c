#include "skinning/pose_space.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <sstream>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "skinning/fit_lbs.h"

namespace bodymodel {

PoseSpaceMethod parse_pose_space_method(const std::string& name) {
  if (name == "psd") return PoseSpaceMethod::psd;
  if (name == "eigenskin") return PoseSpaceMethod::eigenskin;
  if (name == "quadratic") return PoseSpaceMethod::quadratic;
  throw InputError("unknown pose-space method '" + name + "' (expected psd, eigenskin or quadratic)");
}

std::string pose_space_method_name(PoseSpaceMethod m) {
  switch (m) {
    case PoseSpaceMethod::psd: return "psd";
    case PoseSpaceMethod::eigenskin: return "eigenskin";
    case PoseSpaceMethod::quadratic: return "quadratic";
  }
  return "?";
}

bool is_pose_space_method(const std::string& name) {
  return name == "psd" || name == "eigenskin" || name == "quadratic";
}

std::string PoseSpaceFitSummary::brief() const {
  std::ostringstream s;
  s << pose_space_method_name(method) << " fit: " << vertices << " vertices, " << poses << " poses";
  if (method == PoseSpaceMethod::eigenskin) s << ", " << groups << " neighbourhoods, " << mean_modes << " modes on average";
  if (method == PoseSpaceMethod::quadratic) s << ", " << groups << " parts";
  s << "; residual RMS " << rms_residual << ", max " << max_residual << "; " << seconds << " s";
  return s.str();
}

namespace {

constexpr int kQ = 10;         // quadratic vector length (Park's 9 plus a constant, see the header)
constexpr int kA = 3 * kQ;     // entries of A
using Vec9 = Eigen::Matrix<double, 1, 9>;
using VecQ = Eigen::Matrix<double, 1, kQ>;

// Row-major 3 by 3 → 1 by 9.
Vec9 flat(const Eigen::Matrix3d& R) {
  Vec9 f;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) f(3 * r + c) = R(r, c);
  return f;
}

Vec9 pair_feature(const BoneTransforms& M, int a, int b) {
  return flat(M[static_cast<size_t>(a)].linear().transpose() * M[static_cast<size_t>(b)].linear());
}

// q = [x y z x² y² z² xy yz zx 1] (Park & Hodgins §5.3, plus the constant).
VecQ quadratic_vector(const Eigen::Vector3d& p) {
  VecQ q;
  q << p.x(), p.y(), p.z(), p.x() * p.x(), p.y() * p.y(), p.z() * p.z(), p.x() * p.y(), p.y() * p.z(),
      p.z() * p.x(), 1.0;
  return q;
}

// The slot of the largest weight (the primary bone).
Eigen::Index primary_slot(const SkinningRig& lbs, Eigen::Index i) {
  Eigen::Index best = 0;
  double w = -1;
  for (Eigen::Index k = 0; k < lbs.influences.cols(); ++k)
    if (lbs.influences(i, k) >= 0 && lbs.coefficients(i, k) > w) w = lbs.coefficients(i, k), best = k;
  return best;
}

// Median of the positive entries of the upper triangle of a P by P distance matrix (0 if none).
double median_positive(const Eigen::MatrixXd& D) {
  std::vector<double> v;
  for (Eigen::Index p = 0; p < D.rows(); ++p)
    for (Eigen::Index q = p + 1; q < D.cols(); ++q)
      if (D(p, q) > 1e-12) v.push_back(D(p, q));
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

Eigen::MatrixXd kernel(const Eigen::MatrixXd& D2, double sigma) {
  return (-D2 / (2 * sigma * sigma)).array().exp().matrix();
}

// Factorised (Φ + λI) of one descriptor.
Eigen::LLT<Eigen::MatrixXd> rbf_factor(const Eigen::MatrixXd& D2, double sigma, double ridge) {
  Eigen::MatrixXd Phi = kernel(D2, sigma);
  Phi.diagonal().array() += std::max(ridge, 1e-10);
  Eigen::LLT<Eigen::MatrixXd> llt(Phi);
  if (llt.info() != Eigen::Success) {
    Phi.diagonal().array() += 1e-8 * double(D2.rows());
    llt.compute(Phi);
  }
  return llt;
}

// Squared pose distance of a weighted pair combination: Σ ω G_pair (P by P or 1 by P).
Eigen::MatrixXd combine(const std::vector<Eigen::MatrixXd>& G, const std::vector<int>& pairs,
                        const std::vector<double>& omega, Eigen::Index rows, Eigen::Index cols) {
  Eigen::MatrixXd D2 = Eigen::MatrixXd::Zero(rows, cols);
  for (size_t k = 0; k < pairs.size(); ++k) D2 += omega[k] * G[static_cast<size_t>(pairs[k])];
  return D2;
}

// Bones a and b are adjacent (share a "joint") when some vertex has weight ≥ `threshold` on both.
std::vector<std::vector<char>> bone_adjacency(const SkinningRig& lbs, double threshold) {
  const int B = lbs.bone_count;
  std::vector<std::vector<char>> adj(static_cast<size_t>(B), std::vector<char>(static_cast<size_t>(B), 0));
  for (Eigen::Index i = 0; i < lbs.rest.rows(); ++i)
    for (Eigen::Index k = 0; k < lbs.influences.cols(); ++k)
      for (Eigen::Index l = 0; l < lbs.influences.cols(); ++l) {
        const int a = lbs.influences(i, k), b = lbs.influences(i, l);
        if (a >= 0 && b >= 0 && a != b && lbs.coefficients(i, k) >= threshold && lbs.coefficients(i, l) >= threshold)
          adj[static_cast<size_t>(a)][static_cast<size_t>(b)] = 1;
      }
  return adj;
}

// Descriptor of a set of vertices sharing primary bone a (weighted pose space after Kurihara &
// Miyata 2004: a joint counts for a vertex with the vertex's weights on the two bones it joins):
// the pairs (a, b) for every bone b adjacent to a, ω_b = mean over the vertices of w_ia + w_ib.
void descriptor_of(const SkinningRig& lbs, const std::vector<Eigen::Index>& vs, const Eigen::VectorXi& primary,
                   const std::vector<std::vector<char>>& adj, std::map<std::pair<int, int>, int>& pair_index,
                   std::vector<int>* pairs, std::vector<double>* omega) {
  pairs->clear();
  omega->clear();
  if (vs.empty()) return;
  const int a = primary(vs[0]);
  const int B = lbs.bone_count;
  std::vector<double> sum(static_cast<size_t>(B), 0.0);
  for (Eigen::Index i : vs) {
    double wa = 0;
    std::vector<double> w(static_cast<size_t>(B), 0.0);
    for (Eigen::Index k = 0; k < lbs.influences.cols(); ++k)
      if (lbs.influences(i, k) >= 0) w[static_cast<size_t>(lbs.influences(i, k))] += lbs.coefficients(i, k);
    wa = w[static_cast<size_t>(a)];
    for (int b = 0; b < B; ++b)
      if (adj[static_cast<size_t>(a)][static_cast<size_t>(b)]) sum[static_cast<size_t>(b)] += wa + w[static_cast<size_t>(b)];
  }
  for (int b = 0; b < B; ++b) {
    if (!adj[static_cast<size_t>(a)][static_cast<size_t>(b)]) continue;
    auto [it, inserted] = pair_index.emplace(std::make_pair(a, b), static_cast<int>(pair_index.size()));
    pairs->push_back(it->second);
    omega->push_back(sum[static_cast<size_t>(b)] / double(vs.size()));
  }
}

// Blended linear part L = Σ w_k R_k and the SSD position of vertex i.
void ssd_at(const SkinningRig& lbs, Eigen::Index i, const BoneTransforms& M, Eigen::Matrix3d* L, Eigen::Vector3d* x) {
  L->setZero();
  x->setZero();
  const Eigen::Vector3d v = lbs.rest.row(i).transpose();
  for (Eigen::Index k = 0; k < lbs.influences.cols(); ++k) {
    const int b = lbs.influences(i, k);
    if (b < 0) continue;
    const double w = lbs.coefficients(i, k);
    *L += w * M[static_cast<size_t>(b)].linear();
    *x += w * (M[static_cast<size_t>(b)] * v);
  }
}

// Quadratic: the blended position of vertex i for per-part deformations A (#B by 30, row-major
// 3 by 10 per row), parts that do not deform the vertex moving it rigidly.
Eigen::Vector3d quadratic_blend(const PoseSpaceRig& rig, Eigen::Index i, const BoneTransforms& M,
                                const Eigen::MatrixXd& A) {
  const SkinningRig& lbs = rig.base;
  const Eigen::Vector3d v = lbs.rest.row(i).transpose();
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  for (Eigen::Index k = 0; k < lbs.influences.cols(); ++k) {
    const int b = lbs.influences(i, k);
    if (b < 0) continue;
    const double w = lbs.coefficients(i, k);
    if (!rig.member(i, k)) {
      x += w * (M[static_cast<size_t>(b)] * v);
      continue;
    }
    const auto q = rig.vertex_quadratic.row(i).segment<kQ>(kQ * k);
    Eigen::Vector3d local;
    for (int r = 0; r < 3; ++r) local(r) = A.row(b).segment<kQ>(kQ * r).dot(q);
    const Eigen::Vector3d rest_frame = rig.part_centroid.row(b).transpose() +
                                       rig.part_scale(b) * (rig.part_axes[static_cast<size_t>(b)] * local);
    x += w * (M[static_cast<size_t>(b)] * rest_frame);
  }
  return x;
}

// The pose-dependent part of posing: squared feature distances of the new pose to every example,
// per pair (1 by P), and the kernel rows of every neighbourhood.
struct PoseQuery {
  std::vector<Eigen::MatrixXd> g;
  std::vector<Eigen::RowVectorXd> phi;   // per neighbourhood (empty when σ = 0)
};

PoseQuery query_pose(const PoseSpaceRig& rig, const BoneTransforms& M) {
  PoseQuery q;
  const Eigen::Index np = rig.pairs.rows();
  q.g.resize(static_cast<size_t>(np));
  for (Eigen::Index k = 0; k < np; ++k) {
    const Vec9 f = pair_feature(M, rig.pairs(k, 0), rig.pairs(k, 1));
    Eigen::MatrixXd row(1, rig.poses);
    for (int p = 0; p < rig.poses; ++p) row(0, p) = (rig.pair_features.block<1, 9>(k, 9 * p) - f).squaredNorm();
    q.g[static_cast<size_t>(k)] = row;
  }
  const size_t G = rig.group_pairs.size();
  q.phi.resize(G);
  for (size_t g = 0; g < G; ++g) {
    const double sigma = rig.group_sigma(static_cast<Eigen::Index>(g));
    if (sigma > 0) q.phi[g] = kernel(combine(q.g, rig.group_pairs[g], rig.group_omega[g], 1, rig.poses), sigma).row(0);
  }
  return q;
}

// Per-vertex correction from the vertex RBF (mean + Σ φ c), with its neighbourhood's kernel row.
Eigen::Vector3d vertex_correction(const PoseSpaceRig& rig, const PoseQuery& q, Eigen::Index i) {
  Eigen::Vector3d d = rig.vertex_mean.row(i).transpose();
  const Eigen::RowVectorXd& phi = q.phi[static_cast<size_t>(rig.vertex_group(i))];
  if (phi.size() == 0) return d;
  for (int c = 0; c < 3; ++c)
    d(c) += phi.dot(Eigen::Map<const Eigen::VectorXd, 0, Eigen::InnerStride<Eigen::Dynamic>>(
        rig.vertex_coef.data() + i + c * rig.vertex_coef.rows(), rig.poses,
        Eigen::InnerStride<Eigen::Dynamic>(3 * rig.vertex_coef.rows())));
  return d;
}

}  // namespace

void PoseSpaceRig::validate(const std::string& what) const {
  base.validate(what + " (base)");
  if (base.method != SkinningMethod::lbs) throw InputError(what + ": the base rig must be ssd");
  const Eigen::Index n = base.rest.rows(), K = base.influences.cols();
  const int B = base.bone_count;
  if (poses < 1) throw InputError(what + ": no example poses");
  if (pairs.cols() != 2 || pair_features.rows() != pairs.rows() || pair_features.cols() != 9 * poses)
    throw InputError(what + ": pair features must be #pairs by 9·" + std::to_string(poses));
  if (pairs.size() && (pairs.minCoeff() < 0 || pairs.maxCoeff() >= B))
    throw InputError(what + ": a pose-feature pair names a bone outside 0.." + std::to_string(B - 1));
  if (primary.size() != n || vertex_group.size() != n || vertex_mean.rows() != n || vertex_mean.cols() != 3)
    throw InputError(what + ": per-vertex pose-space arrays do not have one row per vertex (" + std::to_string(n) + ")");
  if (primary.size() && (primary.minCoeff() < 0 || primary.maxCoeff() >= B))
    throw InputError(what + ": a primary bone is outside 0.." + std::to_string(B - 1));
  const size_t G = group_pairs.size();
  if (group_omega.size() != G || static_cast<size_t>(group_sigma.size()) != G)
    throw InputError(what + ": neighbourhood arrays disagree in count");
  if (vertex_group.size() && (vertex_group.minCoeff() < 0 || static_cast<size_t>(vertex_group.maxCoeff()) >= G))
    throw InputError(what + ": a vertex names a neighbourhood outside 0.." + std::to_string(static_cast<long>(G) - 1));
  auto check_desc = [&](const std::vector<int>& pp, const std::vector<double>& oo, const std::string& which) {
    if (oo.size() != pp.size()) throw InputError(what + ": " + which + " has pairs and weights of different counts");
    for (size_t k = 0; k < pp.size(); ++k)
      if (pp[k] < 0 || pp[k] >= pairs.rows() || !(oo[k] >= 0) || !std::isfinite(oo[k]))
        throw InputError(what + ": " + which + " names pose-feature pair " + std::to_string(pp[k]) + " with weight " +
                         std::to_string(oo[k]));
  };
  for (size_t g = 0; g < G; ++g)
    check_desc(group_pairs[g], group_omega[g], "neighbourhood " + std::to_string(g));
  if (!pair_features.allFinite() || !group_sigma.allFinite() || !vertex_mean.allFinite() || !vertex_coef.allFinite())
    throw InputError(what + ": pose-space arrays contain NaN or infinity");
  if (method != PoseSpaceMethod::eigenskin && (vertex_coef.rows() != n || vertex_coef.cols() != 3 * poses))
    throw InputError(what + ": vertex RBF coefficients must be #V by 3·" + std::to_string(poses));
  if (method == PoseSpaceMethod::eigenskin) {
    if (group_coef.size() != G || vertex_modes.size() != static_cast<size_t>(n))
      throw InputError(what + ": EigenSkin needs coefficients per neighbourhood and modes per vertex");
    for (size_t g = 0; g < G; ++g)
      if (group_coef[g].rows() != poses || !group_coef[g].allFinite())
        throw InputError(what + ": neighbourhood " + std::to_string(g) + " coefficients must be " +
                         std::to_string(poses) + " finite rows");
    for (Eigen::Index i = 0; i < n; ++i)
      if (vertex_modes[static_cast<size_t>(i)].size() != 3 * group_coef[static_cast<size_t>(vertex_group(i))].cols() ||
          !vertex_modes[static_cast<size_t>(i)].allFinite())
        throw InputError(what + ": vertex " + std::to_string(i) + " modes do not match its neighbourhood's");
  }
  if (method == PoseSpaceMethod::quadratic) {
    if (part_pairs.size() != static_cast<size_t>(B) || part_omega.size() != static_cast<size_t>(B) ||
        part_sigma.size() != B || part_mean.rows() != B || part_mean.cols() != kA ||
        part_coef.size() != static_cast<size_t>(B) || part_centroid.rows() != B ||
        part_axes.size() != static_cast<size_t>(B) || part_scale.size() != B)
      throw InputError(what + ": quadratic parts must be one per bone (" + std::to_string(B) + "), A 3 by 10");
    for (int b = 0; b < B; ++b) {
      check_desc(part_pairs[static_cast<size_t>(b)], part_omega[static_cast<size_t>(b)], "part " + std::to_string(b));
      if (part_coef[static_cast<size_t>(b)].rows() != poses || part_coef[static_cast<size_t>(b)].cols() != kA ||
          !part_coef[static_cast<size_t>(b)].allFinite() || !part_axes[static_cast<size_t>(b)].allFinite())
        throw InputError(what + ": part " + std::to_string(b) + " coefficients must be " + std::to_string(poses) +
                         " by 30, finite");
    }
    if (member.rows() != n || member.cols() != K || vertex_quadratic.rows() != n || vertex_quadratic.cols() != kQ * K ||
        !vertex_quadratic.allFinite() || !part_centroid.allFinite() || !part_scale.allFinite() ||
        !part_mean.allFinite() || !part_sigma.allFinite())
      throw InputError(what + ": quadratic per-vertex arrays must be #V by K and #V by 10·K, finite");
  }
}

namespace {

// What the stages of fit_pose_space share: the inputs, the rig being filled in, and what passes
// from one stage to the next (neighbourhoods, distances between the examples, correction targets).
struct PoseSpaceFit {
  const SkinningExamples& ex;
  const SkinningRig& lbs;
  const PoseSpaceOptions& o;
  PoseSpaceRig& rig;
  Eigen::Index n, K;
  int B, P;
  std::vector<Eigen::Index> primary_slots;                 // per vertex, the slot of its primary bone
  std::vector<std::vector<Eigen::Index>> group_vertices;   // per neighbourhood, its vertices
  std::vector<Eigen::MatrixXd> Gd;                         // per pair, P by P squared example distances
  std::vector<Eigen::MatrixXd> group_D2;                   // per neighbourhood, its combined distances
  Eigen::MatrixXd target;                                  // #V by 3P corrections to interpolate
};

// The argument checks of fit_pose_space, all before any work so a bad call fails at once.
void check_fit_inputs(const SkinningExamples& ex, const SkinningRig& lbs, const PoseSpaceOptions& o,
                      const std::string& who) {
  validate_examples(ex, true);
  if (lbs.method != SkinningMethod::lbs || lbs.vertex_count() != ex.vertex_count() || lbs.bone_count != ex.bone_count())
    throw InputError(who + ": the base rig must be an ssd rig with the examples' " + std::to_string(ex.vertex_count()) +
                     " vertices and " + std::to_string(ex.bone_count()) + " bones");
  const int P = ex.pose_count();
  if (P < 2)
    throw InputError(who + ": needs at least 2 example poses to interpolate between, found " + std::to_string(P));
  if (!(o.kernel_width > 0) || !(o.rbf_ridge >= 0) || !(o.inverse_damping >= 0) || !(o.quadratic_ridge >= 0) ||
      o.eigenskin_modes < 1)
    throw InputError(who + ": kernel width must be > 0, ridges and damping ≥ 0, modes ≥ 1");
}

// Primary bones, the vertex neighbourhoods (primary, second bone if weighty) and, for quadratic,
// the parts, with the pose descriptor of each: the bone pairs the interpolation looks at.
void build_descriptors(PoseSpaceFit& f) {
  const SkinningRig& lbs = f.lbs;
  PoseSpaceRig& rig = f.rig;
  const Eigen::Index n = f.n, K = f.K;
  std::map<std::pair<int, int>, int> pair_index;
  f.primary_slots.resize(static_cast<size_t>(n));
  rig.primary.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    f.primary_slots[static_cast<size_t>(i)] = primary_slot(lbs, i);
    rig.primary(i) = lbs.influences(i, f.primary_slots[static_cast<size_t>(i)]);
  }
  // Neighbourhoods: (primary, second bone if weighty).
  {
    std::map<std::pair<int, int>, int> key;
    rig.vertex_group.resize(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      int second = -1;
      double w2 = f.o.neighbourhood_weight;
      for (Eigen::Index k = 0; k < K; ++k)
        if (k != f.primary_slots[static_cast<size_t>(i)] && lbs.influences(i, k) >= 0 && lbs.coefficients(i, k) >= w2)
          w2 = lbs.coefficients(i, k), second = lbs.influences(i, k);
      auto [it, inserted] = key.emplace(std::make_pair(rig.primary(i), second), static_cast<int>(key.size()));
      if (inserted) f.group_vertices.emplace_back();
      f.group_vertices[static_cast<size_t>(it->second)].push_back(i);
      rig.vertex_group(i) = it->second;
    }
  }
  const size_t G = f.group_vertices.size();
  rig.group_pairs.assign(G, {});
  rig.group_omega.assign(G, {});
  const std::vector<std::vector<char>> adj = bone_adjacency(lbs, f.o.neighbourhood_weight);
  for (size_t g = 0; g < G; ++g)
    descriptor_of(lbs, f.group_vertices[g], rig.primary, adj, pair_index, &rig.group_pairs[g], &rig.group_omega[g]);
  std::vector<std::vector<Eigen::Index>> part_vertices;
  if (f.o.method == PoseSpaceMethod::quadratic) {
    part_vertices.assign(static_cast<size_t>(f.B), {});
    for (Eigen::Index i = 0; i < n; ++i) part_vertices[static_cast<size_t>(rig.primary(i))].push_back(i);
    rig.part_pairs.assign(static_cast<size_t>(f.B), {});
    rig.part_omega.assign(static_cast<size_t>(f.B), {});
    for (int b = 0; b < f.B; ++b)
      descriptor_of(lbs, part_vertices[static_cast<size_t>(b)], rig.primary, adj, pair_index,
                    &rig.part_pairs[static_cast<size_t>(b)], &rig.part_omega[static_cast<size_t>(b)]);
  }
  rig.pairs.resize(static_cast<Eigen::Index>(pair_index.size()), 2);
  for (const auto& [ab, k] : pair_index) rig.pairs.row(k) << ab.first, ab.second;
}

// The pair features of every example, their distances per pair, and per neighbourhood the
// combined distances and kernel width: everything the RBFs are built on.
void example_distances(PoseSpaceFit& f) {
  PoseSpaceRig& rig = f.rig;
  const int P = f.P;
  const Eigen::Index np = rig.pairs.rows();
  rig.pair_features.resize(np, 9 * P);
  for (Eigen::Index k = 0; k < np; ++k)
    for (int p = 0; p < P; ++p)
      rig.pair_features.block<1, 9>(k, 9 * p) = pair_feature(f.ex.transforms[static_cast<size_t>(p)], rig.pairs(k, 0),
                                                            rig.pairs(k, 1));
  // Per pair, P by P squared distances between the examples.
  f.Gd.assign(static_cast<size_t>(np), Eigen::MatrixXd::Zero(P, P));
  for (Eigen::Index k = 0; k < np; ++k)
    for (int p = 0; p < P; ++p)
      for (int q = p + 1; q < P; ++q)
        f.Gd[static_cast<size_t>(k)](p, q) = f.Gd[static_cast<size_t>(k)](q, p) =
            (rig.pair_features.block<1, 9>(k, 9 * p) - rig.pair_features.block<1, 9>(k, 9 * q)).squaredNorm();
  const size_t G = f.group_vertices.size();
  f.group_D2.resize(G);
  rig.group_sigma = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(G));
  for (size_t g = 0; g < G; ++g) {
    f.group_D2[g] = combine(f.Gd, rig.group_pairs[g], rig.group_omega[g], P, P);
    rig.group_sigma(static_cast<Eigen::Index>(g)) = f.o.kernel_width * median_positive(f.group_D2[g].cwiseSqrt());
  }
}

// psd and eigenskin targets: pre-skinning displacements d = (LᵀL + εI)⁻¹ Lᵀ (q − SSD) per vertex
// and example, so that skinning the corrected rest vertex reproduces the example.
void displacement_targets(PoseSpaceFit& f) {
  const SkinningExamples& ex = f.ex;
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, f.n, 256), [&](const auto& r) {
    for (Eigen::Index i = r.begin(); i < r.end(); ++i)
      for (int p = 0; p < f.P; ++p) {
        Eigen::Matrix3d L;
        Eigen::Vector3d x;
        ssd_at(f.lbs, i, ex.transforms[static_cast<size_t>(p)], &L, &x);
        const Eigen::Vector3d res = ex.poses[static_cast<size_t>(p)].row(i).transpose() - x;
        const Eigen::Vector3d d =
            (L.transpose() * L + f.o.inverse_damping * Eigen::Matrix3d::Identity()).ldlt().solve(L.transpose() * res);
        f.target.block<1, 3>(i, 3 * p) = d.transpose();
      }
  });
}

// Quadratic: x in part b's frame (centroid, principal axes, RMS radius), where its A acts.
Eigen::Vector3d part_local(const PoseSpaceRig& rig, int b, const Eigen::Vector3d& x) {
  return rig.part_axes[static_cast<size_t>(b)].transpose() * (x - rig.part_centroid.row(b).transpose()) /
         rig.part_scale(b);
}

// Quadratic: the members of each part, the part frames (centroid, principal axes, RMS radius of
// the members in the rest pose) and every member's quadratic vector in its part's frame; returns
// the members per part.
std::vector<std::vector<Eigen::Index>> part_frames(PoseSpaceFit& f) {
  const SkinningRig& lbs = f.lbs;
  const SkinningExamples& ex = f.ex;
  PoseSpaceRig& rig = f.rig;
  const Eigen::Index n = f.n, K = f.K;
  const int B = f.B;
  rig.member = Eigen::MatrixXi::Zero(n, K);
  std::vector<std::vector<Eigen::Index>> members(static_cast<size_t>(B));
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index k = 0; k < K; ++k) {
      const int b = lbs.influences(i, k);
      if (b < 0) continue;
      if (k == f.primary_slots[static_cast<size_t>(i)] || lbs.coefficients(i, k) >= f.o.membership_weight) {
        rig.member(i, k) = 1;
        members[static_cast<size_t>(b)].push_back(i);
      }
    }
  rig.part_centroid = Eigen::MatrixX3d::Zero(B, 3);
  rig.part_axes.assign(static_cast<size_t>(B), Eigen::Matrix3d::Identity());
  rig.part_scale = Eigen::VectorXd::Ones(B);
  for (int b = 0; b < B; ++b) {
    const auto& mem = members[static_cast<size_t>(b)];
    if (mem.empty()) continue;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (Eigen::Index i : mem) c += ex.rest.row(i).transpose();
    c /= double(mem.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (Eigen::Index i : mem) {
      const Eigen::Vector3d d = ex.rest.row(i).transpose() - c;
      cov += d * d.transpose();
    }
    cov /= double(mem.size());
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    Eigen::Matrix3d E = eig.eigenvectors().rowwise().reverse();
    if (E.determinant() < 0) E.col(2) *= -1;
    rig.part_centroid.row(b) = c.transpose();
    rig.part_axes[static_cast<size_t>(b)] = E;
    rig.part_scale(b) = std::max(std::sqrt(std::max(cov.trace(), 0.0)), 1e-12);
  }
  rig.vertex_quadratic = Eigen::MatrixXd::Zero(n, kQ * K);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index k = 0; k < K; ++k)
      if (rig.member(i, k))
        rig.vertex_quadratic.block<1, kQ>(i, kQ * k) =
            quadratic_vector(part_local(rig, lbs.influences(i, k), ex.rest.row(i).transpose()));
  return members;
}

// Quadratic: per part and example, A (3 by 10) with Ŷ ≈ Q Aᵀ, ridge towards [I 0 0] (eq. 6);
// returns per part the P by 30 deformations, one row per example.
std::vector<Eigen::MatrixXd> part_deformations(const PoseSpaceFit& f, const std::vector<std::vector<Eigen::Index>>& members) {
  const SkinningExamples& ex = f.ex;
  const PoseSpaceRig& rig = f.rig;
  const int P = f.P;
  std::vector<Eigen::MatrixXd> A(static_cast<size_t>(f.B), Eigen::MatrixXd::Zero(P, kA));
  Eigen::Matrix<double, kQ, 3> A0t = Eigen::Matrix<double, kQ, 3>::Zero();
  A0t.topRows<3>().setIdentity();
  tbb::parallel_for(0, f.B, [&](int b) {
    const auto& mem = members[static_cast<size_t>(b)];
    const Eigen::Index m = static_cast<Eigen::Index>(mem.size());
    Eigen::MatrixXd Q(m, kQ);
    for (Eigen::Index r = 0; r < m; ++r)
      Q.row(r) = quadratic_vector(part_local(rig, b, ex.rest.row(mem[static_cast<size_t>(r)]).transpose()));
    Eigen::Matrix<double, kQ, kQ> H = Q.transpose() * Q;
    const double mu = f.o.quadratic_ridge * std::max(H.trace() / kQ, 1e-12) + 1e-12;
    H.diagonal().array() += mu;
    const Eigen::LDLT<Eigen::Matrix<double, kQ, kQ>> ldlt(H);
    for (int p = 0; p < P; ++p) {
      const Eigen::Affine3d Minv = ex.transforms[static_cast<size_t>(p)][static_cast<size_t>(b)].inverse();
      Eigen::MatrixXd Y(m, 3);
      for (Eigen::Index r = 0; r < m; ++r)
        Y.row(r) = part_local(rig, b, Minv * Eigen::Vector3d(ex.poses[static_cast<size_t>(p)].row(mem[static_cast<size_t>(r)])))
                       .transpose();
      const Eigen::Matrix<double, kQ, 3> At = ldlt.solve(Q.transpose() * Y + mu * A0t);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < kQ; ++c) A[static_cast<size_t>(b)](p, kQ * r + c) = At(c, r);
    }
  });
  return A;
}

// Quadratic: interpolate A over each part's pose descriptor; returns per example the interpolated
// A of every part (#B by 30), which the residual targets are taken after.
std::vector<Eigen::MatrixXd> interpolate_parts(PoseSpaceFit& f, const std::vector<std::vector<Eigen::Index>>& members,
                                               const std::vector<Eigen::MatrixXd>& A) {
  PoseSpaceRig& rig = f.rig;
  const int B = f.B, P = f.P;
  rig.part_sigma = Eigen::VectorXd::Zero(B);
  rig.part_coef.assign(static_cast<size_t>(B), Eigen::MatrixXd::Zero(P, kA));
  rig.part_mean = Eigen::MatrixXd::Zero(B, kA);
  std::vector<Eigen::MatrixXd> predicted(static_cast<size_t>(P), Eigen::MatrixXd(B, kA));
  for (int b = 0; b < B; ++b) {
    const Eigen::MatrixXd& Ab = A[static_cast<size_t>(b)];
    Eigen::RowVectorXd mean = Ab.colwise().mean();
    if (members[static_cast<size_t>(b)].empty()) {
      mean.setZero();
      mean(0) = mean(kQ + 1) = mean(2 * kQ + 2) = 1;   // unused part: rigid
    }
    rig.part_mean.row(b) = mean;
    const Eigen::MatrixXd D2 =
        combine(f.Gd, rig.part_pairs[static_cast<size_t>(b)], rig.part_omega[static_cast<size_t>(b)], P, P);
    const double sigma = members[static_cast<size_t>(b)].empty() ? 0.0 : f.o.kernel_width * median_positive(D2.cwiseSqrt());
    rig.part_sigma(b) = sigma;
    Eigen::MatrixXd pred = mean.replicate(P, 1);
    if (sigma > 0) {
      rig.part_coef[static_cast<size_t>(b)] = rbf_factor(D2, sigma, f.o.rbf_ridge).solve(Eigen::MatrixXd(Ab.rowwise() - mean));
      pred += kernel(D2, sigma) * rig.part_coef[static_cast<size_t>(b)];
    }
    for (int p = 0; p < P; ++p) predicted[static_cast<size_t>(p)].row(b) = pred.row(p);
  }
  return predicted;
}

// Quadratic: residual targets in the primary part's axes, after the interpolated A (zero unless
// the options ask for the residual correction).
void quadratic_residual_targets(PoseSpaceFit& f, const std::vector<Eigen::MatrixXd>& predicted) {
  const SkinningExamples& ex = f.ex;
  const PoseSpaceRig& rig = f.rig;
  tbb::parallel_for(0, f.P, [&](int p) {
    const BoneTransforms& M = ex.transforms[static_cast<size_t>(p)];
    for (Eigen::Index i = 0; i < f.n; ++i) {
      const Eigen::Vector3d x = quadratic_blend(rig, i, M, predicted[static_cast<size_t>(p)]);
      const Eigen::Vector3d res = ex.poses[static_cast<size_t>(p)].row(i).transpose() - x;
      const Eigen::Vector3d local = M[static_cast<size_t>(rig.primary(i))].linear().transpose() * res;
      f.target.block<1, 3>(i, 3 * p) = f.o.quadratic_residual ? Eigen::RowVector3d(local.transpose()) : Eigen::RowVector3d::Zero();
    }
  });
}

// Per neighbourhood: the mean correction of each vertex, then the RBF (psd, quadratic residual:
// every vertex's corrections; eigenskin: the coefficients of the leading modes). Returns the modes
// kept per neighbourhood (eigenskin).
std::vector<int> fit_corrections(PoseSpaceFit& f) {
  const PoseSpaceOptions& o = f.o;
  PoseSpaceRig& rig = f.rig;
  const int P = f.P;
  const size_t G = f.group_vertices.size();
  if (o.method != PoseSpaceMethod::eigenskin) rig.vertex_coef = Eigen::MatrixXd::Zero(f.n, 3 * P);
  if (o.method == PoseSpaceMethod::eigenskin) {
    rig.group_coef.assign(G, Eigen::MatrixXd());
    rig.vertex_modes.assign(static_cast<size_t>(f.n), Eigen::RowVectorXd());
  }
  std::vector<int> modes_kept(G, 0);
  tbb::parallel_for(size_t(0), G, [&](size_t g) {
    const auto& vs = f.group_vertices[g];
    const Eigen::Index ng = static_cast<Eigen::Index>(vs.size());
    // D: P by 3n_g, example-major rows, the mean of each column removed.
    Eigen::MatrixXd D(P, 3 * ng);
    for (Eigen::Index r = 0; r < ng; ++r) {
      const Eigen::Index i = vs[static_cast<size_t>(r)];
      for (int p = 0; p < P; ++p) D.block<1, 3>(p, 3 * r) = f.target.block<1, 3>(i, 3 * p);
      const Eigen::RowVector3d mean = D.middleCols<3>(3 * r).colwise().mean();
      rig.vertex_mean.row(i) = mean;
      D.middleCols<3>(3 * r).rowwise() -= mean;
    }
    const double sigma = rig.group_sigma(static_cast<Eigen::Index>(g));
    if (o.method != PoseSpaceMethod::eigenskin) {
      if (sigma <= 0) return;
      const Eigen::MatrixXd C = rbf_factor(f.group_D2[g], sigma, o.rbf_ridge).solve(D);   // P by 3n_g
      for (Eigen::Index r = 0; r < ng; ++r) {
        const Eigen::Index i = vs[static_cast<size_t>(r)];
        for (int p = 0; p < P; ++p) rig.vertex_coef.block<1, 3>(i, 3 * p) = C.block<1, 3>(p, 3 * r);
      }
      return;
    }
    // EigenSkin: PCA of the displacement fields via the P by P Gram matrix.
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(D * D.transpose());
    const Eigen::VectorXd ev = eig.eigenvalues().reverse();
    const Eigen::MatrixXd V = eig.eigenvectors().rowwise().reverse();
    const double tol = 1e-12 * std::max(ev(0), 0.0);
    int m = 0;
    while (m < std::min<int>(o.eigenskin_modes, P) && ev(m) > tol && ev(m) > 0) ++m;
    Eigen::MatrixXd U = D.transpose() * V.leftCols(m);               // 3n_g by m (= U S)
    for (int c = 0; c < m; ++c) U.col(c) /= std::sqrt(ev(c));        // orthonormal modes
    const Eigen::MatrixXd alpha = D * U;                              // P by m mode coefficients
    rig.group_coef[g] = sigma > 0 && m > 0 ? Eigen::MatrixXd(rbf_factor(f.group_D2[g], sigma, o.rbf_ridge).solve(alpha))
                                           : Eigen::MatrixXd::Zero(P, m);
    for (Eigen::Index r = 0; r < ng; ++r) {
      Eigen::RowVectorXd modes(3 * m);
      for (int c = 0; c < 3; ++c) modes.segment(c * m, m) = U.row(3 * r + c);
      rig.vertex_modes[static_cast<size_t>(vs[static_cast<size_t>(r)])] = modes;
    }
    modes_kept[g] = m;
  });
  return modes_kept;
}

// The fit summary: sizes, modes kept, and the residual of the finished rig at the examples.
void summarize_fit(const PoseSpaceFit& f, const std::vector<int>& modes_kept,
                   std::chrono::steady_clock::time_point t0, PoseSpaceFitSummary* summary) {
  const int P = f.P;
  const size_t G = f.group_vertices.size();
  summary->method = f.o.method;
  summary->vertices = static_cast<int>(f.n);
  summary->poses = P;
  summary->groups = static_cast<int>(G);
  double sm = 0;
  for (int m : modes_kept) sm += m;
  summary->mean_modes = G ? sm / double(G) : 0;
  double s = 0, mx = 0;
  for (int p = 0; p < P; ++p) {
    const Eigen::VectorXd e =
        (evaluate_pose_space(f.rig, f.ex.transforms[static_cast<size_t>(p)]) - f.ex.poses[static_cast<size_t>(p)]).rowwise().norm();
    s += e.squaredNorm();
    mx = std::max(mx, e.maxCoeff());
  }
  summary->rms_residual = std::sqrt(s / (double(P) * double(f.n)));
  summary->max_residual = mx;
  summary->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

PoseSpaceRig fit_pose_space(const SkinningExamples& ex, const SkinningRig& lbs, const PoseSpaceOptions& o,
                            PoseSpaceFitSummary* summary, const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string who = pose_space_method_name(o.method);
  check_fit_inputs(ex, lbs, o, who);
  const int P = ex.pose_count();
  const Eigen::Index n = ex.rest.rows(), K = lbs.influences.cols();
  const int B = lbs.bone_count;

  PoseSpaceRig rig;
  rig.method = o.method;
  rig.base = lbs;
  rig.poses = P;
  PoseSpaceFit f{ex, lbs, o, rig, n, K, B, P, {}, {}, {}, {}, {}};
  build_descriptors(f);
  example_distances(f);
  report_progress(progress, 0.05, who + ": corrections at the examples");

  // Targets per vertex and example: #V by 3P, example-major.
  f.target.resize(n, 3 * P);
  rig.vertex_mean = Eigen::MatrixXd::Zero(n, 3);
  if (o.method != PoseSpaceMethod::quadratic) {
    displacement_targets(f);
  } else {
    const std::vector<std::vector<Eigen::Index>> members = part_frames(f);
    const std::vector<Eigen::MatrixXd> A = part_deformations(f, members);
    quadratic_residual_targets(f, interpolate_parts(f, members, A));
  }
  report_progress(progress, 0.4, who + ": pose-space interpolation");

  const std::vector<int> modes_kept = fit_corrections(f);
  report_progress(progress, 1.0, who + ": done");
  if (!rig.vertex_coef.allFinite() || !rig.vertex_mean.allFinite())
    throw NumericalError(who + ": the RBF solve produced non-finite coefficients");
  if (summary) summarize_fit(f, modes_kept, t0, summary);
  return rig;
}

Eigen::MatrixX3d evaluate_pose_space(const PoseSpaceRig& rig, const BoneTransforms& M) {
  if (static_cast<int>(M.size()) != rig.bone_count())
    throw InputError("pose-space rig: " + std::to_string(rig.bone_count()) + " bones, the pose has " +
                     std::to_string(M.size()) + " transforms");
  const PoseQuery q = query_pose(rig, M);
  const Eigen::Index n = rig.vertex_count();
  Eigen::MatrixX3d out(n, 3);
  // Part deformations A (quadratic) and mode weights (eigenskin) for this pose.
  Eigen::MatrixXd A;
  if (rig.method == PoseSpaceMethod::quadratic) {
    A = rig.part_mean;
    for (int b = 0; b < rig.bone_count(); ++b) {
      const double sigma = rig.part_sigma(b);
      if (sigma <= 0) continue;
      const Eigen::RowVectorXd phi =
          kernel(combine(q.g, rig.part_pairs[static_cast<size_t>(b)], rig.part_omega[static_cast<size_t>(b)], 1, rig.poses),
                 sigma).row(0);
      A.row(b) += phi * rig.part_coef[static_cast<size_t>(b)];
    }
  }
  std::vector<Eigen::RowVectorXd> alpha;
  if (rig.method == PoseSpaceMethod::eigenskin) {
    alpha.resize(rig.group_coef.size());
    for (size_t g = 0; g < alpha.size(); ++g)
      alpha[g] = q.phi[g].size() ? Eigen::RowVectorXd(q.phi[g] * rig.group_coef[g])
                                 : Eigen::RowVectorXd::Zero(rig.group_coef[g].cols());
  }
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, n, 256), [&](const auto& r) {
    for (Eigen::Index i = r.begin(); i < r.end(); ++i) {
      if (rig.method == PoseSpaceMethod::quadratic) {
        const Eigen::Vector3d x = quadratic_blend(rig, i, M, A);
        const Eigen::Vector3d d = vertex_correction(rig, q, i);
        out.row(i) = (x + M[static_cast<size_t>(rig.primary(i))].linear() * d).transpose();
        continue;
      }
      Eigen::Matrix3d L;
      Eigen::Vector3d x;
      ssd_at(rig.base, i, M, &L, &x);
      Eigen::Vector3d d;
      if (rig.method == PoseSpaceMethod::psd) {
        d = vertex_correction(rig, q, i);
      } else {
        d = rig.vertex_mean.row(i).transpose();
        const Eigen::RowVectorXd& a = alpha[static_cast<size_t>(rig.vertex_group(i))];
        const Eigen::RowVectorXd& modes = rig.vertex_modes[static_cast<size_t>(i)];
        const Eigen::Index m = a.size();
        for (int c = 0; c < 3; ++c) d(c) += modes.segment(c * m, m).dot(a);
      }
      out.row(i) = (x + L * d).transpose();
    }
  });
  return out;
}

}  // namespace bodymodel
