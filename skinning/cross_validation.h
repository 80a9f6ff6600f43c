// Regularisation chosen by cross-validation on the training examples only (issue 26; nested: the
// evaluated frames are never seen). The training examples are split into folds; for every fold
// the SSD base is refitted on the other examples (same options, so its influence sets too), each
// candidate setting of the model is fitted on them, and the held-out examples are posed with their
// bone maps and measured. The candidate with the smallest mean error over all held-out examples
// of all folds wins; the final model is then fitted on all training examples with it.
//
// Schemes: `interleaved` — fold f holds out the examples f, f + k, f + 2k, … (the training frames
// of a sequence evaluated on frames between them, or unordered poses); `last` — one fold holding
// out the last examples (a sequence evaluated on frames after its training frames: tune on the
// future of the training part, as the issue asks for Vlasic jumping).
// The held-out examples keep the bone maps they were given (from the bone fit over all training
// frames, weights held fixed, like unseen frames): a mild approximation of full nesting, which
// would refit the bones per fold.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/progress.h"
#include "skinning/fit_lbs.h"
#include "skinning/skinning_error.h"
#include "skinning/skinning_model.h"

namespace bodymodel {

enum class CvScheme { none, interleaved, last };

struct SkinCrossValidationOptions {
  CvScheme scheme = CvScheme::interleaved;
  int folds = 5;      // interleaved: at most this many folds (fewer when there are fewer examples)
  int held_out = 0;   // last: examples held back, 0 = a third of them (10 of the 30 Vlasic frames)
  // Error per held-out vertex: distance to the held-out mesh's surface (the geometric deviation
  // the comparison reports) when surfaces are given, else ‖x − y‖; measured on every
  // vertex_stride-th vertex (the closest-point queries dominate the cost; 1 = every vertex).
  int vertex_stride = 4;
  // Grids (the start value is used when a grid is empty). Each reaches far enough that its
  // largest value gives back the method's base (AS → the SSD prior, MWE → its underlying rig,
  // the RBFs → the mean correction): a choice at the edge of a grid would mean the grid is short.
  // Animation Space: ridge λ.
  std::vector<double> as_ridges = {0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1, 10};
  // MWE: ridge scale s (relative), underlying rig (delta space, §4.5), refined influences
  // (weight count; 0 = all), principal components (0 = all with variance).
  std::vector<double> mwe_scales = {1e-9, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1, 100};
  std::vector<MweBase> mwe_bases = {MweBase::lbs, MweBase::animation_space};
  std::vector<int> mwe_delta_influences = {2, 4};
  std::vector<int> mwe_components = {0};
  // PSD: kernel width and RBF ridge. EigenSkin and the quadratic method share PSD's pose space:
  // they keep the start's width and ridge (the evaluation sets them to PSD's choice first) and
  // choose only their own parameter: EigenSkin's modes, the quadratic fit's ridge.
  std::vector<double> kernel_widths = {0.5, 1, 2, 4};
  std::vector<double> rbf_ridges = {1e-2, 1e-1, 1, 10};
  std::vector<int> eigenskin_modes = {2, 4, 8, 16};
  std::vector<double> quadratic_ridges = {1e-3, 1e-2, 1e-1, 1, 10};
};

struct CvCandidate {
  std::string setting;   // e.g. "base as (λ 1e-4), s 1e-8, influences 2, components all"
  double error = 0;      // mean held-out error (data units)
  ModelFitOptions options;
};

struct CrossValidationResult {
  SkinningModel model = SkinningModel::ssd;
  ModelFitOptions chosen;
  std::string chosen_setting;
  double chosen_error = 0;
  std::vector<CvCandidate> candidates;
  int folds = 0, held_out_examples = 0;
  double seconds = 0;
  std::string brief() const;   // one line: model, folds, chosen setting and its error
};

// The folds of a scheme: for each fold, the held-out example indices (0..count−1).
// Throws InputError when the scheme leaves no example to fit on or none to hold out.
std::vector<std::vector<int>> cv_folds(int count, const SkinCrossValidationOptions& options);

class CrossValidator {
 public:
  // ex: the training examples (rest, transforms, poses). lbs: how the SSD base is fitted.
  // surfaces: one per example (the example mesh's surface) or empty; F their faces.
  CrossValidator(const SkinningExamples& ex, const LbsFitOptions& lbs, const SkinCrossValidationOptions& options,
                 std::vector<const ReferenceSurface*> surfaces = {});
  // Chooses the setting of `model` (starting from `start`, whose other fields are kept).
  // ssd and dqs have nothing to choose: the result holds `start`.
  CrossValidationResult select(SkinningModel model, const ModelFitOptions& start,
                               const ProgressCallback& progress = {}) const;
  int folds() const { return static_cast<int>(folds_.size()); }

 private:
  double held_out_error(const FittedModel& m, int fold) const;   // Σ over held-out vertices
  const SkinningExamples& ex_;
  SkinCrossValidationOptions options_;
  std::vector<const ReferenceSurface*> surfaces_;
  std::vector<std::vector<int>> folds_;
  std::vector<SkinningExamples> fold_train_;
  std::vector<SkinningRig> fold_lbs_;
  long long held_out_vertices_ = 0;
};

}  // namespace bodymodel
