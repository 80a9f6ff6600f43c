#include "registration/shape_fit.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/error.h"
#include "core/geometry.h"
#include "core/point_index.h"
#include "registration/pose_fit.h"

namespace bodymodel {

double macro_slider(const MacroSettings& s, const std::string& n) {
  if (n == "gender") return s.gender;
  if (n == "age") return s.age;
  if (n == "muscle") return s.muscle;
  if (n == "weight") return s.weight;
  if (n == "height") return s.height;
  if (n == "proportions") return s.proportions;
  if (n == "cup") return s.cup;
  if (n == "firmness") return s.firmness;
  if (n == "african") return s.african;
  if (n == "asian") return s.asian;
  if (n == "caucasian") return s.caucasian;
  throw InputError("unknown macro slider '" + n +
                   "' (expected gender, age, muscle, weight, height, proportions, cup, firmness, "
                   "african, asian, caucasian)");
}

void set_macro_slider(MacroSettings* s, const std::string& n, double v) {
  if (!std::isfinite(v)) throw InputError("macro slider '" + n + "': value is not finite");
  v = std::clamp(v, 0.0, 1.0);
  if (n == "gender") s->gender = v;
  else if (n == "age") s->age = v;
  else if (n == "muscle") s->muscle = v;
  else if (n == "weight") s->weight = v;
  else if (n == "height") s->height = v;
  else if (n == "proportions") s->proportions = v;
  else if (n == "cup") s->cup = v;
  else if (n == "firmness") s->firmness = v;
  else if (n == "african" || n == "asian" || n == "caucasian") s->set_ethnic(n, v);
  else macro_slider(*s, n);  // throws the unknown-name error
}

namespace {

// A sample pair: posed template vertex `vertex` should lie on the scan's plane (p, n).
struct Pair {
  int vertex;
  Eigen::Vector3d p, n;
  double w;  // Huber weight (IRLS), fixed for one pair update
};

// The parameters: sliders, translation (3), scale (optional).
struct Layout {
  int sliders = 0, translation = -1, scale = -1, count = 0;
};

class Problem {
 public:
  Problem(const MakeHuman& mh, const MacroSettings& start, double scale, const Pose& pose,
          const ShapeFitOptions& o)
      : mh_(mh), start_(start), pose_(pose), o_(o) {
    L_.sliders = int(o.sliders.size());
    L_.count = L_.sliders;
    if (o.fit_translation) L_.translation = L_.count, L_.count += 3;
    if (o.fit_scale) L_.scale = L_.count, L_.count += 1;
    const MakeHuman::Body b0 = mh.body(start);
    anchor_ = b0.skeleton.heads.row(0).transpose() + pose.root_translation;
    theta0_.resize(L_.count);
    for (int k = 0; k < L_.sliders; ++k) theta0_[k] = macro_slider(start, o.sliders[k]);
    if (L_.translation >= 0) theta0_.segment<3>(L_.translation).setZero();
    if (L_.scale >= 0) theta0_[L_.scale] = scale;
    scale_ = scale;
  }

  const Layout& layout() const { return L_; }
  const Eigen::VectorXd& theta0() const { return theta0_; }
  int builds = 0;

  MacroSettings settings(const Eigen::VectorXd& th) const {
    MacroSettings s = start_;
    for (int k = 0; k < L_.sliders; ++k) set_macro_slider(&s, o_.sliders[k], th[k]);
    return s;
  }
  double scale(const Eigen::VectorXd& th) const { return L_.scale >= 0 ? th[L_.scale] : scale_; }
  Pose pose(const MakeHuman::Body& b, const Eigen::VectorXd& th) const {
    Pose p = pose_;
    p.root_translation = anchor_ - b.skeleton.heads.row(0).transpose();
    if (L_.translation >= 0) p.root_translation += th.segment<3>(L_.translation);
    return p;
  }
  // Posed template for the parameters (13380 by 3, mm); the body through *body if given.
  Eigen::MatrixX3d posed(const Eigen::VectorXd& th, MakeHuman::Body* body = nullptr) {
    MakeHuman::Body b = mh_.body(settings(th));
    ++builds;
    Eigen::MatrixX3d V = pose_template(b.mesh.V, b.skeleton, b.weights, scale(th), pose(b, th));
    if (body) *body = std::move(b);
    return V;
  }
  // Posed template for the sliders of th with the scale replaced (no rebuild needed for the
  // scale's derivative, but a body is cheap enough: keep it simple and exact).

 private:
  const MakeHuman& mh_;
  MacroSettings start_;
  Pose pose_;
  const ShapeFitOptions& o_;
  Layout L_;
  Eigen::Vector3d anchor_;
  Eigen::VectorXd theta0_;
  double scale_ = 1.0;
};

}  // namespace

ShapeFitResult fit_shape(const MakeHuman& mh, const MacroSettings& start, double scale,
                         const Pose& pose, const PointCloud& scan,
                         const std::vector<Landmark>& landmarks, const ShapeFitOptions& o,
                         ShapeFitSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  if (scan.P.rows() == 0 || scan.N.rows() != scan.P.rows())
    throw InputError("shape fit: the scan needs points and one normal per point, found " +
                     std::to_string(scan.P.rows()) + " points and " +
                     std::to_string(scan.N.rows()) + " normals");
  if (!(scale > 0) || !std::isfinite(scale))
    throw InputError("shape fit: the scale must be positive and finite, found " +
                     std::to_string(scale));
  for (const auto& n : o.sliders) macro_slider(start, n);  // names checked
  start.validate();
  Problem prob(mh, start, scale, pose, o);
  const Layout& L = prob.layout();
  const int nv = MakeHuman::kBodyVertexCount;
  for (const Landmark& l : landmarks)
    if (l.vertex < 0 || l.vertex >= nv)
      throw InputError("shape fit: landmark '" + l.name + "' has vertex " +
                       std::to_string(l.vertex) + ", expected 0.." + std::to_string(nv - 1));

  // Sample vertices: not mostly bound below the excluded bones (hands).
  MakeHuman::Body body;
  Eigen::VectorXd theta = prob.theta0();
  Eigen::MatrixX3d V = prob.posed(theta, &body);
  const Skeleton& sk = body.skeleton;
  std::vector<char> excluded_bone(sk.bone_count(), 0);
  for (int b = 0; b < sk.bone_count(); ++b) {
    const int p = sk.parents[b];
    if (p >= 0 && excluded_bone[p]) excluded_bone[b] = 1;
    for (const auto& n : o.excluded_below)
      if (sk.names[b] == n) excluded_bone[b] = 1;
  }
  std::vector<int> allowed;
  for (int i = 0; i < body.weights.outerSize() && i < nv; ++i) {
    double w_ex = 0;
    for (SkinWeights::InnerIterator it(body.weights, i); it; ++it)
      if (excluded_bone[it.col()]) w_ex += it.value();
    if (w_ex < 0.5) allowed.push_back(i);
  }
  std::vector<int> samples;
  const int stride_t = std::max(1, int(allowed.size()) / std::max(1, o.sample_vertices));
  for (size_t k = 0; k < allowed.size(); k += stride_t) samples.push_back(allowed[k]);
  const PointIndex scan_index(scan.P);
  const int stride_s = std::max(1, int(scan.P.rows()) / std::max(1, o.scan_samples));
  const double cos_max = std::cos(o.max_normal_angle_deg * M_PI / 180.0);
  const Eigen::MatrixX3i& F = mh.body_faces();

  // Residuals for the pairs, landmarks and prior at posed vertices V and parameters th.
  std::vector<Pair> pairs;
  const double ptp = std::sqrt(o.point_to_point_weight);
  auto residuals = [&](const Eigen::MatrixX3d& Vp, const Eigen::VectorXd& th) {
    const int np = int(pairs.size()), nl = int(landmarks.size());
    Eigen::VectorXd r(4 * np + 3 * nl + L.sliders + (L.scale >= 0 ? 1 : 0));
    const double wn = np > 0 ? 1.0 / np : 0.0;
    for (int k = 0; k < np; ++k) {
      const Pair& q = pairs[k];
      const Eigen::Vector3d d = Vp.row(q.vertex).transpose() - q.p;
      const double s = std::sqrt(q.w * wn);
      r[4 * k] = s * q.n.dot(d);
      r.segment<3>(4 * k + 1) = s * ptp * d;
    }
    const double wl = nl > 0 ? std::sqrt(o.landmark_weight / nl) : 0.0;
    for (int k = 0; k < nl; ++k)
      r.segment<3>(4 * np + 3 * k) =
          wl * (Vp.row(landmarks[k].vertex).transpose() - landmarks[k].target);
    const int base = 4 * np + 3 * nl;
    for (int k = 0; k < L.sliders; ++k)
      r[base + k] = std::sqrt(o.prior_weight) * (th[k] - prob.theta0()[k]);
    if (L.scale >= 0) r[base + L.sliders] = std::sqrt(o.scale_prior) * (th[L.scale] - 1.0);
    return r;
  };

  ShapeFitSummary sum;
  double max_dist = o.initial_max_distance;
  for (int it = 0; it < o.icp_iterations; ++it) {
    // Pair update: template samples → scan, scan samples → allowed template vertices.
    const Eigen::MatrixX3d N = vertex_normals(V, F);
    pairs.clear();
    double plane2 = 0;
    auto accept = [&](int v, int s) {
      const Eigen::Vector3d p = scan.P.row(s).transpose();
      const Eigen::Vector3d n = scan.N.row(s).transpose();
      const Eigen::Vector3d d = V.row(v).transpose() - p;
      if (d.norm() > max_dist) return;
      double c = n.dot(N.row(v).transpose());
      if (o.unsigned_normals) c = std::abs(c);
      if (c < cos_max) return;
      const double e = std::abs(n.dot(d));
      pairs.push_back({v, p, n, e <= o.robust_scale ? 1.0 : o.robust_scale / e});
      plane2 += e * e;
    };
    for (int v : samples) accept(v, scan_index.nearest(V.row(v).transpose()));
    const int n_forward = int(pairs.size());
    {
      Eigen::MatrixX3d A(allowed.size(), 3);
      for (size_t k = 0; k < allowed.size(); ++k) A.row(k) = V.row(allowed[k]);
      const PointIndex tpl_index(A);
      for (int s = 0; s < scan.P.rows(); s += stride_s)
        accept(allowed[tpl_index.nearest(scan.P.row(s).transpose())], s);
    }
    // Both directions weigh the same in total.
    const int n_back = int(pairs.size()) - n_forward;
    if (n_forward > 0 && n_back > 0)
      for (int k = n_forward; k < int(pairs.size()); ++k) pairs[k].w *= double(n_forward) / n_back;
    if (pairs.empty()) break;
    const double rms = std::sqrt(plane2 / pairs.size());
    if (it == 0) sum.rms_before = rms;
    sum.rms_after = rms;
    ++sum.icp_iterations;

    const Eigen::VectorXd theta_it = theta;
    Eigen::VectorXd r = residuals(V, theta);
    double cost = r.squaredNorm();
    double mu = 1e-3;
    for (int step = 0; step < o.solver_iterations; ++step) {
      // Jacobian: finite differences for the sliders and the scale, exact for the translation.
      Eigen::MatrixXd J = Eigen::MatrixXd::Zero(r.size(), L.count);
      for (int k = 0; k < L.count; ++k) {
        if (L.translation >= 0 && k >= L.translation && k < L.translation + 3) {
          Eigen::VectorXd th = theta;
          th[k] += 1.0;
          Eigen::MatrixX3d Vt = V.rowwise() + Eigen::RowVector3d::Unit(k - L.translation);
          J.col(k) = residuals(Vt, th) - r;
          continue;
        }
        Eigen::VectorXd th = theta;
        double h = o.fd_step;
        if (k < L.sliders && th[k] + h > 1.0) h = -h;
        th[k] += h;
        J.col(k) = (residuals(prob.posed(th), th) - r) / h;
      }
      const Eigen::MatrixXd JtJ = J.transpose() * J;
      const Eigen::VectorXd g = J.transpose() * r;
      bool accepted = false;
      for (int tries = 0; tries < 6 && !accepted; ++tries) {
        Eigen::MatrixXd A = JtJ;
        A.diagonal() += mu * JtJ.diagonal() + Eigen::VectorXd::Constant(L.count, 1e-9);
        Eigen::VectorXd th = theta - A.ldlt().solve(g);
        for (int k = 0; k < L.sliders; ++k) th[k] = std::clamp(th[k], 0.0, 1.0);
        if (L.scale >= 0) th[L.scale] = std::clamp(th[L.scale], 0.5, 2.0);
        if (!th.allFinite()) {
          mu *= 10;
          continue;
        }
        MakeHuman::Body bt;
        Eigen::MatrixX3d Vt = prob.posed(th, &bt);
        const Eigen::VectorXd rt = residuals(Vt, th);
        const double ct = rt.squaredNorm();
        if (ct < cost) {
          theta = th, V = std::move(Vt), body = std::move(bt), r = rt, cost = ct;
          mu = std::max(1e-6, mu / 3);
          accepted = true;
          ++sum.solver_steps;
        } else {
          mu *= 8;
        }
      }
      if (!accepted) break;
    }
    max_dist = std::max(o.max_distance, max_dist * 0.5);
    const double moved = L.sliders > 0 ? (theta - theta_it).head(L.sliders).cwiseAbs().maxCoeff() : 0;
    if (moved < o.convergence && max_dist <= o.max_distance && it > 0) break;
  }
  double lm2 = 0;
  for (const Landmark& l : landmarks) lm2 += (V.row(l.vertex).transpose() - l.target).squaredNorm();
  sum.landmark_rms = landmarks.empty() ? 0.0 : std::sqrt(lm2 / landmarks.size());
  sum.builds = prob.builds;

  ShapeFitResult res;
  res.settings = prob.settings(theta);
  res.scale = prob.scale(theta);
  res.pose = prob.pose(body, theta);
  res.body = std::move(body);
  res.V = std::move(V);
  if (!res.V.allFinite()) throw NumericalError("shape fit produced non-finite vertices");
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (summary) *summary = sum;
  return res;
}

}  // namespace bodymodel
