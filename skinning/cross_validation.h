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
// Rule: `minimum` (the default) keeps the candidate with the smallest held-out mean; `one_se`
// keeps the most regularised candidate whose held-out mean is within one standard error of that
// smallest mean (Breiman et al. 1984, Hastie et al. "Elements of Statistical Learning" §7.10): when
// candidates differ by less than the noise of the estimate, the simpler model is the safer bet.
// Measured on the horse, Vlasic crane and jumping and SCAPE it is not (docs/skinning.md): with
// 6–40 held-out poses it pulls Animation Space towards the SSD prior, 2–7 % worse on unseen poses
// of the horse and crane, and does not make MWE generalise better than its base on SCAPE.
// Every candidate is measured on the same held-out examples, so the standard error is the paired
// one, of the per-example differences to the best candidate (sd/√n); the unpaired one
// (`one_se_unpaired`, sd of the best candidate's per-example errors / √n, the textbook form with
// examples in place of folds) includes how much harder one pose is than another, which says
// nothing about which candidate is better and lets the rule fall back to the strongest ridge.
// Nesting: `weights` (the default) refits the SSD base per fold but the held-out examples keep the
// bone maps they were given (from the bone fit over all training frames, which saw them); `full`
// refits the bones too — recovery and SSD alternation on the fold's training part only, the
// held-out examples' bone maps then fitted like unseen frames (weights held fixed) — through a
// FoldBoneFitter the caller supplies (sequence_evaluation.h), at about one more bones + SSD fit
// per fold. Measured in docs/skinning.md.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "core/progress.h"
#include "skinning/fit_lbs.h"
#include "skinning/skinning_error.h"
#include "skinning/skinning_model.h"

namespace bodymodel {

enum class CvScheme { none, interleaved, last };
enum class CvRule { minimum, one_se, one_se_unpaired };
std::string cv_rule_name(CvRule r);
CvRule parse_cv_rule(const std::string& s);   // "min", "one-se", "one-se-unpaired"; InputError otherwise
enum class CvNesting { weights, full };
std::string cv_nesting_name(CvNesting n);
CvNesting parse_cv_nesting(const std::string& s);   // "weights", "full"; InputError otherwise

struct SkinCrossValidationOptions {
  CvScheme scheme = CvScheme::interleaved;
  int folds = 5;      // interleaved: at most this many folds (fewer when there are fewer examples)
  int held_out = 0;   // last: examples held back, 0 = a third of them (10 of the 30 Vlasic frames)
  // Error per held-out vertex: distance to the held-out mesh's surface (the geometric deviation
  // the comparison reports) when surfaces are given, else ‖x − y‖; measured on every
  // vertex_stride-th vertex (the closest-point queries dominate the cost; 1 = every vertex).
  int vertex_stride = 4;
  CvRule rule = CvRule::minimum;   // one_se measured worse on AS (docs/skinning.md)
  CvNesting nesting = CvNesting::weights;
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
  // Regularisation strength, compared lexicographically (larger = more regularised, closer to the
  // method's base): AS {λ}; MWE {s, −refined influences}; PSD {RBF λ}; EigenSkin {−modes};
  // quadratic {ridge}. `structure` holds the choices that are not an amount of regularisation
  // (MWE: its base rig; PSD: the kernel width): the one-SE rules move only along the
  // regularisation of the structure the smallest mean has. (Ranking an SSD base as "more
  // regularised" than an AS one let the rule fall back to plain SSD on the horse and jumping.)
  std::vector<double> strength, structure;
  // Mean error of each held-out example (folds in order, each fold's examples in order; the same
  // order for every candidate), and the standard errors of `error` the rules use.
  std::vector<double> example_errors;
  double standard_error = 0;          // sd(example_errors) / √n
  double paired_standard_error = 0;   // sd(example_errors − the minimum's) / √n (0 for the minimum)
};

// The index of the candidate `rule` keeps (fills the standard errors from example_errors first):
// among the candidates of the minimum's structure within one SE of the minimum, the strongest.
// Candidates whose error is not finite are never kept. Throws InputError when none is finite.
size_t select_candidate(std::vector<CvCandidate>& candidates, CvRule rule);

struct CrossValidationResult {
  SkinningModel model = SkinningModel::ssd;
  ModelFitOptions chosen;
  std::string chosen_setting;
  double chosen_error = 0;
  CvRule rule = CvRule::minimum;
  std::string minimum_setting;   // the smallest held-out mean (= chosen under `minimum`)
  double minimum_error = 0;
  std::vector<CvCandidate> candidates;
  int folds = 0, held_out_examples = 0;
  double seconds = 0;
  std::string brief() const;   // one line: model, folds, chosen setting and its error
};

// Bones of one fold under full nesting, fitted on the fold's training part only.
struct FoldBones {
  SkinningExamples train;                  // the fold's training examples with their own bone maps
  SkinningRig lbs;                         // the SSD base fitted (and alternated) with them
  std::vector<BoneTransforms> held_out;    // bone maps of the held-out examples, in fold order
};
// train, held_out: indices into the cross-validated examples (disjoint).
using FoldBoneFitter = std::function<FoldBones(const std::vector<int>& train, const std::vector<int>& held_out)>;

// The folds of a scheme: for each fold, the held-out example indices (0..count−1).
// Throws InputError when the scheme leaves no example to fit on or none to hold out.
std::vector<std::vector<int>> cv_folds(int count, const SkinCrossValidationOptions& options);

class CrossValidator {
 public:
  // ex: the training examples (rest, transforms, poses). lbs: how the SSD base is fitted.
  // surfaces: one per example (the example mesh's surface) or empty; F their faces.
  // fold_bones: required when options.nesting is full (InputError otherwise), unused else.
  CrossValidator(const SkinningExamples& ex, const LbsFitOptions& lbs, const SkinCrossValidationOptions& options,
                 std::vector<const ReferenceSurface*> surfaces = {}, const FoldBoneFitter& fold_bones = {},
                 const ProgressCallback& progress = {});
  // Chooses the setting of `model` (starting from `start`, whose other fields are kept).
  // ssd and dqs have nothing to choose: the result holds `start`.
  CrossValidationResult select(SkinningModel model, const ModelFitOptions& start,
                               const ProgressCallback& progress = {}) const;
  int folds() const { return static_cast<int>(folds_.size()); }
  // What each fold fits on and poses its held-out examples with (exposed for tests).
  const SkinningExamples& fold_train(int f) const { return fold_train_[static_cast<size_t>(f)]; }
  const SkinningRig& fold_lbs(int f) const { return fold_lbs_[static_cast<size_t>(f)]; }
  const BoneTransforms& held_out_transforms(int fold, int k) const;   // k-th held-out example of the fold
  const std::vector<int>& held_out(int f) const { return folds_[static_cast<size_t>(f)]; }

 private:
  // Mean error over each held-out example's sampled vertices.
  std::vector<double> held_out_errors(const FittedModel& m, int fold) const;
  const SkinningExamples& ex_;
  SkinCrossValidationOptions options_;
  std::vector<const ReferenceSurface*> surfaces_;
  std::vector<std::vector<int>> folds_;
  std::vector<SkinningExamples> fold_train_;
  std::vector<SkinningRig> fold_lbs_;
  std::vector<std::vector<BoneTransforms>> fold_held_transforms_;   // full nesting only
};

}  // namespace bodymodel
