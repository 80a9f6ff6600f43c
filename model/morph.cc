#include "model/morph.h"

#include <algorithm>
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif
#include <chrono>
#include <cmath>
#include <limits>
#include "model/format.h"
#include <random>
#include <map>
#include <mutex>
#include <set>
#include <Eigen/LU>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/geometry.h"

namespace bodymodel {

std::optional<double> measured_label(const std::string& name, const BodyMeasurements& m) {
  if (!is_measurable_label(name)) return std::nullopt;
  const double v = measurement_value(m, name);
  if (std::isfinite(v)) return v;
  return std::nullopt;
}

bool is_measurable_label(const std::string& name) {
  static const std::set<std::string> names = {"height_cm", "weight_kg", "waist_cm", "hips_cm", "chest_cm", "neck_cm",
                                              "volume_l", "body_fat_pct", "waist_iliac_cm", "arm_circumference_cm",
                                              "upper_arm_length_cm", "upper_leg_length_cm"};
  return names.count(name) > 0;
}

std::string MorphSummary::report() const {
  std::string s = fmt::format("{} after {} iteration(s), |z| = {:.3g}\n",
                              converged ? "converged" : "NOT converged", iterations, change_norm);
  for (const auto& l : labels)
    s += fmt::format("  {:<14} start {:>9.3f}  target {:>9.3f}  achieved {:>9.3f} ({})  {}\n", l.label,
                     l.start, l.target, l.achieved, l.measured ? "measured" : "predicted",
                     l.satisfied ? "ok" : "MISSED");
  return s;
}

// The measured response of the conditions' labels to a requested change d (label units, the
// eq. 11 request): measured labels change by f(d) = θ·φ(u), u = d's measured components,
// φ(u) = (u_j, u_j², u_j u_l for j < l); other labels by d itself (their value is the
// regression's, met exactly).
struct ShapeMorpher::Response {
  bool usable = false;           // false: unit slope (the regression as the response)
  std::vector<int> measured;     // condition indices of the measured labels (k)
  std::vector<int> other;        // condition indices of unmeasured labels with a linear effect
  bool cross = false;            // φ has the u_j u_l terms
  Eigen::VectorXd anchor_value;  // m: at the anchor, measured where measurable
  Eigen::VectorXd anchor_predicted;  // m: the regression's values at the anchor
  Eigen::VectorXd anchor;        // K: the anchor's coefficients
  Eigen::MatrixXd theta;         // k by #φ

  int terms() const {
    const int k = static_cast<int>(measured.size());
    return 2 * k + (cross ? k * (k - 1) / 2 : 0) + static_cast<int>(other.size());
  }
  // φ(d): the measured labels' terms, then the other labels' requested changes (linear).
  Eigen::VectorXd phi(const Eigen::VectorXd& d) const {
    const Eigen::VectorXd u = measured_part(d);
    const int k = static_cast<int>(u.size());
    Eigen::VectorXd p(terms());
    int t = 0;
    for (int j = 0; j < k; ++j) p(t++) = u(j);
    for (int j = 0; j < k; ++j) p(t++) = u(j) * u(j);
    if (cross)
      for (int j = 0; j < k; ++j)
        for (int l = j + 1; l < k; ++l) p(t++) = u(j) * u(l);
    for (int j : other) p(t++) = d(j);
    return p;
  }
  Eigen::VectorXd measured_part(const Eigen::VectorXd& d) const {
    Eigen::VectorXd u(measured.size());
    for (size_t j = 0; j < measured.size(); ++j) u(j) = d(measured[j]);
    return u;
  }
  // f(d), m values.
  Eigen::VectorXd change(const Eigen::VectorXd& d) const {
    Eigen::VectorXd f = d;
    if (!usable) return f;
    const Eigen::VectorXd fm = theta * phi(d);
    for (size_t i = 0; i < measured.size(); ++i) f(measured[i]) = fm(i);
    return f;
  }
  // ∂f/∂d at d, m by m.
  Eigen::MatrixXd jacobian(const Eigen::VectorXd& d) const {
    const int m = static_cast<int>(d.size()), k = static_cast<int>(measured.size());
    Eigen::MatrixXd J = Eigen::MatrixXd::Identity(m, m);
    if (!usable) return J;
    const Eigen::VectorXd u = measured_part(d);
    Eigen::MatrixXd Ju = Eigen::MatrixXd::Zero(k, k);  // ∂φ-part/∂u
    for (int i = 0; i < k; ++i) {
      int t = 2 * k;
      for (int j = 0; j < k; ++j) Ju(i, j) = theta(i, j) + 2 * theta(i, k + j) * u(j);
      if (cross)
        for (int j = 0; j < k; ++j)
          for (int l = j + 1; l < k; ++l, ++t) {
            Ju(i, j) += theta(i, t) * u(l);
            Ju(i, l) += theta(i, t) * u(j);
          }
    }
    const int first_other = terms() - static_cast<int>(other.size());
    for (int i = 0; i < k; ++i) {
      J.row(measured[i]).setZero();
      for (int j = 0; j < k; ++j) J(measured[i], measured[j]) = Ju(i, j);
      for (size_t j = 0; j < other.size(); ++j) J(measured[i], other[j]) = theta(i, first_other + j);
    }
    return J;
  }
  // The request d with f(d) = g (Newton on the model from the slope at 0; the best iterate if
  // it does not converge).
  Eigen::VectorXd request_for(const Eigen::VectorXd& g, const Eigen::VectorXd& scale) const {
    Eigen::FullPivLU<Eigen::MatrixXd> lu0(jacobian(Eigen::VectorXd::Zero(g.size())));
    Eigen::VectorXd d = lu0.solve(g);
    if (!usable) return d;
    Eigen::VectorXd best = d;
    double best_r = ((g - change(d)).array() / scale.array()).abs().maxCoeff();
    for (int it = 0; it < 10 && best_r > 1e-3; ++it) {
      Eigen::FullPivLU<Eigen::MatrixXd> lu(jacobian(d));
      if (!lu.isInvertible()) break;
      d += lu.solve(g - change(d));
      const double r = ((g - change(d)).array() / scale.array()).abs().maxCoeff();
      if (!std::isfinite(r)) break;
      if (r < best_r) best_r = r, best = d;
    }
    return best;
  }
};

struct ShapeMorpher::ResponseCache {
  std::mutex mutex;
  std::map<std::string, std::shared_ptr<const Response>> responses;  // by label set, sex, anchor
};

namespace {

// acc[0 .. rows) += c · b[0 .. rows), b float32: the inner loop of ShapeMorpher::reconstruct. Where
// the CPU has AVX2 and FMA (checked once at run time, as encoding/block_cholesky.cc does; the
// project is built for plain x86-64) four values per instruction, fused (rounded once).
void float_axpy_portable(int rows, double c, const float* b, double* acc) {
  for (int r = 0; r < rows; ++r) acc[r] += static_cast<double>(b[r]) * c;
}
#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("avx2,fma"))) void float_axpy_avx2(int rows, double c, const float* b, double* acc) {
  const __m256d cc = _mm256_set1_pd(c);
  int r = 0;
  for (; r + 8 <= rows; r += 8) {
    const __m256d a0 = _mm256_fmadd_pd(_mm256_cvtps_pd(_mm_loadu_ps(b + r)), cc, _mm256_loadu_pd(acc + r));
    const __m256d a1 = _mm256_fmadd_pd(_mm256_cvtps_pd(_mm_loadu_ps(b + r + 4)), cc, _mm256_loadu_pd(acc + r + 4));
    _mm256_storeu_pd(acc + r, a0);
    _mm256_storeu_pd(acc + r + 4, a1);
  }
  for (; r < rows; ++r) acc[r] += static_cast<double>(b[r]) * c;
}
#endif
using FloatAxpy = void (*)(int, double, const float*, double*);
FloatAxpy float_axpy_kernel() {
#if defined(__x86_64__) && defined(__GNUC__)
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return float_axpy_avx2;
#endif
  return float_axpy_portable;
}
const FloatAxpy float_axpy = float_axpy_kernel();

}  // namespace

// The float32 copy of the shape basis reconstruct() reads (empty when some value is not a float).
struct ShapeMorpher::FloatBasis {
  std::once_flag once;
  Eigen::MatrixXf basis;
  bool exact = false;
};

ShapeMorpher::ShapeMorpher(std::shared_ptr<const BodyModel> model, DecoderOptions options)
    : model_(std::move(model)),
      decoder_(model_->tmpl, options),
      response_cache_(std::make_shared<ResponseCache>()),
      float_basis_(std::make_shared<FloatBasis>()) {}

Eigen::VectorXd ShapeMorpher::reconstruct(const Eigen::VectorXd& c) const {
  const Pca& pca = model_->shape.pca;
  FloatBasis& fb = *float_basis_;
  std::call_once(fb.once, [&] {
    fb.basis = pca.basis.cast<float>();
    fb.exact = pca.basis.allFinite() && fb.basis.cast<double>() == pca.basis;
    if (!fb.exact) fb.basis.resize(0, 0);
  });
  if (!fb.exact || c.size() != pca.basis.cols()) return pca.reconstruct(c);
  // mean + basis·c a block of rows at a time: the block's sums stay in L1 while the K columns'
  // segments stream through once.
  const Eigen::Index n = fb.basis.rows(), k = fb.basis.cols();
  constexpr Eigen::Index kRows = 2048;
  Eigen::VectorXd x(n);
  std::vector<double> acc(kRows);
  for (Eigen::Index r0 = 0; r0 < n; r0 += kRows) {
    const int rows = static_cast<int>(std::min(kRows, n - r0));
    std::fill(acc.begin(), acc.begin() + rows, 0.0);
    for (Eigen::Index j = 0; j < k; ++j) float_axpy(rows, c(j), fb.basis.data() + j * n + r0, acc.data());
    for (int r = 0; r < rows; ++r) x(r0 + r) = pca.mean(r0 + r) + acc[r];
  }
  return x;
}

Eigen::MatrixX3d ShapeMorpher::decode(const Eigen::VectorXd& x) const {
  return decoder_.decode(model_->encoding_of(x));
}

BodyMeasurements ShapeMorpher::measure(const Eigen::MatrixX3d& V, Sex sex) const {
  return measure_body(V, model_->tmpl->faces(), sex);
}

namespace {

// The eq. 11 options of a morph: with prior_weighted, the metric of the model's eigenvalues.
ConstrainedChangeOptions change_options(const SubModel& sm, const MorphOptions& o) {
  ConstrainedChangeOptions c = o.change;
  if (o.prior_weighted) c.metric = sm.pca.eigenvalues.cwiseMax(1e-12 * std::max(1e-300, sm.pca.eigenvalues.maxCoeff()));
  return c;
}

double tolerance_for(const LabelInfo& info, const MorphOptions& o) {
  if (info.unit == "cm") return o.tolerance_cm;
  if (info.unit == "kg") return o.tolerance_kg;
  return o.tolerance_other * std::max(info.stddev, 1e-9);
}

// The targets of `conditions` as text: "height_cm = 150, waist_cm 60 … 70, weight_kg kept".
std::string targets_text(const std::vector<LabelCondition>& conditions) {
  std::string s;
  for (const auto& c : conditions) {
    s += s.empty() ? "" : ", ";
    if (c.keep) s += c.label + " kept";
    else if (c.lo == c.hi) s += fmt::format("{} = {:.4g}", c.label, c.lo);
    else s += fmt::format("{} {:.4g} … {:.4g}", c.label, c.lo, c.hi);
  }
  return s;
}

// The conditions' label values of a body: measured on V where a mesh can tell (height and
// weight/volume only: the fast measure_height_and_weight), else the regression's prediction
// from the coefficients c.
Eigen::VectorXd label_values(const ShapeMorpher& morpher, const std::vector<LabelCondition>& conditions,
                             const std::vector<int>& idx, const Eigen::VectorXd& c, const Eigen::MatrixX3d& V,
                             Sex sex) {
  const int m = static_cast<int>(conditions.size());
  bool any_measured = false, only_extent_and_volume = true;
  for (auto& cond : conditions)
    if (is_measurable_label(cond.label)) {
      any_measured = true;
      if (cond.label != "height_cm" && cond.label != "weight_kg" && cond.label != "volume_l")
        only_extent_and_volume = false;
    }
  Eigen::VectorXd v(m);
  Eigen::VectorXd pred = morpher.model().shape.regression.predict(c);
  std::optional<BodyMeasurements> meas;
  if (any_measured && only_extent_and_volume) {
    // Fast path, the same definitions as measure_body (core/measure.h) without the girth
    // sections: height = extent along +y, weight = enclosed volume × density.
    meas = measure_height_and_weight(V, morpher.model().tmpl->faces());
  } else if (any_measured) {
    meas = measure_morphed(morpher, V, sex, conditions);
  }
  for (int i = 0; i < m; ++i) {
    std::optional<double> mv;
    if (meas) mv = measured_label(conditions[i].label, *meas);
    v(i) = mv ? *mv : pred(idx[i]);
  }
  return v;
}

}  // namespace

std::shared_ptr<const ShapeMorpher::Response> ShapeMorpher::measured_response(
    const std::vector<LabelCondition>& conditions, const MorphOptions& o) const {
  const SubModel& sm = model_->shape;
  const int m = static_cast<int>(conditions.size());
  const int K = sm.component_count();
  const Eigen::VectorXd anchor =
      o.response_anchor.size() == K ? o.response_anchor : Eigen::VectorXd(Eigen::VectorXd::Zero(K));
  std::string key = std::to_string(static_cast<int>(o.sex)) + (o.prior_weighted ? "|likely" : "");
  for (auto& c : conditions) key += "|" + c.label;
  key.append(reinterpret_cast<const char*>(anchor.data()), sizeof(double) * K);
  // Held while calibrating: a second caller with the same key waits instead of repeating it
  // (prepare() calibrates before a crowd's parallel loop, so workers rarely wait here).
  std::lock_guard<std::mutex> lock(response_cache_->mutex);
  auto found = response_cache_->responses.find(key);
  if (found != response_cache_->responses.end()) return found->second;
  auto r = std::make_shared<Response>();
  r->anchor = anchor;
  std::vector<int> idx(m);
  Eigen::MatrixXd S(K, m);
  for (int i = 0; i < m; ++i) {
    idx[i] = sm.regression.index(conditions[i].label);
    S.col(i) = sm.regression.gradients.col(idx[i]);
    if (is_measurable_label(conditions[i].label))
      r->measured.push_back(i);
    else if (conditions[i].label != "sex")  // the sex of a crowd's body is its start's
      r->other.push_back(i);
  }
  const int k = static_cast<int>(r->measured.size());
  r->cross = k <= 4;
  const Eigen::VectorXd pred = sm.regression.predict(anchor);
  r->anchor_predicted.resize(m);
  for (int i = 0; i < m; ++i) r->anchor_predicted(i) = pred(idx[i]);
  // Calibration requests: 0, ±step_j e_j, and step_j e_j + step_l e_l. Steps of 1.5 standard
  // deviations of the label in the data (the spread a population asks for), shortened to stay
  // inside the data's range (at least a quarter of a standard deviation).
  std::vector<Eigen::VectorXd> requests(1, Eigen::VectorXd::Zero(m));
  Eigen::VectorXd plus = Eigen::VectorXd::Zero(m);
  for (int j : r->measured) {
    const LabelInfo& info = sm.regression.labels[idx[j]];
    const double sd = std::max(info.stddev, 1e-9);
    const double up = std::clamp(info.max - pred(idx[j]), 0.25 * sd, 1.5 * sd);
    const double down = std::clamp(pred(idx[j]) - info.min, 0.25 * sd, 1.5 * sd);
    Eigen::VectorXd d = Eigen::VectorXd::Zero(m);
    d(j) = up;
    requests.push_back(d);
    d(j) = -down;
    requests.push_back(d);
    plus(j) = up;
  }
  // The other labels' effect on the measured ones (age changes weight at a constant predicted
  // weight: −0.04 kg per year on the population model): one step each, a linear term.
  for (int j : r->other) {
    const LabelInfo& info = sm.regression.labels[idx[j]];
    const double sd = std::max(info.stddev, 1e-9);
    Eigen::VectorXd d = Eigen::VectorXd::Zero(m);
    d(j) = std::clamp(info.max - pred(idx[j]), 0.25 * sd, 1.5 * sd);
    requests.push_back(d);
  }
  if (r->cross)
    for (int a = 0; a < k; ++a)
      for (int b = a + 1; b < k; ++b) {
        Eigen::VectorXd d = Eigen::VectorXd::Zero(m);
        d(r->measured[a]) = plus(r->measured[a]);
        d(r->measured[b]) = plus(r->measured[b]);
        requests.push_back(d);
      }
  std::vector<Eigen::VectorXd> values(requests.size());
  const auto opts = change_options(sm, o);
  tbb::parallel_for(0, static_cast<int>(requests.size()), [&](int q) {
    const Eigen::VectorXd z = requests[q].isZero() ? Eigen::VectorXd(Eigen::VectorXd::Zero(K))
                                                   : constrained_change(S, requests[q], opts);
    const Eigen::VectorXd c = anchor + z;
    values[q] = label_values(*this, conditions, idx, c, decode(reconstruct(c)), o.sex);
  });
  r->anchor_value = values[0];
  if (k > 0) {
    // θ from the calibration points: one exact (square) solve per measured label.
    const int nt = r->terms();
    Eigen::MatrixXd Phi(nt, nt), Y(nt, k);
    for (int q = 1; q <= nt; ++q) {
      Phi.row(q - 1) = r->phi(requests[q]).transpose();
      for (int i = 0; i < k; ++i) Y(q - 1, i) = values[q](r->measured[i]) - values[0](r->measured[i]);
    }
    Eigen::FullPivLU<Eigen::MatrixXd> lu(Phi);
    if (lu.isInvertible() && Y.allFinite() && values[0].allFinite()) {
      r->theta = lu.solve(Y).transpose();
      r->usable = r->theta.allFinite();
      // Not a usable response (a slope out of [0.2, 5] at the anchor): the unit slope.
      for (int i = 0; i < k && r->usable; ++i)
        if (!(r->theta(i, i) > 0.2 && r->theta(i, i) < 5)) r->usable = false;
      if (r->usable) {
        Eigen::FullPivLU<Eigen::MatrixXd> j0(r->jacobian(Eigen::VectorXd::Zero(m)));
        r->usable = j0.isInvertible() && j0.rcond() > 1e-3;
      }
    }
  }
  response_cache_->responses[key] = r;
  return r;
}

void ShapeMorpher::prepare(const std::vector<LabelCondition>& conditions, const MorphOptions& options) const {
  bool any_measured = false;
  for (auto& c : conditions) any_measured = any_measured || is_measurable_label(c.label);
  if (options.calibrated_response && options.triangle_mask.size() == 0 && any_measured)
    measured_response(conditions, options);
}

namespace {

// The regression index of each condition's label, checked (each label once, non-empty ranges),
// and whether any label is measured on the body rather than only predicted.
struct ConditionLabels {
  std::vector<int> idx;
  bool any_measured = false;
};

ConditionLabels condition_labels(const SemanticRegression& reg, const std::vector<LabelCondition>& conditions) {
  const int m = static_cast<int>(conditions.size());
  ConditionLabels cl;
  cl.idx.resize(m);
  std::set<std::string> seen;
  for (int i = 0; i < m; ++i) {
    cl.idx[i] = reg.index(conditions[i].label);
    if (!seen.insert(conditions[i].label).second)
      throw InputError(fmt::format("label '{}' is given more than once", conditions[i].label));
    if (!conditions[i].keep && !(conditions[i].lo <= conditions[i].hi))
      throw InputError(fmt::format("label '{}': empty range {}..{}", conditions[i].label,
                                   conditions[i].lo, conditions[i].hi));
    cl.any_measured = cl.any_measured || is_measurable_label(conditions[i].label);
  }
  return cl;
}

// Per condition the value aimed at, the accepted interval and the tolerance: the start value for
// a kept label, the value of an exact condition, else the start clamped into the range's margins
// (or moved to range_aim). all_ok and badness judge a candidate's values against them.
struct LabelTargets {
  Eigen::VectorXd target, lo, hi, tol;

  bool all_ok(const Eigen::VectorXd& v) const {
    for (Eigen::Index i = 0; i < lo.size(); ++i)
      if (v(i) < lo(i) || v(i) > hi(i)) return false;
    return true;
  }
  // The largest distance outside its interval, in tolerances.
  double badness(const Eigen::VectorXd& v) const {
    double b = 0;
    for (Eigen::Index i = 0; i < lo.size(); ++i) {
      double e = v(i) < lo(i) ? lo(i) - v(i) : v(i) > hi(i) ? v(i) - hi(i) : 0;
      b = std::max(b, e / tol(i));
    }
    return b;
  }
};

LabelTargets label_targets(const SemanticRegression& reg, const std::vector<LabelCondition>& conditions,
                           const std::vector<int>& idx, const Eigen::VectorXd& start, const MorphOptions& o) {
  const int m = static_cast<int>(conditions.size());
  LabelTargets t{Eigen::VectorXd(m), Eigen::VectorXd(m), Eigen::VectorXd(m), Eigen::VectorXd(m)};
  Eigen::VectorXd &target = t.target, &lo = t.lo, &hi = t.hi, &tol = t.tol;
  for (int i = 0; i < m; ++i) {
    const LabelCondition& c = conditions[i];
    const LabelInfo& info = reg.labels[idx[i]];
    tol(i) = tolerance_for(info, o);
    if (c.keep) {
      target(i) = start(i);
      lo(i) = start(i) - tol(i);
      hi(i) = start(i) + tol(i);
    } else if (c.lo == c.hi) {
      target(i) = c.lo;
      lo(i) = c.lo - tol(i);
      hi(i) = c.hi + tol(i);
    } else {
      double margin = o.range_margin * (c.hi - c.lo);
      if (o.range_aim >= 0 && (start(i) < c.lo + margin || start(i) > c.hi - margin))
        target(i) = c.lo + margin + std::min(o.range_aim, 1.0) * (c.hi - c.lo - 2 * margin);
      else
        target(i) = std::clamp(start(i), c.lo + margin, c.hi - margin);
      lo(i) = c.lo;
      hi(i) = c.hi;
    }
  }
  return t;
}

}  // namespace

Eigen::MatrixX3d ShapeMorpher::morph_encoding(const Eigen::VectorXd& x0_given,
                                              const std::vector<LabelCondition>& conditions,
                                              const MorphOptions& o, MorphSummary* summary,
                                              Eigen::VectorXd* x_out, const Eigen::VectorXd* c0_known) const {
  auto t0 = std::chrono::steady_clock::now();
  const SubModel& sm = model_->shape;
  // The start's shape coefficients. Without a mask every candidate is x0 + basis·z, whose
  // coefficients are c0 + z (orthonormal basis): no D-sized projection per iteration (each
  // costs as much memory traffic as reading the whole basis).
  if (x0_given.size() == 0 && !c0_known) throw InputError("morph: neither a start encoding nor its coefficients");
  // x0 is needed only to decode the start or mask a change; else every candidate is made from c0.
  const bool masked = o.triangle_mask.size() != 0;
  bool any_keep_ = false;
  for (auto& c : conditions) any_keep_ = any_keep_ || c.keep;
  const bool need_x0 = masked || any_keep_ || conditions.empty() || o.max_iterations <= 0;
  const Eigen::VectorXd x0 =
      x0_given.size() == 0 && need_x0 ? reconstruct(*c0_known) : x0_given;
  const Eigen::VectorXd c0 = c0_known ? *c0_known : sm.pca.project(x0);
  const SemanticRegression& reg = sm.regression;
  const int m = static_cast<int>(conditions.size());
  const ConditionLabels labels = condition_labels(reg, conditions);
  const std::vector<int>& idx = labels.idx;
  const bool any_measured = labels.any_measured;
  if (o.triangle_mask.size() != 0 && o.triangle_mask.size() != model_->tmpl->triangle_count())
    throw InputError(fmt::format("mask has {} entries, the model has {} triangles", o.triangle_mask.size(),
                                 model_->tmpl->triangle_count()));
  Eigen::MatrixXd S(sm.component_count(), m);
  for (int i = 0; i < m; ++i) S.col(i) = reg.gradients.col(idx[i]);

  auto values = [&](const Eigen::VectorXd& x, const Eigen::VectorXd& z, const Eigen::MatrixX3d& V) {
    return label_values(*this, conditions, idx, masked ? sm.pca.project(x) : Eigen::VectorXd(c0 + z), V, o.sex);
  };
  auto apply_change = [&](const Eigen::VectorXd& z) {
    // Without x0 (see the header): mean + basis·(c0 + z), one pass over the basis.
    if (x0.size() == 0) return reconstruct(c0 + z);
    Eigen::VectorXd x = x0 + sm.pca.basis * z;
    if (masked) x = masked_change(model_->encoding_of(x0), model_->encoding_of(x), o.triangle_mask).values;
    return x;
  };

  // The start values: measured on the decoded start body when a label must be kept (its
  // measured value is the target); otherwise predicted by the regression (eq. 10), which saves
  // a decode — the first iteration then decodes and measures.
  bool any_keep = false;
  for (auto& c : conditions) any_keep = any_keep || c.keep;
  const bool start_measured = any_keep || m == 0 || o.max_iterations <= 0;
  int decodes = 0;
  Eigen::MatrixX3d V;
  Eigen::VectorXd start(m);
  if (start_measured) {
    V = decode(x0);
    ++decodes;
    start = values(x0, Eigen::VectorXd::Zero(c0.size()), V);
  } else {
    Eigen::VectorXd pred = reg.predict(c0);
    for (int i = 0; i < m; ++i) start(i) = pred(idx[i]);
  }
  // The measured response (MorphOptions::calibrated_response), or none (unit slope).
  const bool calibrated = o.calibrated_response && !masked && any_measured;
  const std::shared_ptr<const Response> response =
      calibrated ? measured_response(conditions, o) : std::make_shared<const Response>();
  if (!start_measured && response->usable) {
    // At the anchor the start is known as measured; elsewhere the regression's value corrected
    // by its error at the anchor (see MorphOptions::response_anchor).
    const bool at_anchor = c0.size() == response->anchor.size() && c0 == response->anchor;
    for (int i : response->measured)
      start(i) = at_anchor ? response->anchor_value(i)
                           : start(i) + response->anchor_value(i) - response->anchor_predicted(i);
  }
  const LabelTargets t = label_targets(reg, conditions, idx, start, o);
  const Eigen::VectorXd &target = t.target, &lo = t.lo, &hi = t.hi, &tol = t.tol;

  // The request whose modelled response is the remaining change (with the unit slope: the
  // change itself).
  Eigen::VectorXd delta = response->request_for(target - start, tol);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(sm.component_count());
  Eigen::VectorXd x = x0, best_x = x0, v = start, best_v = start;
  Eigen::MatrixX3d best_V = V;
  double best_bad = start_measured ? t.badness(start) : std::numeric_limits<double>::infinity();
  int it = 0;
  bool ok = start_measured && t.all_ok(start);
  while (!ok && it < o.max_iterations) {
    ++it;
    z = constrained_change(S, delta, change_options(sm, o));
    x = apply_change(z);
    V = decode(x);
    ++decodes;
    v = values(x, z, V);
    double bad = t.badness(v);
    if (bad < best_bad) {
      best_bad = bad;
      best_x = x;
      best_v = v;
      best_V = V;
    }
    ok = t.all_ok(v);
    // Newton-like correction on the measured value: the remaining error, through the measured
    // response's Jacobian at the current request (or with a unit slope: the regression as the
    // Jacobian's estimate).
    {
      Eigen::FullPivLU<Eigen::MatrixXd> lu(response->jacobian(delta));
      delta += lu.isInvertible() ? Eigen::VectorXd(lu.solve(target - v)) : Eigen::VectorXd(target - v);
    }
  }
  if (summary) {
    summary->iterations = it;
    summary->converged = ok;
    summary->change_norm = z.norm();
    summary->labels.clear();
    for (int i = 0; i < m; ++i)
      summary->labels.push_back({conditions[i].label, target(i), lo(i), hi(i), start(i), best_v(i),
                                 is_measurable_label(conditions[i].label) &&
                                     !(conditions[i].label == "body_fat_pct" && o.sex == Sex::unknown),
                                 best_v(i) >= lo(i) && best_v(i) <= hi(i)});
    summary->decodes = decodes;
    summary->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  if (x_out) *x_out = best_x;
  return best_V;
}

Eigen::MatrixX3d ShapeMorpher::morph(const Eigen::MatrixX3d& V, const std::vector<LabelCondition>& conditions,
                                     const MorphOptions& options, MorphSummary* summary) const {
  Encoding e = model_->encode(V, "input body");
  Eigen::MatrixX3d out = morph_encoding(e.values, conditions, options, summary);
  RigidMotion r = fit_rigid_motion(out, V);
  out = apply(r, out);
  out.col(1).array() += V.col(1).minCoeff() - out.col(1).minCoeff();
  return out;
}

namespace {

// The measured labels of a summary re-measured on V (after a fold repair moved vertices):
// achieved and satisfied as measured on the body that is returned.
void remeasure_labels(const ShapeMorpher& morpher, const Eigen::MatrixX3d& V, Sex sex, MorphSummary& summary,
                      const std::vector<LabelCondition>& conditions) {
  bool any = false, only_extent_and_volume = true;
  for (auto& l : summary.labels)
    if (l.measured) {
      any = true;
      if (l.label != "height_cm" && l.label != "weight_kg" && l.label != "volume_l") only_extent_and_volume = false;
    }
  if (!any) return;
  const BodyMeasurements meas = only_extent_and_volume ? measure_height_and_weight(V, morpher.model().tmpl->faces())
                                                       : measure_morphed(morpher, V, sex, conditions);
  for (auto& l : summary.labels) {
    if (!l.measured) continue;
    if (auto mv = measured_label(l.label, meas)) {
      l.achieved = *mv;
      l.satisfied = l.achieved >= l.lo && l.achieved <= l.hi;
    }
  }
}

}  // namespace

namespace {

// The sampling of generate_body: the conditions' sex's subjects (none without a sex condition),
// their mean coefficients, and the morph options with that sex and the mean as the anchor of the
// measured response (MorphOptions::response_anchor).
struct GenerationSetup {
  std::vector<int> pool;
  Eigen::VectorXd mu;
  MorphOptions mo;
};

GenerationSetup generation_setup(const ShapeMorpher& morpher, const std::vector<LabelCondition>& conditions,
                                 const GenerateOptions& o) {
  check_generate_options(o);
  const SubModel& sm = morpher.model().shape;
  GenerationSetup g;
  int sex_label = sm.regression.find("sex");
  Sex sex = Sex::unknown;
  for (auto& c : conditions)
    if (c.label == "sex" && !c.keep && c.lo == c.hi && sex_label >= 0) {
      sex = c.lo < 0.5 ? Sex::female : Sex::male;
      for (int i = 0; i < sm.labels.rows(); ++i)
        if (std::isfinite(sm.labels(i, sex_label)) && std::abs(sm.labels(i, sex_label) - c.lo) < 0.5)
          g.pool.push_back(i);
    }
  g.mo = o.morph;
  if (g.mo.sex == Sex::unknown) g.mo.sex = sex;
  if (g.pool.size() >= 2) {
    g.mu = Eigen::VectorXd::Zero(sm.component_count());
    for (int i : g.pool) g.mu += sm.pca.coefficients.row(i).transpose();
    g.mu /= g.pool.size();
    if (g.mo.response_anchor.size() == 0) g.mo.response_anchor = g.mu;
  }
  return g;
}

}  // namespace

void check_generate_options(const GenerateOptions& o) {
  // A negative spread flips the random coefficients' signs and NaN makes NaN bodies: refused
  // here, so every caller (CLI, Python, server) says the same.
  if (!(std::isfinite(o.spread) && o.spread >= 0))
    throw InputError(fmt::format("generate: spread must be a finite number ≥ 0, got {}", o.spread));
}

void prepare_generation(const ShapeMorpher& morpher, const std::vector<LabelCondition>& conditions,
                        const GenerateOptions& options) {
  morpher.prepare(conditions, generation_setup(morpher, conditions, options).mo);
}

GeneratedBody generate_body(const ShapeMorpher& morpher, const std::vector<LabelCondition>& conditions,
                            uint64_t seed, const GenerateOptions& o) {
  const BodyModel& model = morpher.model();
  const SubModel& sm = model.shape;
  const int K = sm.component_count();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  // Sex-specific sampling pool.
  GenerationSetup setup = generation_setup(morpher, conditions, o);
  const std::vector<int>& pool = setup.pool;
  GeneratedBody best;
  double best_missed = 1e300;
  MorphOptions& mo = setup.mo;
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (int attempt = 1; attempt <= std::max(1, o.max_attempts); ++attempt) {
    // A sample outside a range is moved to a random point of it (not its nearest edge), so a
    // crowd covers the range instead of piling up at one bound.
    mo.range_aim = u01(rng);
    Eigen::VectorXd c(K);
    if (pool.size() >= 2) {
      const Eigen::VectorXd& mu = setup.mu;
      c = mu;
      const double s = o.spread / std::sqrt(pool.size() - 1.0);
      for (int i : pool) c += s * n01(rng) * (sm.pca.coefficients.row(i).transpose() - mu);
    } else {
      for (int k = 0; k < K; ++k) c(k) = o.spread * std::sqrt(std::max(sm.pca.eigenvalues(k), 0.0)) * n01(rng);
    }
    GeneratedBody g;
    g.attempts = attempt;
    // No start encoding: the morph makes its candidates from c (one pass over the basis each).
    g.V = morpher.morph_encoding(Eigen::VectorXd(), conditions, mo, &g.summary, &g.encoding, &c);
    if (o.repair_folds) {
      g.folds = repair_body_folds(model, g.V, o.fold_repair);
      if (g.folds.vertices_moved > 0) remeasure_labels(morpher, g.V, mo.sex, g.summary, conditions);
    }
    g.satisfied = true;
    double missed = 0;
    for (auto& l : g.summary.labels)
      if (!l.satisfied) {
        g.satisfied = false;
        missed += std::min(std::abs(l.achieved - l.lo), std::abs(l.achieved - l.hi));
      }
    if (g.satisfied || missed < best_missed) {
      best_missed = missed;
      best = std::move(g);
    }
    if (best.satisfied) break;
  }
  best.measured = o.measure_girths ? measure_morphed(morpher, best.V, mo.sex, conditions)
                                   : measure_height_and_weight(best.V, model.tmpl->faces());
  return best;
}

// The error names the targets that asked for the body, not only the measurement's complaint.
BodyMeasurements measure_morphed(const ShapeMorpher& morpher, const Eigen::MatrixX3d& V, Sex sex,
                                 const std::vector<LabelCondition>& conditions) {
  try {
    return morpher.measure(V, sex);
  } catch (const InputError& e) {
    throw InputError(fmt::format("morph: the targets {} ask for a body the model cannot make: the body it "
                                 "decodes for them cannot be measured ({}); relax one of them",
                                 targets_text(conditions), e.what()));
  }
}

BodyMeasurements measure_height_and_weight(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  BodyMeasurements b;
  b.height_cm = (V.col(1).maxCoeff() - V.col(1).minCoeff()) / 10.0;
  b.volume_l = signed_volume(V, F) * 1e-6;
  b.weight_kg = b.volume_l * MeasureOptions{}.density_kg_per_l;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  b.waist_cm = b.hips_cm = b.chest_cm = b.neck_cm = b.body_fat_pct = nan;
  return b;
}

namespace {

// The template moved onto V by the inverse of the rigid motion that fits V onto the template:
// normals of V against it are those of the fitted V against the template (same count).
Eigen::MatrixX3d template_on_body(const BodyModel& model, const Eigen::MatrixX3d& V) {
  const Eigen::MatrixX3d& R = model.tmpl->rest_vertices();
  const RigidMotion m = fit_rigid_motion(V, R);
  RigidMotion inv;
  inv.R = m.R.transpose();
  inv.t = -(m.R.transpose() * m.t);
  return apply(inv, R);
}

}  // namespace

int flipped_triangle_count(const BodyModel& model, const Eigen::MatrixX3d& V) {
  const Eigen::MatrixX3d& R = model.tmpl->rest_vertices();
  const Eigen::MatrixX3i& F = model.tmpl->faces();
  Eigen::MatrixX3d A = apply(fit_rigid_motion(V, R), V);
  Eigen::MatrixX3d n1 = face_normals(A, F), n0 = face_normals(R, F);
  int flipped = 0;
  for (int f = 0; f < F.rows(); ++f)
    if (n1.row(f).dot(n0.row(f)) < 0) ++flipped;
  return flipped;
}

FoldRepairOptions body_fold_repair_options() {
  FoldRepairOptions f;
  f.passes = 8;
  return f;
}

MorphedBody morph_body(const ShapeMorpher& morpher, const Eigen::MatrixX3d* V,
                       const std::vector<LabelCondition>& conditions, const MorphOptions& options,
                       const FoldRepairOptions& repair) {
  MorphedBody out;
  const BodyModel& model = morpher.model();
  out.V = V ? morpher.morph(*V, conditions, options, &out.summary)
            : morpher.morph_encoding(model.shape.pca.mean, conditions, options, &out.summary);
  out.folds = repair_body_folds(model, out.V, repair);
  return out;
}

std::string unmet_labels(const MorphSummary& summary) {
  std::string missed;
  for (const auto& l : summary.labels)
    if (!l.satisfied)
      missed += fmt::format("{}{} = {:.4g} (reached {:.4g})", missed.empty() ? "" : ", ", l.label, l.target, l.achieved);
  return missed;
}

FoldRepairSummary repair_body_folds(const BodyModel& model, Eigen::MatrixX3d& V, const FoldRepairOptions& options) {
  return repair_folds(V, template_on_body(model, V), model.tmpl->faces(), options);
}

double rms_vertex_distance(const Eigen::MatrixX3d& a, const Eigen::MatrixX3d& b) {
  Eigen::MatrixX3d bb = apply(fit_rigid_motion(b, a), b);
  return std::sqrt((a - bb).rowwise().squaredNorm().mean());
}

}  // namespace bodymodel
