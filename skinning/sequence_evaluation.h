// Jacka et al. 2007's protocol on a mesh sequence (docs/skinning.md): recover bones from
// the training frames when no transforms are given, fit every method (skinning_model.h: SSD, DQS,
// Animation Space, MWE, PSD, EigenSkin, quadratic) to the training frames — the regularisation of
// AS, MWE and the pose-space methods chosen by cross-validation on the training frames only
// (cross_validation.h) — fit every unseen frame's bone transforms with the SSD weights held fixed,
// pose every frame with each rig and measure it against the frame (train and unseen separately).
// The frames need no order (SCAPE's poses): only the split into training and unseen frames counts.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "core/progress.h"
#include "skinning/bone_recovery.h"
#include "skinning/cross_validation.h"
#include "skinning/fit_lbs.h"
#include "skinning/skinning_error.h"
#include "skinning/skinning_model.h"

namespace bodymodel {

struct SequenceEvaluationOptions {
  std::vector<SkinningModel> methods = {SkinningModel::ssd, SkinningModel::as, SkinningModel::mwe};
  // Index of the frame used as the rest pose. When bones are recovered it must be a training
  // frame (its geometry is the rig's rest shape).
  int rest_frame = 0;
  BoneRecoveryOptions recovery;   // used when no transforms are given
  // Influence slots per vertex (chosen automatically among lbs.influence_candidates bones).
  // Issue 26, SSD unseen E_RMS with 24 bones, 4 → 8 slots and 2 → 10 alternation rounds (16
  // candidates, 10 transform passes): horse 0.959 → 0.740, Vlasic crane 2.11 → 1.64, jumping
  // (first 60 %) 3.21 → 2.84; 8 is also Dem Bones' default (nnz).
  int max_influences = 8;
  // Rounds of (bone transforms with SSD weights fixed, SSD weights refit) on the training frames
  // after recovery (SSDR-style alternation, Kavan & Le 2012); 0 = keep the recovered section
  // transforms.
  int alternations = 10;
  // Stop alternating early once a round lowers the training residual RMS by less than this
  // fraction (0 = always run every round).
  double alternation_tolerance = 0;
  int transform_iterations = 10;  // fixed-weight transform fit passes (every bone once) per frame
  // The same, inside each alternation round (warm-started from the previous round's maps);
  // 0 = transform_iterations. Fewer passes cut the alternation's CPU at a small cost in unseen
  // SSD error, but moved the cross-validated Animation Space ridge on the horse: not the default
  // (measured in docs/skinning.md#speed).
  int alternation_transform_iterations = 0;
  // The fixed-weight transform fits summed over the vertices in every pass (before issue 26's weight
  // moments; equal up to rounding): the benchmark's baseline, with lbs.pairwise_moments false.
  bool baseline_fit = false;
  LbsFitOptions lbs = [] {
    LbsFitOptions o;
    o.influence_candidates = 16;   // horse: 12 → 16 candidates, unseen SSD E_RMS 0.79 → 0.74
    return o;
  }();
  ModelFitOptions fit;            // every method's settings (the start point of cross-validation)
  // Called with every posed frame of every method (e.g. to write them for an outside check of
  // the errors); may be empty.
  std::function<void(SkinningModel, int frame, const Eigen::MatrixX3d& posed)> on_posed;
  // Per-frame triangles, for sets whose vertices correspond but whose triangulation differs from
  // frame to frame (SCAPE's registrations flip about 6 000 of their 25 000 triangles): frame f's
  // surface and normals use frame_faces[f], bone recovery the rest frame's. Empty = every frame
  // uses the faces passed with the frames.
  std::vector<Eigen::MatrixX3i> frame_faces;
  SkinCrossValidationOptions cv;      // scheme none = use `fit` as given
};

struct MethodSplitStats {
  SkinningModel method;
  std::string split;              // "train" or "unseen"
  DeviationStats stats;
};

// What fitting one method cost and chose.
struct MethodFit {
  SkinningModel method;
  std::string brief;              // the fit summary
  CrossValidationResult cv;       // empty candidates when nothing was cross-validated
  double seconds = 0, cpu_seconds = 0;   // fit including its cross-validation (CPU: all threads)
};

struct SequenceEvaluation {
  std::vector<MethodSplitStats> rows;                // one per method and non-empty split
  std::vector<MethodFit> fits;                       // per method
  std::vector<Eigen::VectorXd> mean_unseen_geometric; // per method: #V mean over unseen frames
  std::vector<std::vector<double>> frame_mean_geometric;  // per method, per frame
  std::vector<int> train_frames;
  double diagonal = 0;            // bbox diagonal of the first frame (E_RMS, % of diagonal)
  BoneRecoverySummary recovery;
  LbsFitSummary lbs_summary;
  std::vector<double> alternation_rms;   // training residual RMS after the first SSD fit and each round
  double prepare_seconds = 0, prepare_cpu_seconds = 0;   // bones + SSD (+ alternation)
  double recovery_cpu_seconds = 0, unseen_cpu_seconds = 0;
  double cv_setup_cpu_seconds = 0;   // the folds' SSD bases (and bones, under full nesting)
  double seconds = 0;
};

// Checks, before any work, that every method can be fitted: enough training frames for each
// (minimum_examples) and for each cross-validation fold, training indices in range, a rest frame
// among them when bones are recovered. Throws InputError naming the method or frame.
void check_evaluation_request(int frame_count, const std::vector<int>& train, const SequenceEvaluationOptions& options,
                              bool bones_recovered = true);

// frames: #frames meshes (#V by 3, same order) sharing faces F; train: indices of training frames.
// transforms: per-frame bone transforms, or empty to recover them (options.recovery.bones).
SequenceEvaluation evaluate_skinning_sequence(const std::vector<Eigen::MatrixX3d>& frames,
                                              const Eigen::MatrixX3i& F, const std::vector<int>& train,
                                              const SequenceEvaluationOptions& options,
                                              const std::vector<BoneTransforms>& transforms = {},
                                              const ProgressCallback& progress = {});

// The fitted base of the protocol, reusable across rigs (parameter sweeps): training examples
// with their bone transforms, the SSD rig, and the bone transforms of every frame.
struct PreparedSequence {
  SkinningExamples examples;                // training frames only
  SkinningRig lbs;
  std::vector<BoneTransforms> transforms;   // every frame
  std::vector<bool> is_train;               // every frame
  RecoveredBones recovered;                 // empty when transforms were given
  BoneRecoverySummary recovery;
  LbsFitSummary lbs_summary;
  std::vector<double> alternation_rms;      // training residual RMS after the first SSD fit and each round
  double seconds = 0, cpu_seconds = 0;      // bones, SSD and alternation of the training frames
  double recovery_cpu_seconds = 0;          // of which the bone recovery
  double unseen_seconds = 0, unseen_cpu_seconds = 0;   // bone maps of the unseen frames
};
PreparedSequence prepare_skinning_sequence(const std::vector<Eigen::MatrixX3d>& frames,
                                           const Eigen::MatrixX3i& F, const std::vector<int>& train,
                                           const SequenceEvaluationOptions& options,
                                           const std::vector<BoneTransforms>& transforms = {},
                                           const ProgressCallback& progress = {});

// Full nesting's bones of one cross-validation fold (CvNesting::full): bone recovery, SSD and its
// alternation on the examples `train` of ex only (rest shape ex.rest, its faces Frest), then the
// held-out examples' bone maps fitted with those SSD weights held fixed, as unseen frames are.
// ex.transforms are not used. Throws InputError when the index sets overlap or leave the range.
FoldBones fit_fold_bones(const SkinningExamples& ex, const Eigen::MatrixX3i& Frest, const std::vector<int>& train,
                         const std::vector<int>& held_out, const SequenceEvaluationOptions& options);

// Train and unseen statistics of one rig over every frame. `surfaces` (one per frame) may be
// given to reuse the closest-point trees; otherwise they are built here.
struct RigFrameStats {
  DeviationStats train, unseen;
  std::vector<double> frame_mean_geometric;   // per frame
  Eigen::VectorXd mean_unseen_geometric;      // #V
};
// frame_faces: per-frame triangles (see SequenceEvaluationOptions) or empty.
RigFrameStats evaluate_rig_on_frames(const SkinningRig& rig, const PreparedSequence& prepared,
                                     const std::vector<Eigen::MatrixX3d>& frames, const Eigen::MatrixX3i& F,
                                     const std::vector<const ReferenceSurface*>& surfaces = {},
                                     const std::vector<Eigen::MatrixX3i>& frame_faces = {});
RigFrameStats evaluate_model_on_frames(const FittedModel& model, const PreparedSequence& prepared,
                                       const std::vector<Eigen::MatrixX3d>& frames, const Eigen::MatrixX3i& F,
                                       const std::vector<const ReferenceSurface*>& surfaces = {},
                                       const std::vector<Eigen::MatrixX3i>& frame_faces = {},
                                       const std::function<void(int, const Eigen::MatrixX3d&)>& on_posed = {});

// Fits one method on the prepared training examples: cross-validation (when options.cv.scheme is
// not none; `validator` may be shared between methods) then the final fit with the chosen setting.
FittedModel fit_sequence_method(SkinningModel method, const PreparedSequence& prepared,
                                const SequenceEvaluationOptions& options, const CrossValidator* validator,
                                MethodFit* fit = nullptr, const ProgressCallback& progress = {});

// CPU seconds of the whole process (all threads).
double process_cpu_seconds();

// Evenly spaced training frames (Jacka §3.1): round(i·(n−1)/(k−1)) for i < k, or every `every`-th.
std::vector<int> evenly_spaced_frames(int frame_count, int count);

}  // namespace bodymodel
