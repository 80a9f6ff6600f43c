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
    << held_out_examples << " held-out examples), chosen " << chosen_setting << " (held-out mean " << chosen_error
    << "); " << seconds << " s";
  return s.str();
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
                               std::vector<const ReferenceSurface*> surfaces)
    : ex_(ex), options_(o), surfaces_(std::move(surfaces)) {
  if (!surfaces_.empty() && static_cast<int>(surfaces_.size()) != ex.pose_count())
    throw InputError("cross-validation: " + std::to_string(surfaces_.size()) + " surfaces for " +
                     std::to_string(ex.pose_count()) + " examples");
  folds_ = cv_folds(ex.pose_count(), o);
  for (const auto& held : folds_) {
    std::vector<bool> out(static_cast<size_t>(ex.pose_count()), false);
    for (int p : held) out[static_cast<size_t>(p)] = true;
    SkinningExamples sub;
    sub.rest = ex.rest;
    for (int p = 0; p < ex.pose_count(); ++p)
      if (!out[static_cast<size_t>(p)]) {
        sub.poses.push_back(ex.poses[static_cast<size_t>(p)]);
        sub.transforms.push_back(ex.transforms[static_cast<size_t>(p)]);
      }
    fold_lbs_.push_back(fit_lbs(sub, {}, lbs));
    fold_train_.push_back(std::move(sub));
    const int stride = std::max(1, o.vertex_stride);
    held_out_vertices_ += static_cast<long long>(held.size()) * ((ex.vertex_count() + stride - 1) / stride);
  }
}

double CrossValidator::held_out_error(const FittedModel& m, int fold) const {
  double sum = 0;
  const Eigen::Index stride = std::max(1, options_.vertex_stride), n = ex_.vertex_count();
  const Eigen::Index count = (n + stride - 1) / stride;
  for (int p : folds_[static_cast<size_t>(fold)]) {
    const Eigen::MatrixX3d X = m.pose(ex_.transforms[static_cast<size_t>(p)]);
    if (!X.allFinite()) return std::numeric_limits<double>::infinity();
    Eigen::MatrixX3d Xs(count, 3), Ys(count, 3);
    for (Eigen::Index r = 0; r < count; ++r) {
      Xs.row(r) = X.row(r * stride);
      Ys.row(r) = ex_.poses[static_cast<size_t>(p)].row(r * stride);
    }
    if (!surfaces_.empty())
      sum += surfaces_[static_cast<size_t>(p)]->distances(Xs).sum();
    else
      sum += (Xs - Ys).rowwise().norm().sum();
  }
  return sum;
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
  auto add = [&](const std::string& s, const ModelFitOptions& o) { cands.push_back({s, 0.0, o}); };
  const SkinCrossValidationOptions& c = options_;
  switch (model) {
    case SkinningModel::as:
      for (double l : or_first(c.as_ridges, start.animation_space.ridge)) {
        ModelFitOptions o = start;
        o.animation_space.ridge = l;
        add("λ " + g(l), o);
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
                      ", components " + (comp ? std::to_string(comp) : std::string("all")), o);
            }
          }
      break;
    case SkinningModel::psd:
      for (double w : or_first(c.kernel_widths, start.pose_space.kernel_width))
        for (double l : or_first(c.rbf_ridges, start.pose_space.rbf_ridge)) {
          ModelFitOptions o = start;
          o.pose_space.kernel_width = w;
          o.pose_space.rbf_ridge = l;
          add("width " + g(w) + ", RBF λ " + g(l), o);
        }
      break;
    case SkinningModel::eigenskin:
      for (int m : or_first(c.eigenskin_modes, start.pose_space.eigenskin_modes)) {
        ModelFitOptions o = start;
        o.pose_space.eigenskin_modes = m;
        add("modes " + std::to_string(m) + " (width " + g(start.pose_space.kernel_width) + ", RBF λ " +
                g(start.pose_space.rbf_ridge) + ")",
            o);
      }
      break;
    case SkinningModel::quadratic:
      for (double q : or_first(c.quadratic_ridges, start.pose_space.quadratic_ridge)) {
        ModelFitOptions o = start;
        o.pose_space.quadratic_ridge = q;
        add("quadratic ridge " + g(q) + " (width " + g(start.pose_space.kernel_width) + ", RBF λ " +
                g(start.pose_space.rbf_ridge) + ")",
            o);
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
        for (size_t j = 0; j < path.size(); ++j) cands[k + j].error += held_out_error(path[j], static_cast<int>(f));
        k = e;
      }
    } else {
      for (size_t k = 0; k < cands.size(); ++k) {
        report_progress(progress, (f + double(k) / cands.size()) / F,
                        "cross-validating " + skinning_model_name(model) + " (fold " + std::to_string(f + 1) + ")");
        const FittedModel m = fit_model(model, fold_train_[f], fold_lbs_[f], cands[k].options);
        cands[k].error += held_out_error(m, static_cast<int>(f));
      }
    }
  }
  size_t best = 0;
  for (size_t k = 0; k < cands.size(); ++k) {
    cands[k].error /= double(std::max<long long>(held_out_vertices_, 1));
    if (cands[k].error < cands[best].error) best = k;
  }
  r.chosen = cands[best].options;
  r.chosen_setting = cands[best].setting;
  r.chosen_error = cands[best].error;
  r.candidates = std::move(cands);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  report_progress(progress, 1.0, "cross-validated " + skinning_model_name(model));
  return r;
}

}  // namespace bodymodel
