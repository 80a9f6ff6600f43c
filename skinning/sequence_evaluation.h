// Jacka et al. 2007's protocol on a mesh sequence (docs/evaluation.md#skinning-protocol): recover
// bones from the training frames when no transforms are given, fit SSD, Animation Space and MWE to
// the training frames, fit every unseen frame's bone transforms with the SSD weights held fixed,
// pose every frame with each rig and measure it against the frame (train and unseen separately).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/progress.h"
#include "skinning/bone_recovery.h"
#include "skinning/fit_animation_space.h"
#include "skinning/fit_lbs.h"
#include "skinning/fit_mwe.h"
#include "skinning/skinning_error.h"

namespace bodymodel {

struct SequenceEvaluationOptions {
  std::vector<SkinningMethod> methods = {SkinningMethod::lbs, SkinningMethod::animation_space,
                                         SkinningMethod::mwe};
  int rest_frame = 0;             // index of the frame used as the rest pose
  BoneRecoveryOptions recovery;   // used when no transforms are given
  int max_influences = 4;         // influence slots per vertex (chosen automatically)
  // Rounds of (bone transforms with SSD weights fixed, SSD weights refit) on the training frames
  // after recovery (SSDR-style alternation); 0 = keep the recovered section transforms.
  int alternations = 2;
  int transform_iterations = 5;   // fixed-weight transform fit iterations per frame
  LbsFitOptions lbs;
  AnimationSpaceFitOptions animation_space;
  MweFitOptions mwe;
};

struct MethodSplitStats {
  SkinningMethod method;
  std::string split;              // "train" or "unseen"
  DeviationStats stats;
};

struct SequenceEvaluation {
  std::vector<MethodSplitStats> rows;                // one per method and non-empty split
  std::vector<Eigen::VectorXd> mean_unseen_geometric; // per method: #V mean over unseen frames
  std::vector<std::vector<double>> frame_mean_geometric;  // per method, per frame
  std::vector<int> train_frames;
  double diagonal = 0;            // bbox diagonal of the first frame (E_RMS, % of diagonal)
  BoneRecoverySummary recovery;
  LbsFitSummary lbs_summary;
  AnimationSpaceFitSummary as_summary;
  MweFitSummary mwe_summary;
  double seconds = 0;
};

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
};
PreparedSequence prepare_skinning_sequence(const std::vector<Eigen::MatrixX3d>& frames,
                                           const Eigen::MatrixX3i& F, const std::vector<int>& train,
                                           const SequenceEvaluationOptions& options,
                                           const std::vector<BoneTransforms>& transforms = {},
                                           const ProgressCallback& progress = {});

// Train and unseen statistics of one rig over every frame. `surfaces` (one per frame) may be
// given to reuse the closest-point trees; otherwise they are built here.
struct RigFrameStats {
  DeviationStats train, unseen;
  std::vector<double> frame_mean_geometric;   // per frame
  Eigen::VectorXd mean_unseen_geometric;      // #V
};
RigFrameStats evaluate_rig_on_frames(const SkinningRig& rig, const PreparedSequence& prepared,
                                     const std::vector<Eigen::MatrixX3d>& frames, const Eigen::MatrixX3i& F,
                                     const std::vector<const ReferenceSurface*>& surfaces = {});

// Evenly spaced training frames (Jacka §3.1): round(i·(n−1)/(k−1)) for i < k, or every `every`-th.
std::vector<int> evenly_spaced_frames(int frame_count, int count);

}  // namespace bodymodel
