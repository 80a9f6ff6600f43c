// The pose fitter's unknowns (docs/pose_fit.md#parameters): which bones rotate together and how
// (PoseParameter), the parameterisations of the MakeHuman skeleton, those resolved against a
// skeleton (PoseParameterization), and the values the solver changes (PoseUnknowns).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/skeleton.h"

namespace bodymodel {

// One fitted rotation shared by a group of bones (each bone of the group gets the same
// rotation relative to its parent), or, with `twist`, an angle about each bone's own rest axis.
struct PoseParameter {
  std::vector<std::string> bones;
  bool twist = false;
  double prior = 1.0;  // multiplies PoseFitOptions::pose_prior for each bone of the group
  // Fitted only in the hand stage (with the body held where it converged); at rest before, not
  // anchored.
  bool late = false;
  // A finger's curl: one angle about each bone's curl axis (bone direction × palm normal of its
  // hand), shared over the phalanges of the group so that the finger closes as a whole.
  bool curl = false;
  // Pulled towards the landmark-only solve's value (PoseFitOptions::anchor_prior) in the ICP.
  bool anchored = true;
  // A thumb's tuck: one angle per bone about its hand's palm normal, signed so that a positive
  // angle sweeps the tip across the palm. Never fitted: set by the hand stage's start
  // (PoseFitOptions::hand_start_tucks_deg) and held there. Needs `late`.
  bool tuck = false;
};

// Pose parameterisations of the MakeHuman default skeleton (docs/pose_fit.md#parameterisations):
// 'segment': one rotation per body segment (tied spine and neck groups, clavicle + shoulder01,
// twist-only second bones of each limb segment) plus finger grasp groups;
const std::vector<PoseParameter>& segment_pose_parameters();
// 'bone': every spine, neck, arm and leg bone of the segment set a free ball joint (the
// pose prior picks the smallest split), finger grasp groups as in 'segment'.
const std::vector<PoseParameter>& bone_pose_parameters();
// 'segment' with the hands in a hand stage (PoseParameter::late) instead of the grasp groups:
// one curl per finger, the thumbs ball joints at their base plus their (held) tuck.
// register --hand-stage on selects it.
const std::vector<PoseParameter>& hand_stage_pose_parameters();
// `parameters` with the finger grasp groups (bones named "finger…") replaced by the hand stage's
// per-finger curls and thumbs (as in hand_stage_pose_parameters()): e.g. 'bone' with a hand
// stage. The other groups are kept as they are.
std::vector<PoseParameter> with_hand_stage(const std::vector<PoseParameter>& parameters);
// The default parameters: 'segment' (the better of the two on the synthetic database).
const std::vector<PoseParameter>& default_pose_parameters();
// All bones named by default_pose_parameters().
const std::vector<std::string>& default_free_bones();

// A PoseParameter resolved against a skeleton.
struct FittedParameter {
  std::vector<int> bones;  // skeleton indices (never the root, which is always free on its own)
  bool twist = false;
  double prior = 1.0;
  bool late = false;
  bool curl = false;
  bool anchored = true;
  bool tuck = false;
  // One angle (twist, curl, tuck: stored in PoseUnknowns::joints[k][0]) or a ball joint (3).
  bool one_dof() const { return twist || curl || tuck; }
};

// The parameters of one fit against one skeleton of #B bones, #P parameters.
struct PoseParameterization {
  std::vector<FittedParameter> params;     // #P
  std::vector<int> free_index;             // #B: bone → its parameter, -1 fixed (and the root)
  std::vector<int> free_bones;             // the root, then every parameter's bones in order
  std::vector<Eigen::Vector3d> bone_axis;  // #B unit rest direction (zero for a zero-length bone)
  // #B rotation axis of a 1-DOF bone: its rest direction (twist), its curl axis (rest direction ×
  // palm normal) or its tuck axis (± palm normal); bone_axis for the other bones.
  std::vector<Eigen::Vector3d> dof_axis;
  std::vector<int> hand_of;                // #B: a curl bone's wrist bone, else -1

  int count() const { return static_cast<int>(params.size()); }
};

// Resolves the fit's parameters: `free_bones` (names, each its own ball joint) when not empty,
// else `parameters`, else default_pose_parameters() keeping the bones the skeleton has. A bone
// already taken by an earlier group is skipped. Throws InputError for a named bone (free_bones or
// parameters) the skeleton does not have, a zero-length twist or curl bone, or a curl or tuck
// bone without a hand of several bones below its wrist.
PoseParameterization resolve_pose_parameters(const Skeleton& skeleton,
                                             const std::vector<std::string>& free_bones,
                                             const std::vector<PoseParameter>& parameters);

// The values the solver changes; Ceres parameter blocks point into them, so they must not move
// while a ceres::Problem refers to them.
struct PoseUnknowns {
  double scale = 1.0;                                    // about the root head
  Eigen::Vector3d root = Eigen::Vector3d::Zero();        // root rotation vector (rad)
  Eigen::Vector3d translation = Eigen::Vector3d::Zero(); // root translation (mm)
  // #P: a ball joint's rotation vector (rad), or a 1-DOF parameter's angle (rad) in [0].
  std::vector<Eigen::Vector3d> joints;
};

// The rotation (relative to its parent) that parameter k gives its bone b.
Eigen::Matrix3d parameter_rotation(const PoseParameterization& parameterization,
                                   const PoseUnknowns& unknowns, int k, int b);
// The pose of all #B bones (`bone_count`): fixed bones at rest.
Pose pose_of(const PoseParameterization& parameterization, const PoseUnknowns& unknowns,
             int bone_count);

}  // namespace bodymodel
