#include "skinning/cross_validation.h"

#include <chrono>
#include <cmath>
#include <limits>

#include <sstream>

#include "core/error.h"

namespace bodymodel {

std::string CrossValidationResult::brief() const {
  if (candidates.empty()) return skinning_model_name(model) + ": nothing to cross-validate";
  std::ostringstream s;
  s << skinning_model_name(model) << ": " << candidates.size() << " setting(s) over " << folds << " fold(s) ("
    << held_out_examples << " held-out examples), " << cv_rule_name(rule) << " chose " << chosen_setting
    << " (held-out mean " << chosen_error << ")";
  if (chosen_setting != minimum_setting) s << ", smallest " << minimum_setting << " (" << minimum_error << ")";
  s << "; " << seconds << " s";
  return s.str();
}

std::string cv_rule_name(CvRule r) {
  return r == CvRule::minimum ? "min" : r == CvRule::one_se ? "one-se" : "one-se-unpaired";
}

CvRule parse_cv_rule(const std::string& s) {
  if (s == "min") return CvRule::minimum;
  if (s == "one-se") return CvRule::one_se;
  if (s == "one-se-unpaired") return CvRule::one_se_unpaired;
  throw InputError("--cv-rule: expected min, one-se or one-se-unpaired, found '" + s + "'");
}

std::string cv_nesting_name(CvNesting n) { return n == CvNesting::weights ? "weights" : "full"; }

CvNesting parse_cv_nesting(const std::string& s) {
  if (s == "weights") return CvNesting::weights;
  if (s == "full") return CvNesting::full;
  throw InputError("--cv-nesting: expected full or weights, found '" + s + "'");
}

namespace {
// Sample standard deviation / √n of v (0 for fewer than two values or a non-finite one).
double standard_error_of_mean(const std::vector<double>& v) {
  const size_t n = v.size();
  if (n < 2) return 0;
  double mean = 0;
  for (double x : v) mean += x;
  mean /= double(n);
  double ss = 0;
  for (double x : v) ss += (x - mean) * (x - mean);
  const double se = std::sqrt(ss / double(n - 1) / double(n));
  return std::isfinite(se) ? se : 0;
}
}  // namespace

size_t select_candidate(std::vector<CvCandidate>& c, CvRule rule) {
  size_t best = c.size();
  for (size_t k = 0; k < c.size(); ++k)
    if (std::isfinite(c[k].error) && (best == c.size() || c[k].error < c[best].error)) best = k;
  if (best == c.size()) throw InputError("cross-validation: no candidate setting gave a finite held-out error");
  for (auto& k : c) {
    k.standard_error = standard_error_of_mean(k.example_errors);
    std::vector<double> d(k.example_errors.size());
    const bool paired = k.example_errors.size() == c[best].example_errors.size();
    for (size_t i = 0; paired && i < d.size(); ++i) d[i] = k.example_errors[i] - c[best].example_errors[i];
    k.paired_standard_error = paired ? standard_error_of_mean(d) : 0;
  }
  if (rule == CvRule::minimum) return best;
  size_t chosen = best;
  for (size_t k = 0; k < c.size(); ++k) {
    if (!std::isfinite(c[k].error)) continue;
    const double se = rule == CvRule::one_se ? c[k].paired_standard_error : c[best].standard_error;
    if (c[k].structure == c[best].structure && c[k].error <= c[best].error + se && c[chosen].strength < c[k].strength)
      chosen = k;
  }
  return chosen;
}

std::vector<std::vector<int>> cv_folds(int count, const SkinCrossValidationOptions& o) {
  std::vector<std::vector<int>> folds;
  if (o.scheme == CvScheme::none) return folds;
  if (count < 2)
    throw InputError("cross-validation needs at least 2 training examples, found " + std::to_string(count));
  if (o.scheme == CvScheme::interleaved) {
    if (o.folds < 2) throw InputError("cross-validation: at least 2 folds, found " + std::to_string(o.folds));
    const int k = std::min(o.folds, count);
    folds.assign(static_cast<size_t>(k), {});
    for (int p = 0; p < count; ++p) folds[static_cast<size_t>(p % k)].push_back(p);
  } else {
    const int h = o.held_out > 0 ? o.held_out : std::max(1, static_cast<int>(std::lround(count / 3.0)));
    if (h >= count)
      throw InputError("cross-validation: holding back the last " + std::to_string(h) + " of " + std::to_string(count) +
                       " training examples leaves none to fit on");
    folds.push_back({});
    for (int p = count - h; p < count; ++p) folds[0].push_back(p);
  }
  return folds;
}

CrossValidator::CrossValidator(const SkinningExamples& ex, const LbsFitOptions& lbs, const SkinCrossValidationOptions& o,
                               std::vector<const ReferenceSurface*> surfaces, const FoldBoneFitter& fold_bones,
                               const ProgressCallback& progress)
    : ex_(ex), options_(o), surfaces_(std::move(surfaces)) {
  if (!surfaces_.empty() && static_cast<int>(surfaces_.size()) != ex.pose_count())
    throw InputError("cross-validation: " + std::to_string(surfaces_.size()) + " surfaces for " +
                     std::to_string(ex.pose_count()) + " examples");
  if (o.nesting == CvNesting::full && !fold_bones)
    throw InputError("cross-validation: full nesting needs the bones refitted per fold, and no bone fit was given");
  folds_ = cv_folds(ex.pose_count(), o);
  for (size_t f = 0; f < folds_.size(); ++f) {
    const auto& held = folds_[f];
    report_progress(progress, double(f) / folds_.size(),
                    o.nesting == CvNesting::full ? "bones of cross-validation fold " + std::to_string(f + 1)
                                                 : "SSD of cross-validation fold " + std::to_string(f + 1));
    std::vector<bool> out(static_cast<size_t>(ex.pose_count()), false);
    for (int p : held) out[static_cast<size_t>(p)] = true;
    std::vector<int> train;
    for (int p = 0; p < ex.pose_count(); ++p)
      if (!out[static_cast<size_t>(p)]) train.push_back(p);
    if (o.nesting == CvNesting::full) {
      FoldBones b = fold_bones(train, held);
      if (b.train.pose_count() != static_cast<int>(train.size()) || b.held_out.size() != held.size())
        throw InputError("cross-validation: the fold's bone fit returned " + std::to_string(b.train.pose_count()) +
                         " training and " + std::to_string(b.held_out.size()) + " held-out bone sets for " +
                         std::to_string(train.size()) + " and " + std::to_string(held.size()));
      fold_train_.push_back(std::move(b.train));
      fold_lbs_.push_back(std::move(b.lbs));
      fold_held_transforms_.push_back(std::move(b.held_out));
      continue;
    }
    SkinningExamples sub;
    sub.rest = ex.rest;
    for (int p : train) {
      sub.poses.push_back(ex.poses[static_cast<size_t>(p)]);
      sub.transforms.push_back(ex.transforms[static_cast<size_t>(p)]);
    }
    fold_lbs_.push_back(fit_lbs(sub, {}, lbs));
    fold_train_.push_back(std::move(sub));
  }
  report_progress(progress, 1.0, "cross-validation folds ready");
}

const BoneTransforms& CrossValidator::held_out_transforms(int fold, int k) const {
  if (!fold_held_transforms_.empty()) return fold_held_transforms_[static_cast<size_t>(fold)][static_cast<size_t>(k)];
  return ex_.transforms[static_cast<size_t>(folds_[static_cast<size_t>(fold)][static_cast<size_t>(k)])];
}

std::vector<double> CrossValidator::held_out_errors(const FittedModel& m, int fold) const {
  std::vector<double> out;
  const Eigen::Index stride = std::max(1, options_.vertex_stride), n = ex_.vertex_count();
  const Eigen::Index count = (n + stride - 1) / stride;
  const std::vector<int>& held = folds_[static_cast<size_t>(fold)];
  for (size_t k = 0; k < held.size(); ++k) {
    const int p = held[k];
    const Eigen::MatrixX3d X = m.pose(held_out_transforms(fold, static_cast<int>(k)));
    if (!X.allFinite()) {
      out.push_back(std::numeric_limits<double>::infinity());
      continue;
    }
    Eigen::MatrixX3d Xs(count, 3), Ys(count, 3);
    for (Eigen::Index r = 0; r < count; ++r) {
      Xs.row(r) = X.row(r * stride);
      Ys.row(r) = ex_.poses[static_cast<size_t>(p)].row(r * stride);
    }
    const double sum = !surfaces_.empty() ? surfaces_[static_cast<size_t>(p)]->distances(Xs).sum()
                                          : (Xs - Ys).rowwise().norm().sum();
    out.push_back(sum / double(count));
  }
  return out;
}

namespace {
std::string g(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}
template <typename T>
std::vector<T> or_first(const std::vector<T>& v, T fallback) {
  return v.empty() ? std::vector<T>{fallback} : v;
}
}  // namespace

CrossValidationResult CrossValidator::select(SkinningModel model, const ModelFitOptions& start,
                                             const ProgressCallback& progress) const {
  const auto t0 = std::chrono::steady_clock::now();
  CrossValidationResult r;
  r.model = model;
  r.chosen = start;
  r.folds = static_cast<int>(folds_.size());
  r.held_out_examples = 0;
  for (const auto& f : folds_) r.held_out_examples += static_cast<int>(f.size());
  if (folds_.empty() || model == SkinningModel::ssd || model == SkinningModel::dqs) return r;
  for (const auto& t : fold_train_)
    if (t.pose_count() < minimum_examples(model))
      throw InputError("cross-validation of " + skinning_model_name(model) + ": a fold leaves " +
                       std::to_string(t.pose_count()) + " training example(s), the method needs " +
                       std::to_string(minimum_examples(model)) + " (use fewer folds or more training frames)");
  // Candidate settings (MWE: everything but the ridge scale, which is solved as a path).
  std::vector<CvCandidate> cands;
  std::vector<std::vector<double>> paths;   // MWE: the scales of each candidate group
  auto add = [&](const std::string& s, const ModelFitOptions& o, std::vector<double> strength,
                 std::vector<double> structure = {}) {
    CvCandidate c;
    c.setting = s;
    c.options = o;
    c.strength = std::move(strength);
    c.structure = std::move(structure);
    cands.push_back(std::move(c));
  };
  const SkinCrossValidationOptions& c = options_;
  switch (model) {
    case SkinningModel::as:
      for (double l : or_first(c.as_ridges, start.animation_space.ridge)) {
        ModelFitOptions o = start;
        o.animation_space.ridge = l;
        add("λ " + g(l), o, {l});
      }
      break;
    case SkinningModel::mwe:
      for (MweBase b : or_first(c.mwe_bases, start.mwe.base))
        for (int d : or_first(c.mwe_delta_influences, start.mwe.delta_influences))
          for (int comp : or_first(c.mwe_components, start.mwe.components)) {
            ModelFitOptions o = start;
            o.mwe.base = b;
            o.mwe.delta_influences = d;
            o.mwe.components = comp;
            const std::string base = b == MweBase::lbs ? "ssd" : b == MweBase::animation_space
                                         ? "as (λ " + g(start.mwe.base_as_ridge) + ")" : b == MweBase::rigid ? "rigid" : "none";
            for (double s : or_first(c.mwe_scales, start.mwe.ridge_scale)) {
              o.mwe.ridge_scale = s;
              add("base " + base + ", s " + g(s) + ", influences " + (d ? std::to_string(d) : std::string("all")) +
                      ", components " + (comp ? std::to_string(comp) : std::string("all")),
                  o, {s, d ? -double(d) : -1e9}, {double(static_cast<int>(b)), double(comp)});
            }
          }
      break;
    case SkinningModel::psd:
      for (double w : or_first(c.kernel_widths, start.pose_space.kernel_width))
        for (double l : or_first(c.rbf_ridges, start.pose_space.rbf_ridge)) {
          ModelFitOptions o = start;
          o.pose_space.kernel_width = w;
          o.pose_space.rbf_ridge = l;
          add("width " + g(w) + ", RBF λ " + g(l), o, {l}, {w});
        }
      break;
    case SkinningModel::eigenskin:
      for (int m : or_first(c.eigenskin_modes, start.pose_space.eigenskin_modes)) {
        ModelFitOptions o = start;
        o.pose_space.eigenskin_modes = m;
        add("modes " + std::to_string(m) + " (width " + g(start.pose_space.kernel_width) + ", RBF λ " +
                g(start.pose_space.rbf_ridge) + ")",
            o, {-double(m)});
      }
      break;
    case SkinningModel::quadratic:
      for (double q : or_first(c.quadratic_ridges, start.pose_space.quadratic_ridge)) {
        ModelFitOptions o = start;
        o.pose_space.quadratic_ridge = q;
        add("quadratic ridge " + g(q) + " (width " + g(start.pose_space.kernel_width) + ", RBF λ " +
                g(start.pose_space.rbf_ridge) + ")",
            o, {q});
      }
      break;
    default: break;
  }
  const size_t F = folds_.size();
  for (size_t f = 0; f < F; ++f) {
    if (model == SkinningModel::mwe) {
      // Candidates come in runs sharing everything but s: one path fit per run.
      size_t k = 0;
      while (k < cands.size()) {
        size_t e = k;
        std::vector<double> scales;
        while (e < cands.size() && cands[e].options.mwe.base == cands[k].options.mwe.base &&
               cands[e].options.mwe.delta_influences == cands[k].options.mwe.delta_influences &&
               cands[e].options.mwe.components == cands[k].options.mwe.components)
          scales.push_back(cands[e++].options.mwe.ridge_scale);
        report_progress(progress, (f + double(k) / cands.size()) / F,
                        "cross-validating mwe (fold " + std::to_string(f + 1) + ")");
        const std::vector<FittedModel> path =
            fit_mwe_models(fold_train_[f], fold_lbs_[f], cands[k].options.mwe, scales);
        for (size_t j = 0; j < path.size(); ++j) {
          const std::vector<double> e = held_out_errors(path[j], static_cast<int>(f));
          cands[k + j].example_errors.insert(cands[k + j].example_errors.end(), e.begin(), e.end());
        }
        k = e;
      }
    } else {
      for (size_t k = 0; k < cands.size(); ++k) {
        report_progress(progress, (f + double(k) / cands.size()) / F,
                        "cross-validating " + skinning_model_name(model) + " (fold " + std::to_string(f + 1) + ")");
        const FittedModel m = fit_model(model, fold_train_[f], fold_lbs_[f], cands[k].options);
        const std::vector<double> e = held_out_errors(m, static_cast<int>(f));
        cands[k].example_errors.insert(cands[k].example_errors.end(), e.begin(), e.end());
      }
    }
  }
  // Every held-out example has the same number of sampled vertices: the mean over all held-out
  // vertices is the mean of the examples' means.
  for (auto& k : cands) {
    k.error = 0;
    for (double e : k.example_errors) k.error += e;
    k.error /= double(std::max<size_t>(k.example_errors.size(), 1));
  }
  const size_t minimum = select_candidate(cands, CvRule::minimum);
  const size_t best = select_candidate(cands, options_.rule);
  r.rule = options_.rule;
  r.minimum_setting = cands[minimum].setting;
  r.minimum_error = cands[minimum].error;
  r.chosen = cands[best].options;
  r.chosen_setting = cands[best].setting;
  r.chosen_error = cands[best].error;
  r.candidates = std::move(cands);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  report_progress(progress, 1.0, "cross-validated " + skinning_model_name(model));
  return r;
}

}  // namespace bodymodel
