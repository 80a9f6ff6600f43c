#include "population/fit_proportions.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>

#include "core/error.h"
#include "core/fold_repair.h"
#include "core/intersection_repair.h"
#include "core/plausibility.h"
#include "population/bounded_lm.h"
#include "population/fit_measurements.h"

namespace bodymodel {

int MeasurementSet::index(const std::string& name) const {
  const auto it = std::find(names.begin(), names.end(), name);
  return it == names.end() ? -1 : static_cast<int>(it - names.begin());
}

void MeasurementPrior::condition(const std::vector<std::string>& given_names, const Eigen::VectorXd& given_values,
                                 Eigen::VectorXd& expected, Eigen::VectorXd& sd) const {
  const int n = static_cast<int>(names.size());
  std::vector<int> g;
  for (const auto& name : given_names) {
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end()) throw InputError(fmt::format("the population prior has no measurement '{}'", name));
    g.push_back(static_cast<int>(it - names.begin()));
  }
  expected = mean;
  sd = covariance.diagonal().cwiseSqrt();
  if (g.empty()) return;
  const int k = static_cast<int>(g.size());
  Eigen::MatrixXd Sgg(k, k), Sag(n, k);
  Eigen::VectorXd dg(k);
  for (int a = 0; a < k; ++a) {
    dg(a) = given_values(a) - mean(g[a]);
    for (int b = 0; b < k; ++b) Sgg(a, b) = covariance(g[a], g[b]);
    for (int i = 0; i < n; ++i) Sag(i, a) = covariance(i, g[a]);
  }
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(Sgg);
  expected += Sag * ldlt.solve(dg);
  const Eigen::MatrixXd reduction = Sag * ldlt.solve(Sag.transpose());
  for (int i = 0; i < n; ++i) sd(i) = std::sqrt(std::max(0.0, covariance(i, i) - reduction(i, i)));
  for (int a = 0; a < k; ++a) expected(g[a]) = given_values(a), sd(g[a]) = 0;
}

MeasurementPrior learn_measurement_prior(const AnsurTable& table, int male, const std::vector<std::string>& names,
                                         const std::vector<int>& rows) {
  std::vector<int> cols;
  for (const auto& n : names) cols.push_back(table.column(n));
  std::vector<int> use;
  if (rows.empty()) {
    for (int r = 0; r < static_cast<int>(table.male.size()); ++r) use.push_back(r);
  } else {
    use = rows;
  }
  use.erase(std::remove_if(use.begin(), use.end(), [&](int r) { return table.male.at(r) != male; }), use.end());
  const int n = static_cast<int>(names.size());
  if (static_cast<int>(use.size()) < n + 2)
    throw InputError(fmt::format("'{}': {} {} rows are too few to learn a prior of {} measurements",
                                 table.source.string(), use.size(), male ? "male" : "female", n));
  Eigen::MatrixXd X(use.size(), n);
  for (size_t r = 0; r < use.size(); ++r)
    for (int c = 0; c < n; ++c) X(r, c) = table.values(use[r], cols[c]);
  MeasurementPrior p;
  p.names = names;
  p.rows = static_cast<int>(use.size());
  p.mean = X.colwise().mean();
  const Eigen::MatrixXd C = X.rowwise() - p.mean.transpose();
  p.covariance = C.transpose() * C / double(use.size() - 1);
  return p;
}

// ---- the fitter ------------------------------------------------------------------------------

namespace {

// One modifier's offsets on the body's 13 380 vertices, per side (mm at value ±1): sparse rows.
struct SparseOffsets {
  std::vector<int> rows;
  Eigen::MatrixX3d d;  // rows.size() by 3
  void add(Eigen::MatrixX3d& V, double w) const {
    for (size_t i = 0; i < rows.size(); ++i) V.row(rows[i]) += w * d.row(i);
  }
};

SparseOffsets sparse_of(const Eigen::MatrixX3d& D) {
  SparseOffsets s;
  for (int v = 0; v < MakeHuman::kBodyVertexCount; ++v)
    if (D.row(v).squaredNorm() > 0) s.rows.push_back(v);
  s.d.resize(s.rows.size(), 3);
  for (size_t i = 0; i < s.rows.size(); ++i) s.d.row(i) = D.row(s.rows[i]);
  return s;
}

// A modifier of the body: a measurement modifier or a shape modifier, both sides' offsets.
struct Modifier {
  bool measure = true;
  int index = 0;          // into measure_modifier_names() or shape_modifiers()
  bool two_sided = true;
  SparseOffsets side[2];  // [decrease (v < 0), increase (v > 0)]
};

// A fit parameter: a macro slider or a group of modifiers moved together (left and right).
struct Parameter {
  std::string name;
  int macro = -1;              // 0 muscle, 1 weight, 2 height, 3 proportions, 4 cup, 5 firmness
  std::vector<int> modifiers;  // into Impl::modifiers
  double lo = 0, hi = 1, prior = 0.5, scale = 0.5, step = 0.02;
};

constexpr const char* kMacros[] = {"muscle", "weight", "height", "proportions", "cup", "firmness"};

bool excluded_shape(const MakeHuman::ShapeModifier& m, bool hands_and_feet) {
  const std::string& n = m.name;
  // The hands' overall scale stays: span reaches the fingertips.
  if (!hands_and_feet && n.find("-hand-scale") == std::string::npos &&
      (n.find("-hand-") != std::string::npos || n.find("-foot-") != std::string::npos))
    return true;
  return n.find("stomach-pregnant") != std::string::npos || n.find("pelvis/bulge") != std::string::npos;
}

}  // namespace

struct ProportionFitter::Impl {
  MakeHuman mh;
  MeasurementSet set;
  ProportionFitOptions o;
  std::vector<Modifier> modifiers;
  std::vector<Parameter> params[2];    // [female, male]
  std::vector<std::string> names[2];
  Eigen::MatrixX3d template_V;        // MakeHuman's default body (the fold reference)
  int template_self_intersections = 0;
  std::vector<char> trunk_and_limb_faces;  // faces with every vertex in mh.trunk_and_limbs_region()
};

namespace {

std::vector<Parameter> parameters_for(const ProportionFitter::Impl& m, bool male) {
  const ProportionFitOptions& o = m.o;
  std::vector<Parameter> ps;
  for (int k = 0; k < (male ? 4 : 6); ++k) {
    Parameter p;
    p.name = kMacros[k];
    p.macro = k;
    p.hi = k == 1 ? o.weight_max : 1.0;
    p.scale = o.prior_slider;
    ps.push_back(p);
  }
  const auto& shapes = m.mh.shape_modifiers();
  std::vector<char> taken(m.modifiers.size(), 0);
  for (size_t i = 0; i < m.modifiers.size(); ++i) {
    if (taken[i]) continue;
    const Modifier& mod = m.modifiers[i];
    Parameter p;
    p.modifiers = {static_cast<int>(i)};
    p.lo = mod.two_sided ? -o.modifier_limit : 0.0;
    p.hi = mod.two_sided ? o.modifier_limit : 1.0;
    p.prior = 0;
    p.scale = o.prior_modifier;
    p.step = 0.05;
    if (mod.measure) {
      p.name = "measure/" + m.mh.measure_modifier_names()[mod.index];
    } else {
      const auto& s = shapes[mod.index];
      if (s.group == "bodyshapes" && s.name.find(male ? "-man-" : "-fem-") == std::string::npos) continue;
      p.name = s.name;
      if (!s.side.empty() && s.mirror >= 0) {
        for (size_t j = 0; j < m.modifiers.size(); ++j)
          if (!m.modifiers[j].measure && m.modifiers[j].index == s.mirror) p.modifiers.push_back(static_cast<int>(j)), taken[j] = 1;
        p.name = s.group + "/" + s.name.substr(s.group.size() + 3);  // "armslegs/upperarm-fat-decr|incr"
      }
    }
    taken[i] = 1;
    ps.push_back(std::move(p));
  }
  return ps;
}


}  // namespace

ProportionFitter::ProportionFitter(const MakeHuman& mh, MeasurementSet set, const ProportionFitOptions& o) {
  auto m = std::make_shared<Impl>(Impl{mh, std::move(set), o, {}, {}, {}, {}});
  if (!m->set.measure || m->set.names.empty()) throw InputError("fit: an empty measurement set");
  for (int k = 0; k < static_cast<int>(mh.measure_modifier_names().size()); ++k) {
    Modifier mod;
    mod.index = k;
    for (int s = 0; s < 2; ++s) mod.side[s] = sparse_of(mh.measure_modifier_offsets(k, s == 1));
    m->modifiers.push_back(std::move(mod));
  }
  const auto& shapes = mh.shape_modifiers();
  for (int k = 0; k < static_cast<int>(shapes.size()); ++k) {
    if (excluded_shape(shapes[k], o.include_hands_and_feet)) continue;
    Modifier mod;
    mod.measure = false;
    mod.index = k;
    mod.two_sided = shapes[k].two_sided;
    for (int s = 0; s < 2; ++s) {
      if (s == 0 && !mod.two_sided) continue;
      Eigen::MatrixX3d D = Eigen::MatrixX3d::Zero(MakeHuman::kBodyVertexCount, 3);
      mh.add_shape_modifier(D, k, s == 1 ? 1.0 : -1.0);
      mod.side[s] = sparse_of(D);
    }
    m->modifiers.push_back(std::move(mod));
  }
  for (int male = 0; male < 2; ++male) {
    m->params[male] = parameters_for(*m, male == 1);
    for (const auto& p : m->params[male]) m->names[male].push_back(p.name);
  }
  m->template_V = mh.build_vertices(MacroSettings{}).topRows(MakeHuman::kBodyVertexCount);
  m->template_self_intersections = self_intersecting_triangle_pairs(m->template_V, mh.body_faces());
  const std::vector<char> region = mh.trunk_and_limbs_region();
  const Eigen::MatrixX3i& F = mh.body_faces();
  m->trunk_and_limb_faces.resize(F.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    m->trunk_and_limb_faces[f] = region[F(f, 0)] && region[F(f, 1)] && region[F(f, 2)];
  impl_ = std::move(m);
}

int ProportionFitter::template_self_intersections() const { return impl_->template_self_intersections; }

const std::vector<std::string>& ProportionFitter::parameter_names(Sex sex) const {
  return impl_->names[sex == Sex::male ? 1 : 0];
}

namespace {

// One person's problem: parameters, targets, the macro body cache and the evaluation counter.
struct ProportionProblem {
  const ProportionFitter::Impl& m;
  const std::vector<Parameter>& ps;
  MacroSettings base;                  // gender, age and ethnic mix fixed by the person
  Eigen::VectorXd target, sigma;       // per measurement name (sigma = inf: not fitted)
  int evaluations = 0;
  Eigen::VectorXd cached_macros;
  Eigen::MatrixX3d cached_body;

  int P() const { return static_cast<int>(ps.size()); }
  int T() const { return static_cast<int>(target.size()); }

  MacroSettings settings_of(const Eigen::VectorXd& x) const {
    MacroSettings s = base;
    double* slot[] = {&s.muscle, &s.weight, &s.height, &s.proportions, &s.cup, &s.firmness};
    for (int j = 0; j < P(); ++j)
      if (ps[j].macro >= 0) *slot[ps[j].macro] = x(j);
    return s;
  }
  Eigen::VectorXd macros_of(const Eigen::VectorXd& x) const {
    Eigen::VectorXd v(6);
    v.setZero();
    for (int j = 0; j < P(); ++j)
      if (ps[j].macro >= 0) v(ps[j].macro) = x(j);
    return v;
  }
  // Adds the offsets of parameter j at `value` (value > 0: the increase side times value;
  // < 0: the decrease side times |value|), times `sign` (−1 takes them away again).
  void add_modifier(Eigen::MatrixX3d& V, int j, double value, double sign = 1) const {
    if (value == 0) return;
    for (int i : ps[j].modifiers) m.modifiers[i].side[value > 0 ? 1 : 0].add(V, sign * std::abs(value));
  }
  Eigen::MatrixX3d body_of(const Eigen::VectorXd& x) {
    const Eigen::VectorXd mac = macros_of(x);
    if (cached_macros.size() == 0 || mac != cached_macros) {
      MakeHuman::BuildOptions bo;
      bo.allow_extrapolation = true;
      cached_body = m.mh.build_vertices(settings_of(x), Eigen::VectorXd(), bo).topRows(MakeHuman::kBodyVertexCount);
      cached_macros = mac;
    }
    Eigen::MatrixX3d V = cached_body;
    for (int j = 0; j < P(); ++j)
      if (ps[j].macro < 0) add_modifier(V, j, x(j));
    return V;
  }
  Eigen::VectorXd measure(const Eigen::MatrixX3d& V) {
    ++evaluations;
    return m.set.measure(V);
  }
  Eigen::VectorXd residual(const Eigen::VectorXd& x, const Eigen::VectorXd& v) const {
    Eigen::VectorXd r(T() + P());
    for (int k = 0; k < T(); ++k)
      r(k) = std::isfinite(sigma(k)) ? (std::isfinite(v(k)) ? (v(k) - target(k)) / sigma(k) : 1e6) : 0;
    for (int j = 0; j < P(); ++j) r(T() + j) = (x(j) - ps[j].prior) / ps[j].scale;
    return r;
  }
  // Forward differences of the measurements (T by P) at x, whose body is V and values v: a
  // modifier step adds its offsets to V, a macro step rebuilds the body.
  Eigen::MatrixXd jacobian(const Eigen::VectorXd& x, const Eigen::MatrixX3d& V, const Eigen::VectorXd& v) {
    Eigen::MatrixXd D(T(), P());
    for (int j = 0; j < P(); ++j) {
      double h = ps[j].step;
      if (x(j) + h > ps[j].hi || (x(j) < 0 && x(j) - h >= ps[j].lo)) h = -h;
      Eigen::VectorXd vj;
      if (ps[j].macro >= 0) {
        Eigen::VectorXd xj = x;
        xj(j) += h;
        vj = measure(body_of(xj));
      } else {
        Eigen::MatrixX3d Vj = V;
        add_modifier(Vj, j, x(j) + h);
        add_modifier(Vj, j, x(j), -1);
        vj = measure(Vj);
      }
      for (int k = 0; k < T(); ++k) D(k, j) = std::isfinite(vj(k)) && std::isfinite(v(k)) ? (vj(k) - v(k)) / h : 0;
    }
    return D;
  }
};

double unit_sigma(const std::string& name, const ProportionFitOptions& o) {
  return name == "weightkg" ? o.sigma_kg : o.sigma_mm;
}

}  // namespace

namespace {

// Fills the problem's targets: the given values, and (with a prior) the completed ones with their
// conditional spread; measurements neither given nor in the prior are not fitted.
void set_targets(ProportionProblem& p, const std::vector<ProportionTarget>& targets, const MeasurementPrior& prior,
                 ProportionFit& fit) {
  const MeasurementSet& set = p.m.set;
  const int T = static_cast<int>(set.names.size());
  fit.names = set.names;
  fit.target = Eigen::VectorXd::Constant(T, std::numeric_limits<double>::quiet_NaN());
  fit.target_sd = fit.target;
  fit.given.assign(T, 0);
  p.sigma = Eigen::VectorXd::Constant(T, std::numeric_limits<double>::infinity());
  std::vector<std::string> given_names;
  Eigen::VectorXd given_values(targets.size());
  for (size_t i = 0; i < targets.size(); ++i) {
    const int k = set.index(targets[i].name);
    if (k < 0)
      throw InputError(fmt::format("unknown measurement '{}' (known: {})", targets[i].name, fmt::join(set.names, ", ")));
    if (fit.given[k]) throw InputError(fmt::format("measurement '{}' is given twice", targets[i].name));
    if (!std::isfinite(targets[i].value)) throw InputError(fmt::format("measurement '{}' is not a number", targets[i].name));
    fit.given[k] = 1;
    fit.target(k) = targets[i].value;
    fit.target_sd(k) = 0;
    p.sigma(k) = unit_sigma(targets[i].name, p.m.o);
    if (std::find(prior.names.begin(), prior.names.end(), targets[i].name) != prior.names.end())
      given_names.push_back(targets[i].name), given_values(given_names.size() - 1) = targets[i].value;
  }
  if (!prior.names.empty()) {
    Eigen::VectorXd expected, sd;
    prior.condition(given_names, given_values.head(given_names.size()), expected, sd);
    for (size_t i = 0; i < prior.names.size(); ++i) {
      const int k = set.index(prior.names[i]);
      if (k < 0 || fit.given[k]) continue;
      fit.target(k) = expected(i);
      fit.target_sd(k) = sd(i);
      p.sigma(k) = std::max(sd(i) * p.m.o.completion_sd_factor, unit_sigma(prior.names[i], p.m.o));
    }
  }
  p.target = fit.target;
}

// Bounded Levenberg–Marquardt: a forward-difference Jacobian every `refresh_every` steps, Broyden
// rank-one updates between. Returns the iterations.
int descend(ProportionProblem& p, Eigen::VectorXd& x, Eigen::MatrixX3d& V, Eigen::VectorXd& v) {
  const ProportionFitOptions& o = p.m.o;
  const int P = p.P(), T = p.T();
  Eigen::VectorXd lo(P), hi(P), scale(P);
  for (int j = 0; j < P; ++j) lo(j) = p.ps[j].lo, hi(j) = p.ps[j].hi, scale(j) = p.ps[j].scale;
  Eigen::VectorXd r = p.residual(x, v);
  double cost = r.squaredNorm(), lambda = 1e-3;
  Eigen::MatrixXd D;
  int since = 0, it = 0;
  bool fresh = false;
  const Eigen::VectorXd inv_sigma = p.sigma.unaryExpr([](double s) { return std::isfinite(s) ? 1.0 / s : 0.0; });
  for (; it < o.max_iterations; ++it) {
    if (D.size() == 0 || since >= o.refresh_every) D = p.jacobian(x, V, v), since = 0, fresh = true;
    Eigen::MatrixXd J(T + P, P);
    J.topRows(T) = inv_sigma.asDiagonal() * D;
    J.bottomRows(P) = scale.cwiseInverse().asDiagonal();
    const Eigen::VectorXd g = J.transpose() * r;
    const std::vector<int> free = free_parameters(x, lo, hi, g);
    if (free.empty()) break;
    const FreeSystem system = free_system(J, r, free);
    bool accepted = false, converged = false;
    for (int attempt = 0; attempt < (fresh ? 8 : 3) && !accepted; ++attempt) {
      const Eigen::VectorXd xn = damped_step(x, lo, hi, system, lambda);
      Eigen::MatrixX3d Vn = p.body_of(xn);
      const Eigen::VectorXd vn = p.measure(Vn);
      const Eigen::VectorXd rn = p.residual(xn, vn);
      const double cn = rn.squaredNorm();
      const Eigen::VectorXd dx = xn - x;
      if (dx.squaredNorm() > 0 && vn.allFinite() && v.allFinite()) D += (vn - v - D * dx) * dx.transpose() / dx.squaredNorm();
      ++since;
      if (cn < cost) {
        converged = cost - cn < o.relative_tolerance * cost;
        x = xn, V = std::move(Vn), v = vn, r = rn, cost = cn;
        lambda = std::max(lambda / 3, 1e-7);
        accepted = true;
        fresh = false;
      } else {
        lambda *= 4;
      }
    }
    if (converged) return it + 1;
    if (!accepted) {
      if (fresh) break;
      since = o.refresh_every;
    }
  }
  return it;
}

}  // namespace

namespace {

// One fit with the parameters' prior scales times `stiffness` (the retry of a folded body moves
// the modifiers less), fold repair included.
// Where the trunk and limbs cross (inner thighs, a breast into the chest), pushes them apart
// (core/intersection_repair.h); kept when it removes intersections without adding a flipped
// triangle, and the body is measured again.
void push_apart_intersections(ProportionProblem& p, const ProportionFitter::Impl& m, const Eigen::MatrixX3d& reference,
                              ProportionFit& fit) {
  const Eigen::MatrixX3i& F = m.mh.body_faces();
  Eigen::MatrixX3d W = fit.V;
  repair_self_intersections(W, F, m.trunk_and_limb_faces);
  const int pairs = self_intersecting_triangle_pairs(W, F);
  const int flipped = count_flipped_triangles(W, reference, F);
  if (pairs >= fit.self_intersections || flipped > fit.flipped_triangles) return;
  fit.intersections_repaired = fit.self_intersections - pairs;
  fit.self_intersections = pairs;
  fit.flipped_triangles = flipped;
  fit.V = std::move(W);
  fit.measured = p.measure(fit.V);
}

ProportionFit fit_once(const ProportionFitter::Impl& m, Sex sex, double age_years,
                       const std::vector<ProportionTarget>& targets, const MeasurementPrior& prior, double stiffness) {
  std::vector<Parameter> ps = m.params[sex == Sex::male ? 1 : 0];
  for (auto& q : ps)
    if (q.macro < 0) q.scale *= stiffness;
  ProportionProblem p{m, ps, {}, {}, {}, 0, {}, {}};
  p.base.gender = sex == Sex::male ? 1.0 : 0.0;
  p.base.age = age_slider_for_years(age_years, true);
  ProportionFit fit;
  set_targets(p, targets, prior, fit);
  Eigen::VectorXd x(p.P());
  for (int j = 0; j < p.P(); ++j) x(j) = p.ps[j].prior;
  Eigen::MatrixX3d V = p.body_of(x);
  Eigen::VectorXd v = p.measure(V);
  fit.iterations = descend(p, x, V, v);
  fit.sliders = p.settings_of(x);
  fit.measure_modifiers = Eigen::VectorXd::Zero(m.mh.measure_modifier_names().size());
  fit.shape_modifiers = Eigen::VectorXd::Zero(m.mh.shape_modifiers().size());
  for (int j = 0; j < p.P(); ++j)
    for (int i : p.ps[j].modifiers)
      (m.modifiers[i].measure ? fit.measure_modifiers : fit.shape_modifiers)(m.modifiers[i].index) = x(j);
  // Strong modifiers can fold a few triangles where limbs meet the trunk (armpits, neck, under
  // the breasts): they are re-solved from the local shape of MakeHuman's own body with the same
  // macro sliders (core/fold_repair.h; fold-free, and shaped like the fit where the modifiers
  // leave it alone) and the body is measured again, so the measurements reported are those of
  // the repaired body.
  p.body_of(x);  // the macro body of x in the cache
  const Eigen::MatrixX3d reference = p.cached_body;
  FoldRepairOptions repair;
  repair.passes = m.o.fold_repair_passes;
  repair.max_displacement = m.o.fold_repair_max_mm;
  repair.smoothing_steps = m.o.fold_smoothing_steps;
  const FoldRepairSummary folds = repair_folds(V, reference, m.mh.body_faces(), repair);
  fit.flipped_before_repair = folds.flipped_before;
  fit.flipped_triangles = folds.flipped_after;
  if (folds.vertices_moved > 0) v = p.measure(V);
  fit.V = std::move(V);
  fit.measured = v;
  fit.evaluations = p.evaluations;
  fit.self_intersections = self_intersecting_triangle_pairs(fit.V, m.mh.body_faces());
  // A heavy body's arms press into its trunk in MakeHuman's own body too: the intersections the
  // modifiers add are those beyond the default body's and the macro body's own.
  fit.reference_self_intersections = m.template_self_intersections;
  if (fit.self_intersections > m.template_self_intersections)
    fit.reference_self_intersections =
        std::max(m.template_self_intersections, self_intersecting_triangle_pairs(reference, m.mh.body_faces()));
  if (m.o.intersection_repair && fit.self_intersections > fit.reference_self_intersections)
    push_apart_intersections(p, m, reference, fit);
  return fit;
}

}  // namespace

ProportionFit ProportionFitter::fit(Sex sex, double age_years, const std::vector<ProportionTarget>& targets,
                                    const MeasurementPrior& prior) const {
  const auto t0 = std::chrono::steady_clock::now();
  if (sex == Sex::unknown) throw InputError("fit: the sex is needed (female or male)");
  if (!(age_years >= 18 && age_years <= 90))
    throw InputError(fmt::format("fit: age {:g} years is outside the adult range 18–90", age_years));
  const Impl& m = *impl_;
  const auto faults = [](const ProportionFit& f) {
    return f.flipped_triangles + std::max(0, f.self_intersections - f.reference_self_intersections);
  };
  ProportionFit best = fit_once(m, sex, age_years, targets, prior, 1.0);
  int best_faults = faults(best);
  // A body that stays folded after the repair, or intersects itself more than MakeHuman's, is
  // fitted again with stiffer modifiers (about one in a hundred: its measurements then miss by a
  // little more; the body does not fold).
  for (int retry = 1, evaluations = best.evaluations; retry <= m.o.fold_retries && best_faults > 0; ++retry) {
    ProportionFit next = fit_once(m, sex, age_years, targets, prior, std::pow(0.5, retry));
    evaluations += next.evaluations;
    const int next_faults = faults(next);
    if (next_faults < best_faults) best = std::move(next), best_faults = next_faults;
    best.evaluations = evaluations;
    best.retries = retry;
  }
  best.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return best;
}

}  // namespace bodymodel
