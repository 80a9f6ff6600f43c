#include "population/fit_measurements.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>

#include "core/error.h"
#include "population/bounded_lm.h"

namespace bodymodel {

namespace {

// Parameter layout of the fit: 8 macro sliders, 3 raw ethnic weights (normalised when built),
// then one value per measurement modifier.
enum : int { kGender, kAge, kMuscle, kWeight, kHeight, kProportions, kCup, kFirmness, kAfrican, kAsian,
             kCaucasian, kMacroCount };
constexpr const char* kMacroNames[kMacroCount] = {"gender", "age", "muscle", "weight", "height", "proportions",
                                                  "cup", "firmness", "african", "asian", "caucasian"};

struct Range {
  double lo, hi;
};

// Physically possible values of a fittable measurement (bad-input check, not a prior).
Range plausible_range(const std::string& name) {
  if (name == "height_cm") return {50, 250};
  if (name == "weight_kg") return {20, 350};
  if (name == "upper_arm_length_cm" || name == "upper_leg_length_cm") return {10, 80};
  if (name == "arm_circumference_cm") return {12, 90};
  if (name == "neck_cm") return {20, 80};
  return {40, 250};  // torso girths
}

MacroSettings settings_of(const Eigen::VectorXd& x) {
  MacroSettings s;
  s.gender = x(kGender);
  s.age = x(kAge);
  s.muscle = x(kMuscle);
  s.weight = x(kWeight);
  s.height = x(kHeight);
  s.proportions = x(kProportions);
  s.cup = x(kCup);
  s.firmness = x(kFirmness);
  const double e = x(kAfrican) + x(kAsian) + x(kCaucasian);
  s.african = x(kAfrican) / e;
  s.asian = x(kAsian) / e;
  s.caucasian = 1.0 - s.african - s.asian;
  s.caucasian = std::clamp(s.caucasian, 0.0, 1.0);
  return s;
}

double reach_tolerance(const std::string& name, const FitMeasurementsOptions& o) {
  if (name == "height_cm") return o.reach_height_cm;
  if (name == "weight_kg") return o.reach_weight_kg;
  return o.reach_other_cm;
}

}  // namespace

const std::vector<std::string>& fittable_measurements() {
  static const std::vector<std::string> names = {
      "height_cm", "weight_kg", "waist_iliac_cm", "hips_cm", "arm_circumference_cm", "upper_arm_length_cm",
      "upper_leg_length_cm", "waist_cm", "chest_cm", "neck_cm"};
  return names;
}

void validate_measurement_names(const std::vector<std::string>& given) {
  const auto& names = fittable_measurements();
  std::set<std::string> seen;
  for (const auto& n : given) {
    if (std::find(names.begin(), names.end(), n) == names.end())
      throw InputError(fmt::format("unknown measurement '{}' (known: {})", n, fmt::join(names, ", ")));
    if (!seen.insert(n).second) throw InputError(fmt::format("measurement '{}' is given twice", n));
  }
}

void validate_measurement_targets(const std::vector<MeasurementTarget>& targets) {
  std::vector<std::string> given;
  for (const auto& t : targets) given.push_back(t.name);
  validate_measurement_names(given);
  for (const auto& t : targets) {
    if (!std::isfinite(t.value)) throw InputError(fmt::format("measurement '{}' is not a number", t.name));
    const Range r = plausible_range(t.name);
    if (t.value < r.lo || t.value > r.hi)
      throw InputError(fmt::format("{} = {:g} is impossible for an adult body (expected {:g} to {:g})", t.name,
                                   t.value, r.lo, r.hi));
  }
}

double age_slider_for_years(double years, bool adult_shape_below_25) {
  if (adult_shape_below_25 && years >= 18 && years < 25) return 0.5;
  if (years < 25) return std::clamp((years - 1.0) / 48.0, 0.0, 0.5);
  return std::clamp(0.5 + (years - 25.0) / 130.0, 0.5, 1.0);
}

std::string MeasurementFit::sliders_text() const {
  std::string s = fmt::format("gender={:.3f} age={:.3f} muscle={:.3f} weight={:.3f} height={:.3f} proportions={:.3f} "
                              "cup={:.3f} firmness={:.3f} african={:.3f} asian={:.3f} caucasian={:.3f}",
                              sliders.gender, sliders.age, sliders.muscle, sliders.weight, sliders.height,
                              sliders.proportions, sliders.cup, sliders.firmness, sliders.african, sliders.asian,
                              sliders.caucasian);
  return s;
}

namespace {

// The fit's problem: the person's targets and their scales, the parameters' prior, bounds, prior
// scales and difference steps, MakeHuman's own range, and the evaluation of a parameter vector
// (build, measure, residual), which counts the evaluations.
struct MeasurementProblem {
  const MakeHuman& mh;
  const PersonSpec& person;
  const FitMeasurementsOptions& o;
  int M, P, T;
  Eigen::VectorXd x0, lo, hi, scale, step;     // P: prior, bounds, prior scales, difference steps
  Eigen::VectorXd target, sigma;               // T: the targets and their scales
  Eigen::VectorXd range_lo, range_hi, s_ext;   // P: MakeHuman's range and the scale beyond it
  MeasureOptions mo;
  MakeHuman::BuildOptions bo;
  int evaluations = 0;

  MeasurementProblem(const MakeHuman& mh, const PersonSpec& person, const FitMeasurementsOptions& o)
      : mh(mh), person(person), o(o), M(static_cast<int>(mh.measure_modifier_names().size())),
        P(kMacroCount + M), T(static_cast<int>(person.targets.size())) {}

  Eigen::MatrixX3d body_of(const Eigen::VectorXd& x) const {
    return Eigen::MatrixX3d(mh.build_vertices(settings_of(x), x.tail(M), bo).topRows(MakeHuman::kBodyVertexCount));
  }
  Eigen::VectorXd measured(const Eigen::VectorXd& x) {
    ++evaluations;
    const BodyMeasurements m = measure_body(body_of(x), mh.body_faces(), person.sex, mo);
    Eigen::VectorXd v(T);
    for (int k = 0; k < T; ++k) v(k) = measurement_value(m, person.targets[k].name);
    return v;
  }
  // Beyond MakeHuman's range per parameter: the excess over s_ext (0 inside the range).
  Eigen::VectorXd excess(const Eigen::VectorXd& x) const {
    Eigen::VectorXd e(P);
    for (int j = 0; j < P; ++j) e(j) = (x(j) > range_hi(j) ? x(j) - range_hi(j) : x(j) < range_lo(j) ? x(j) - range_lo(j) : 0) / s_ext(j);
    return e;
  }
  // Residuals: the measurements against the targets, the prior, the excess.
  Eigen::VectorXd residual(const Eigen::VectorXd& x, const Eigen::VectorXd& v) const {
    Eigen::VectorXd r(T + 2 * P);
    for (int k = 0; k < T; ++k) r(k) = std::isfinite(v(k)) ? (v(k) - target(k)) / sigma(k) : 1e6;
    r.segment(T, P) = (x - x0).cwiseQuotient(scale);
    r.tail(P) = excess(x);
    return r;
  }
  bool within_stop(const Eigen::VectorXd& v) const {
    for (int k = 0; k < T; ++k) {
      const double tol = person.targets[k].name == "weight_kg" ? o.stop_kg : o.stop_cm;
      if (!(std::abs(v(k) - target(k)) <= tol)) return false;
    }
    return true;
  }
  // The Jacobian of the measured values (T by P) by forward differences at `at`.
  Eigen::MatrixXd difference_jacobian(const Eigen::VectorXd& at, const Eigen::VectorXd& v_at) {
    Eigen::MatrixXd D(T, P);
    for (int j = 0; j < P; ++j) {
      Eigen::VectorXd xj = at;
      double h = step(j);
      if (xj(j) + h > hi(j)) h = -h;
      xj(j) += h;
      const Eigen::VectorXd vj = measured(xj);
      for (int k = 0; k < T; ++k) D(k, j) = std::isfinite(vj(k)) && std::isfinite(v_at(k)) ? (vj(k) - v_at(k)) / h : 0;
    }
    return D;
  }
};

// The argument checks of fit_measurements: targets, age and sex, and measurement modifiers in
// the MakeHuman data.
void check_person(const MakeHuman& mh, const PersonSpec& person) {
  validate_measurement_targets(person.targets);
  if (!(person.age_years >= 1 && person.age_years <= 90))
    throw InputError(fmt::format("age {:g} years is outside MakeHuman's range (1 to 90)", person.age_years));
  if (person.sex == Sex::unknown) throw InputError("fit-measurements needs the sex (female or male)");
  if (mh.measure_modifier_names().empty())
    throw InputError("the MakeHuman data in '" + mh.directory().string() +
                     "' has no targets/measure folder (the measurement modifiers)");
}

// Prior, bounds and prior scales (gender and age fixed by the person, the extended space
// widening muscle, weight and the modifiers), the difference steps, and MakeHuman's own range
// per parameter: beyond it an extra residual (excess / s_ext) makes the extended space a last
// resort, used only where the standard space cannot reach.
void set_parameter_space(MeasurementProblem& p) {
  const FitMeasurementsOptions& o = p.o;
  const PersonSpec& person = p.person;
  const int M = p.M, P = p.P;
  const bool male = person.sex == Sex::male;
  Eigen::VectorXd &x0 = p.x0, &lo = p.lo, &hi = p.hi, &scale = p.scale, &step = p.step;
  x0.resize(P), lo.resize(P), hi.resize(P), scale.resize(P), step.resize(P);
  const double age = age_slider_for_years(person.age_years, o.adult_shape_below_25);
  x0 << (male ? 1.0 : 0.0), age, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, person.ethnic_prior[0], person.ethnic_prior[1],
      person.ethnic_prior[2];
  x0.tail(M).setZero();
  const bool ext = o.extended_space;
  lo << (male ? 0.9 : 0.0), std::max(o.adult_shape_below_25 && person.age_years >= 18 ? 0.5 : 0.0, age - 0.08),
      ext ? o.muscle_min : 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.01, 0.01, 0.01;
  hi << (male ? 1.0 : 0.1), std::min(1.0, age + 0.08), 1.0, ext ? o.weight_max : 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0,
      1.0;
  const double ml = ext ? o.modifier_limit : 1.0;
  lo.tail(M).setConstant(-ml);
  hi.tail(M).setConstant(ml);
  scale << o.prior_gender, o.prior_age, o.prior_muscle, o.prior_weight, o.prior_height, o.prior_proportions,
      o.prior_breast, o.prior_breast, o.prior_ethnic, o.prior_ethnic, o.prior_ethnic;
  scale.tail(M).setConstant(o.prior_modifier);
  step.head(kMacroCount).setConstant(0.02);
  step.tail(M).setConstant(0.05);
  for (int j = 0; j < 3; ++j) x0(kAfrican + j) = std::clamp(x0(kAfrican + j), lo(kAfrican + j), hi(kAfrican + j));
}

// Measurement scales and the measure options (band girths only when a band girth is asked).
void set_targets(MeasurementProblem& p) {
  const int T = p.T;
  p.target.resize(T), p.sigma.resize(T);
  p.mo = p.o.measure;
  p.mo.band_girths = false;
  for (int k = 0; k < T; ++k) {
    const auto& name = p.person.targets[k].name;
    p.target(k) = p.person.targets[k].value;
    p.sigma(k) = name == "weight_kg" ? p.o.sigma_kg : p.o.sigma_cm;
    if (name == "waist_cm" || name == "chest_cm" || name == "neck_cm") p.mo.band_girths = true;
  }
}

// MakeHuman's own range per parameter ([0, 1] for the sliders, [−1, 1] for the modifiers) and
// the scale of the excess beyond it.
void set_ranges(MeasurementProblem& p) {
  const int M = p.M, P = p.P;
  p.range_lo = Eigen::VectorXd::Zero(P), p.range_hi = Eigen::VectorXd::Ones(P), p.s_ext.resize(P);
  p.range_lo.tail(M).setConstant(-1.0);
  p.s_ext.head(kMacroCount).setConstant(p.o.extension_scale_slider);
  p.s_ext.tail(M).setConstant(p.o.extension_scale_modifier);
}

// A point of the descent: parameters, their measured values, residuals and cost.
struct FitPoint {
  Eigen::VectorXd x, v, r;
  double cost = 0;
};

// Start: the best point of a coarse grid over (muscle, weight), the two sliders that move the
// mass most and interact (MakeHuman's heavy bodies are its low-muscle, high-weight corner):
// from the default alone the descent ends at muscle 1 for heavy men, a local minimum.
FitPoint grid_start(MeasurementProblem& p) {
  const Eigen::VectorXd &x0 = p.x0, &lo = p.lo, &hi = p.hi;
  FitPoint s;
  Eigen::VectorXd &x = s.x, &v = s.v, &r = s.r;
  double& cost = s.cost;
  x = x0.cwiseMax(lo).cwiseMin(hi);
  v = p.measured(x);
  r = p.residual(x, v);
  cost = r.squaredNorm();
  if (p.T > 0) {
    std::vector<double> muscles = {lo(kMuscle), 0.25, 0.5, 0.75, 1.0}, weights = {0.0, 0.25, 0.5, 0.75, 1.0};
    if (hi(kWeight) > 1) weights.push_back(0.5 * (1 + hi(kWeight))), weights.push_back(hi(kWeight));
    for (double mu : muscles)
      for (double we : weights) {
        Eigen::VectorXd xs = x0;
        xs(kMuscle) = mu;
        xs(kWeight) = we;
        xs = xs.cwiseMax(lo).cwiseMin(hi);
        const Eigen::VectorXd vs = p.measured(xs);
        const Eigen::VectorXd rs = p.residual(xs, vs);
        if (rs.squaredNorm() < cost) x = xs, v = vs, r = rs, cost = rs.squaredNorm();
      }
  }
  return s;
}

// Bounded Levenberg–Marquardt from s. D (T by P) is the Jacobian of the measured values: by
// forward differences at the start and every `refresh_every` steps, Broyden rank-one updates
// between (a full difference Jacobian costs P evaluations, an update none). Returns the
// iterations.
int descend(MeasurementProblem& p, FitPoint& s) {
  const FitMeasurementsOptions& o = p.o;
  const int P = p.P, T = p.T;
  const Eigen::VectorXd &lo = p.lo, &hi = p.hi;
  Eigen::VectorXd &x = s.x, &v = s.v, &r = s.r;
  double& cost = s.cost;
  Eigen::MatrixXd D;
  int since_refresh = 0, polish = 0;
  double lambda = 1e-3;
  int it = 0;
  bool fresh = false;
  for (; it < o.max_iterations && T > 0; ++it) {
    if (D.size() == 0 || since_refresh >= o.refresh_every) {
      D = p.difference_jacobian(x, v);
      since_refresh = 0;
      fresh = true;
    }
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(T + 2 * P, P);
    J.topRows(T) = p.sigma.cwiseInverse().asDiagonal() * D;
    J.block(T, 0, P, P).diagonal() = p.scale.cwiseInverse();
    for (int j = 0; j < P; ++j)
      if (x(j) > p.range_hi(j) || x(j) < p.range_lo(j)) J(T + P + j, j) = 1.0 / p.s_ext(j);
    const Eigen::VectorXd g = J.transpose() * r;
    // Active set: sliders at a bound that the gradient pushes further out stay there.
    const std::vector<int> free = free_parameters(x, lo, hi, g);
    if (free.empty()) break;
    const FreeSystem system = free_system(J, r, free);
    bool accepted = false, converged = false;
    for (int attempt = 0; attempt < (fresh ? 10 : 3) && !accepted; ++attempt) {
      const Eigen::VectorXd xn = damped_step(x, lo, hi, system, lambda);
      const Eigen::VectorXd vn = p.measured(xn);
      const Eigen::VectorXd rn = p.residual(xn, vn);
      const double cn = rn.squaredNorm();
      // Broyden: the secant condition along the step actually taken.
      const Eigen::VectorXd dx = xn - x;
      if (dx.squaredNorm() > 0 && vn.allFinite() && v.allFinite())
        D += (vn - v - D * dx) * dx.transpose() / dx.squaredNorm();
      ++since_refresh;
      if (cn < cost) {
        // Converged once the targets are met and a step gains little, or after a few steps that
        // only polish which of the equally measuring bodies is returned (the prior part).
        if (p.within_stop(vn)) ++polish;
        converged = p.within_stop(vn) && (cost - cn < o.relative_tolerance * cost || polish >= o.polish_steps);
        x = xn, v = vn, r = rn, cost = cn;
        lambda = std::max(lambda / 3, 1e-7);
        accepted = true;
        fresh = false;
      } else {
        lambda *= 4;
      }
    }
    if (converged) {
      ++it;
      break;
    }
    if (!accepted) {
      if (fresh) break;          // no descent even along the difference Jacobian
      since_refresh = o.refresh_every;  // the Broyden estimate went stale: difference again
    }
  }
  return it;
}

// The fit at x: body, measurements (with the caller's measure options), quality figures, the
// residual per target and, when a target is missed, the reason (misses and sliders at a bound).
MeasurementFit fit_at(const MeasurementProblem& p, const Eigen::VectorXd& x, int it) {
  const MakeHuman& mh = p.mh;
  const FitMeasurementsOptions& o = p.o;
  const int M = p.M, P = p.P, T = p.T;
  const Eigen::MatrixX3i& F = mh.body_faces();
  MeasurementFit fit;
  fit.sliders = settings_of(x);
  fit.modifiers = x.tail(M);
  fit.V = p.body_of(x);
  fit.measured = measure_body(fit.V, F, p.person.sex, o.measure);
  fit.iterations = it;
  fit.roughness = roughness(fit.V, F, mh.trunk_and_limbs_region());
  fit.self_intersections = self_intersecting_triangle_pairs(fit.V, F);
  fit.evaluations = p.evaluations;
  fit.reached = true;
  std::vector<std::string> misses;
  for (int k = 0; k < T; ++k) {
    MeasurementResidual res;
    res.name = p.person.targets[k].name;
    res.target = p.target(k);
    res.achieved = measurement_value(fit.measured, res.name);
    res.within = std::abs(res.residual()) <= reach_tolerance(res.name, o);
    if (!res.within) {
      fit.reached = false;
      misses.push_back(fmt::format("{} {} by {:.1f}", res.name, res.residual() < 0 ? "short" : "over",
                                   std::abs(res.residual())));
    }
    fit.residuals.push_back(res);
  }
  for (int j = 0; j < P; ++j) {
    const bool outside = j < kAfrican ? (x(j) < -0.01 || x(j) > 1.01) : j >= kMacroCount && std::abs(x(j)) > 1.01;
    fit.extrapolated = fit.extrapolated || outside;
  }
  if (!fit.reached) {
    std::vector<std::string> bounds;
    for (int j = 0; j < P; ++j) {
      if (j == kGender || j == kAge || (j >= kAfrican && j < kMacroCount)) continue;  // fixed by the person
      if (x(j) <= p.lo(j) + 1e-9 || x(j) >= p.hi(j) - 1e-9) {
        const std::string name = j < kMacroCount ? kMacroNames[j] : mh.measure_modifier_names()[j - kMacroCount];
        bounds.push_back(fmt::format("{}={:.2f}", name, x(j)));
      }
    }
    fit.reason = fmt::format("{}; {}", fmt::join(misses, ", "),
                             bounds.empty() ? std::string("no slider at a bound (conflicting measurements)")
                                            : "sliders at their bound: " + fmt::format("{}", fmt::join(bounds, " ")));
  }
  return fit;
}

}  // namespace

MeasurementFit fit_measurements(const MakeHuman& mh, const PersonSpec& person, const FitMeasurementsOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  check_person(mh, person);
  MeasurementProblem p(mh, person, o);
  set_parameter_space(p);
  set_targets(p);
  p.bo.allow_extrapolation = true;
  set_ranges(p);

  FitPoint s = grid_start(p);
  const int it = descend(p, s);
  MeasurementFit fit = fit_at(p, s.x, it);
  fit.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return fit;
}

}  // namespace bodymodel

namespace bodymodel {

PlausibilityReport plausibility_against_makehuman(const MakeHuman& mh, const Eigen::MatrixX3d& V,
                                                  const Eigen::MatrixX3i& F, Sex sex, double age_years,
                                                  const FitMeasurementsOptions& options) {
  PlausibilityReport r;
  r.measured = measure_body(V, F, sex, options.measure);
  const std::vector<char> region = mh.trunk_and_limbs_region();
  r.roughness = roughness(V, F, region);
  r.self_intersections = self_intersecting_triangle_pairs(V, F);
  PersonSpec p;
  p.sex = sex == Sex::unknown ? Sex::female : sex;
  p.age_years = std::clamp(age_years, 18.0, 90.0);
  for (const char* n : {"height_cm", "weight_kg", "waist_iliac_cm", "hips_cm"}) {
    const double v = measurement_value(r.measured, n);
    const auto ok = [&] {
      try {
        validate_measurement_targets({{n, v}});
        return true;
      } catch (const InputError&) {
        return false;
      }
    }();
    if (ok) p.targets.push_back({n, v});
  }
  const MeasurementFit f = fit_measurements(mh, p, options);
  r.reference = f.roughness;
  r.reference_self_intersections = f.self_intersections;
  r.reference_reached = f.reached;
  return r;
}

}  // namespace bodymodel
