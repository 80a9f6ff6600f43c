// Every skinning method of the comparison (issue 26) behind one interface: fit on examples over a
// fitted SSD rig, then pose with bone maps.
//   ssd        linear blend skinning (fit_lbs.h)          dqs  the SSD weights, dual-quaternion blend
//   as         Animation Space (fit_animation_space.h)    mwe  Multi-Weight Enveloping (fit_mwe.h)
//   psd, eigenskin, quadratic                              pose-space corrections (pose_space.h)
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/progress.h"
#include "skinning/fit_animation_space.h"
#include "skinning/fit_mwe.h"
#include "skinning/pose_space.h"
#include "skinning/skinning_examples.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

enum class SkinningModel { ssd, dqs, as, mwe, psd, eigenskin, quadratic };

// "ssd" (or "lbs"), "dqs", "as", "mwe", "psd", "eigenskin", "quadratic"; InputError otherwise.
SkinningModel parse_skinning_model(const std::string& name);
std::string skinning_model_name(SkinningModel m);
// All seven, in the order above.
std::vector<SkinningModel> all_skinning_models();
// Fewest training examples a model can be fitted to (SSD and DQS 1, AS and MWE 2, the
// pose-space methods 2: they interpolate between examples).
int minimum_examples(SkinningModel m);

// Options of every model (each model reads its own part).
struct ModelFitOptions {
  AnimationSpaceFitOptions animation_space;
  MweFitOptions mwe;
  PoseSpaceOptions pose_space;   // .method is set from the model
};

// One fitted model: a per-slot rig (ssd, dqs, as, mwe) or a pose-space rig.
struct FittedModel {
  SkinningModel model = SkinningModel::ssd;
  SkinningRig rig;
  PoseSpaceRig pose_space;
  bool is_pose_space() const;
  // Posed positions for bone maps M (#B).                                     returns #V by 3
  Eigen::MatrixX3d pose(const BoneTransforms& M) const;
};

// Fits `model` to the examples over the SSD rig `lbs` (fitted to the same examples). `brief`
// receives the fit summary's one-line description. Throws InputError when there are fewer
// examples than minimum_examples(model).
FittedModel fit_model(SkinningModel model, const SkinningExamples& ex, const SkinningRig& lbs,
                      const ModelFitOptions& options = {}, std::string* brief = nullptr,
                      const ProgressCallback& progress = {});

// The same for a path of MWE ridge scales: one model per scale (fit_mwe_path).
std::vector<FittedModel> fit_mwe_models(const SkinningExamples& ex, const SkinningRig& lbs,
                                        const MweFitOptions& options, const std::vector<double>& scales);

}  // namespace bodymodel
