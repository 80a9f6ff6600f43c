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
  // Slider mode: `start` sliders. Space mode (o.space): `start_c` coefficients (empty = 0).
  Problem(const MakeHuman& mh, const MacroSettings& start, const Eigen::VectorXd& start_c, double scale,
          const Pose& pose, const ShapeFitOptions& o)
      : mh_(mh), start_(start), pose_(pose), o_(o), space_(o.space), vspace_(o.vertex_space) {
    L_.sliders = space_ ? space_->dimension() : vspace_ ? vspace_->components() : int(o.sliders.size());
    L_.count = L_.sliders;
    if (o.fit_translation) L_.translation = L_.count, L_.count += 3;
    if (o.fit_scale) L_.scale = L_.count, L_.count += 1;
    theta0_.resize(L_.count);
    if (in_space()) {
      theta0_.head(L_.sliders) = Eigen::VectorXd::Zero(L_.sliders);
      if (space_ && space_->has_sex()) theta0_[space_->components()] = 0.5;
      if (start_c.size() > 0) theta0_.head(L_.sliders) = start_c;
      prior_centre_ = Eigen::VectorXd::Zero(L_.sliders);  // the people's mean
      // The components have the people's Gaussian; the sex slider g none (the data decide).
      prior_sqrt_ = Eigen::VectorXd::Constant(L_.sliders, std::sqrt(o.space_prior_weight));
      if (space_ && space_->has_sex()) prior_sqrt_[space_->components()] = 0.0;
    } else {
      for (int k = 0; k < L_.sliders; ++k) theta0_[k] = macro_slider(start, o.sliders[k]);
      prior_centre_ = theta0_.head(L_.sliders);
      prior_sqrt_ = Eigen::VectorXd::Constant(L_.sliders, std::sqrt(o.prior_weight));
    }
    const MakeHuman::Body b0 = body(theta0_);
    anchor_ = b0.skeleton.heads.row(0).transpose() + pose.root_translation;
    if (L_.translation >= 0) theta0_.segment<3>(L_.translation).setZero();
    if (L_.scale >= 0) theta0_[L_.scale] = scale;
    scale_ = scale;
  }

  const Layout& layout() const { return L_; }
  const Eigen::VectorXd& theta0() const { return theta0_; }
  const Eigen::VectorXd& prior_centre() const { return prior_centre_; }
  const Eigen::VectorXd& prior_sqrt() const { return prior_sqrt_; }
  // Bounds, finite-difference step and convergence of the shape parameters.
  // (A learned space's sex slider g, its last parameter, is a slider: [0, 1], the slider step.)
  int sex_index() const { return space_ && space_->has_sex() ? space_->components() : -1; }
  bool is_slider(int k) const { return !in_space() || (space_ && space_->has_sex() && k == space_->components()); }
  double lower(int k) const { return is_slider(k) ? 0.0 : -o_.space_limit; }
  double upper(int k) const { return is_slider(k) ? 1.0 : o_.space_limit; }
  double fd_step(int k) const { return is_slider(k) ? o_.fd_step : o_.space_fd_step; }
  double convergence() const { return in_space() ? o_.space_convergence : o_.convergence; }
  bool in_space() const { return space_ != nullptr || vspace_ != nullptr; }
  int builds = 0;

  MacroSettings settings(const Eigen::VectorXd& th) const {
    if (space_) return shape_space_parameters(mh_, *space_, th.head(L_.sliders)).macros;
    if (vspace_) return start_;  // not a MakeHuman body: no sliders
    MacroSettings s = start_;
    for (int k = 0; k < L_.sliders; ++k) set_macro_slider(&s, o_.sliders[k], th[k]);
    return s;
  }
  MakeHuman::Body body(const Eigen::VectorXd& th) const {
    if (space_) return shape_space_body(mh_, *space_, th.head(L_.sliders));
    if (vspace_) return vertex_space_body(mh_, *vspace_, th.head(L_.sliders));
    return mh_.body(settings(th));
  }
  double scale(const Eigen::VectorXd& th) const { return L_.scale >= 0 ? th[L_.scale] : scale_; }
  Pose pose(const MakeHuman::Body& b, const Eigen::VectorXd& th) const {
    Pose p = pose_;
    p.root_translation = anchor_ - b.skeleton.heads.row(0).transpose();
    if (L_.translation >= 0) p.root_translation += th.segment<3>(L_.translation);
    return p;
  }
  // Posed template for the parameters (13380 by 3, mm); the body through *body if given.
  Eigen::MatrixX3d posed(const Eigen::VectorXd& th, MakeHuman::Body* body_out = nullptr) {
    MakeHuman::Body b = body(th);
    ++builds;
    Eigen::MatrixX3d V = pose_template(b.mesh.V, b.skeleton, b.weights, scale(th), pose(b, th));
    if (body_out) *body_out = std::move(b);
    return V;
  }

 private:
  const MakeHuman& mh_;
  MacroSettings start_;
  Pose pose_;
  const ShapeFitOptions& o_;
  const ShapeSpace* space_;
  const VertexShapeSpace* vspace_;
  Layout L_;
  Eigen::Vector3d anchor_;
  Eigen::VectorXd theta0_, prior_centre_, prior_sqrt_;
  double scale_ = 1.0;
};

// The argument checks of fit_shape on the scan, the scale and the starting sliders.
void check_shape_inputs(const MacroSettings& start, double scale, const PointCloud& scan, const ShapeFitOptions& o) {
  if (scan.P.rows() == 0 || scan.N.rows() != scan.P.rows())
    throw InputError("shape fit: the scan needs points and one normal per point, found " +
                     std::to_string(scan.P.rows()) + " points and " +
                     std::to_string(scan.N.rows()) + " normals");
  if (!(scale > 0) || !std::isfinite(scale))
    throw InputError("shape fit: the scale must be positive and finite, found " +
                     std::to_string(scale));
  for (const auto& n : o.sliders) macro_slider(start, n);  // names checked
  start.validate();
}

// Template vertices that may pair with the scan (not mostly bound below the excluded bones, e.g.
// the hands), and the evenly strided subset of them matched to the scan.
struct TemplateSamples {
  std::vector<int> allowed, samples;
};

TemplateSamples template_samples(const MakeHuman::Body& body, const ShapeFitOptions& o, int nv) {
  const Skeleton& sk = body.skeleton;
  std::vector<char> excluded_bone(sk.bone_count(), 0);
  for (int b = 0; b < sk.bone_count(); ++b) {
    const int p = sk.parents[b];
    if (p >= 0 && excluded_bone[p]) excluded_bone[b] = 1;
    for (const auto& n : o.excluded_below)
      if (sk.names[b] == n) excluded_bone[b] = 1;
  }
  TemplateSamples ts;
  std::vector<int>& allowed = ts.allowed;
  for (int i = 0; i < body.weights.outerSize() && i < nv; ++i) {
    double w_ex = 0;
    for (SkinWeights::InnerIterator it(body.weights, i); it; ++it)
      if (excluded_bone[it.col()]) w_ex += it.value();
    if (w_ex < 0.5) allowed.push_back(i);
  }
  const int stride_t = std::max(1, int(allowed.size()) / std::max(1, o.sample_vertices));
  for (size_t k = 0; k < allowed.size(); k += stride_t) ts.samples.push_back(allowed[k]);
  return ts;
}

// The residuals for the pairs, landmarks and prior at posed vertices Vp and parameters th: the one
// objective both the Jacobian and the step test evaluate.
struct Residuals {
  const std::vector<Pair>& pairs;
  const std::vector<Landmark>& landmarks;
  const Layout& L;
  const Eigen::VectorXd& prior_centre;
  const Eigen::VectorXd& prior_sqrt;
  const ShapeFitOptions& o;
  double ptp;   // √(point-to-point weight)
  int sex_index;  // a learned space's sex slider g (−1: none): its prior favours either sex

  Eigen::VectorXd operator()(const Eigen::MatrixX3d& Vp, const Eigen::VectorXd& th) const {
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
      r[base + k] = prior_sqrt[k] * (th[k] - prior_centre[k]);
    // The people are women (g = 0) or men (g = 1): an in-between body costs up to the weight.
    if (sex_index >= 0)
      r[base + sex_index] = std::sqrt(o.space_sex_prior_weight) * 2 * std::min(th[sex_index], 1 - th[sex_index]);
    if (L.scale >= 0) r[base + L.sliders] = std::sqrt(o.scale_prior) * (th[L.scale] - 1.0);
    return r;
  }
};

// The fixed inputs of the pair search: the scan and its index, the template's sampled and allowed
// vertices, its faces (for normals) and the acceptance limits.
struct PairSearch {
  const PointCloud& scan;
  const PointIndex& scan_index;
  const TemplateSamples& ts;
  const Eigen::MatrixX3i& F;
  const ShapeFitOptions& o;
  int stride_s;
  double cos_max;
};

// Pair update: template samples → scan, scan samples → allowed template vertices, each kept when
// close and with agreeing normals; both directions weigh the same in total. Returns the sum of
// the squared plane distances of the pairs.
double find_pairs(const PairSearch& ps, const Eigen::MatrixX3d& V, double max_dist, std::vector<Pair>& pairs) {
  const PointCloud& scan = ps.scan;
  const ShapeFitOptions& o = ps.o;
  const std::vector<int>& allowed = ps.ts.allowed;
  const Eigen::MatrixX3d N = vertex_normals(V, ps.F);
  pairs.clear();
  double plane2 = 0;
  auto accept = [&](int v, int s) {
    const Eigen::Vector3d p = scan.P.row(s).transpose();
    const Eigen::Vector3d n = scan.N.row(s).transpose();
    const Eigen::Vector3d d = V.row(v).transpose() - p;
    if (d.norm() > max_dist) return;
    double c = n.dot(N.row(v).transpose());
    if (o.unsigned_normals) c = std::abs(c);
    if (c < ps.cos_max) return;
    const double e = std::abs(n.dot(d));
    pairs.push_back({v, p, n, e <= o.robust_scale ? 1.0 : o.robust_scale / e});
    plane2 += e * e;
  };
  for (int v : ps.ts.samples) accept(v, ps.scan_index.nearest(V.row(v).transpose()));
  const int n_forward = int(pairs.size());
  {
    Eigen::MatrixX3d A(allowed.size(), 3);
    for (size_t k = 0; k < allowed.size(); ++k) A.row(k) = V.row(allowed[k]);
    const PointIndex tpl_index(A);
    for (int s = 0; s < scan.P.rows(); s += ps.stride_s)
      accept(allowed[tpl_index.nearest(scan.P.row(s).transpose())], s);
  }
  // Both directions weigh the same in total.
  const int n_back = int(pairs.size()) - n_forward;
  if (n_forward > 0 && n_back > 0)
    for (int k = n_forward; k < int(pairs.size()); ++k) pairs[k].w *= double(n_forward) / n_back;
  return plane2;
}

// What the solver improves: the parameters, the posed template and the body it was built from.
struct ShapeState {
  Eigen::VectorXd theta;
  Eigen::MatrixX3d V;
  MakeHuman::Body body;
};

// Levenberg–Marquardt on the parameters for fixed pairs: Jacobian by finite differences for the
// sliders and the scale (exact for the translation), damped steps kept only when the cost drops.
void solve_for_pairs(Problem& prob, const Residuals& residuals, const ShapeFitOptions& o, ShapeState& st,
                     ShapeFitSummary& sum) {
  const Layout& L = prob.layout();
  Eigen::VectorXd r = residuals(st.V, st.theta);
  double cost = r.squaredNorm();
  double mu = 1e-3;
  for (int step = 0; step < o.solver_iterations; ++step) {
    // Jacobian: finite differences for the sliders and the scale, exact for the translation.
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(r.size(), L.count);
    for (int k = 0; k < L.count; ++k) {
      if (L.translation >= 0 && k >= L.translation && k < L.translation + 3) {
        Eigen::VectorXd th = st.theta;
        th[k] += 1.0;
        Eigen::MatrixX3d Vt = st.V.rowwise() + Eigen::RowVector3d::Unit(k - L.translation);
        J.col(k) = residuals(Vt, th) - r;
        continue;
      }
      Eigen::VectorXd th = st.theta;
      double h = k < L.sliders ? prob.fd_step(k) : o.fd_step;
      if (k < L.sliders && th[k] + h > prob.upper(k)) h = -h;
      th[k] += h;
      J.col(k) = (residuals(prob.posed(th), th) - r) / h;
    }
    const Eigen::MatrixXd JtJ = J.transpose() * J;
    const Eigen::VectorXd g = J.transpose() * r;
    bool accepted = false;
    for (int tries = 0; tries < 6 && !accepted; ++tries) {
      Eigen::MatrixXd A = JtJ;
      A.diagonal() += mu * JtJ.diagonal() + Eigen::VectorXd::Constant(L.count, 1e-9);
      Eigen::VectorXd th = st.theta - A.ldlt().solve(g);
      for (int k = 0; k < L.sliders; ++k) th[k] = std::clamp(th[k], prob.lower(k), prob.upper(k));
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
        st.theta = th, st.V = std::move(Vt), st.body = std::move(bt), r = rt, cost = ct;
        mu = std::max(1e-6, mu / 3);
        accepted = true;
        ++sum.solver_steps;
      } else {
        mu *= 8;
      }
    }
    if (!accepted) break;
  }
}

}  // namespace

namespace {

// The ICP loop of both entry points: pair updates, a few LM steps each, until the shape settles.
ShapeFitResult run_shape_fit(Problem& prob, const MakeHuman& mh, const PointCloud& scan,
                             const std::vector<Landmark>& landmarks, const ShapeFitOptions& o,
                             ShapeFitSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  const Layout& L = prob.layout();
  const int nv = MakeHuman::kBodyVertexCount;
  for (const Landmark& l : landmarks)
    if (l.vertex < 0 || l.vertex >= nv)
      throw InputError("shape fit: landmark '" + l.name + "' has vertex " +
                       std::to_string(l.vertex) + ", expected 0.." + std::to_string(nv - 1));

  // Sample vertices: not mostly bound below the excluded bones (hands).
  ShapeState st;
  st.theta = prob.theta0();
  st.V = prob.posed(st.theta, &st.body);
  const TemplateSamples ts = template_samples(st.body, o, nv);
  const PointIndex scan_index(scan.P);
  const int stride_s = std::max(1, int(scan.P.rows()) / std::max(1, o.scan_samples));
  const double cos_max = std::cos(o.max_normal_angle_deg * M_PI / 180.0);
  const PairSearch search{scan, scan_index, ts, mh.body_faces(), o, stride_s, cos_max};

  // Residuals for the pairs, landmarks and prior at posed vertices V and parameters th.
  std::vector<Pair> pairs;
  const Residuals residuals{pairs, landmarks, L, prob.prior_centre(), prob.prior_sqrt(), o,
                            std::sqrt(o.point_to_point_weight), prob.sex_index()};

  ShapeFitSummary sum;
  double max_dist = o.initial_max_distance;
  for (int it = 0; it < o.icp_iterations; ++it) {
    const double plane2 = find_pairs(search, st.V, max_dist, pairs);
    if (pairs.empty()) break;
    const double rms = std::sqrt(plane2 / pairs.size());
    if (it == 0) sum.rms_before = rms;
    sum.rms_after = rms;
    ++sum.icp_iterations;

    const Eigen::VectorXd theta_it = st.theta;
    solve_for_pairs(prob, residuals, o, st, sum);
    max_dist = std::max(o.max_distance, max_dist * 0.5);
    const double moved = L.sliders > 0 ? (st.theta - theta_it).head(L.sliders).cwiseAbs().maxCoeff() : 0;
    if (moved < prob.convergence() && max_dist <= o.max_distance && it > 0) break;
  }
  double lm2 = 0;
  for (const Landmark& l : landmarks) lm2 += (st.V.row(l.vertex).transpose() - l.target).squaredNorm();
  sum.landmark_rms = landmarks.empty() ? 0.0 : std::sqrt(lm2 / landmarks.size());
  sum.builds = prob.builds;

  ShapeFitResult res;
  res.settings = prob.settings(st.theta);
  if (prob.in_space()) res.coefficients = st.theta.head(L.sliders);
  res.scale = prob.scale(st.theta);
  res.pose = prob.pose(st.body, st.theta);
  res.body = std::move(st.body);
  res.V = std::move(st.V);
  if (!res.V.allFinite()) throw NumericalError("shape fit produced non-finite vertices");
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (summary) *summary = sum;
  return res;
}

}  // namespace

ShapeFitResult fit_shape(const MakeHuman& mh, const MacroSettings& start, double scale,
                         const Pose& pose, const PointCloud& scan,
                         const std::vector<Landmark>& landmarks, const ShapeFitOptions& o,
                         ShapeFitSummary* summary) {
  check_shape_inputs(start, scale, scan, o);
  ShapeFitOptions so = o;
  so.space = nullptr;
  so.vertex_space = nullptr;
  Problem prob(mh, start, Eigen::VectorXd(), scale, pose, so);
  return run_shape_fit(prob, mh, scan, landmarks, so, summary);
}

ShapeFitResult fit_shape_in_space(const MakeHuman& mh, const Eigen::VectorXd& start, double scale,
                                  const Pose& pose, const PointCloud& scan,
                                  const std::vector<Landmark>& landmarks, const ShapeFitOptions& o,
                                  ShapeFitSummary* summary) {
  if (!o.space == !o.vertex_space)
    throw InputError("shape fit: fit_shape_in_space needs one shape space (ShapeFitOptions::space or vertex_space)");
  if (o.vertex_space) o.vertex_space->validate("shape fit");
  const int dimension = o.space ? o.space->dimension() : o.vertex_space->components();
  if (start.size() != 0 && (start.size() != dimension || !start.allFinite()))
    throw InputError("shape fit: " + std::to_string(start.size()) + " start coefficients for a space of " +
                     std::to_string(dimension) + " coefficients, or not finite");
  ShapeFitOptions so = o;
  so.sliders.clear();
  check_shape_inputs(MacroSettings{}, scale, scan, so);
  Problem prob(mh, MacroSettings{}, start, scale, pose, so);
  return run_shape_fit(prob, mh, scan, landmarks, so, summary);
}

}  // namespace bodymodel
