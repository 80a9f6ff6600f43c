// Training data for fitting a skinning rig: a rest mesh, the bone transforms of each example pose
// and the example meshes (same vertex order), plus the choice of each vertex's influence set.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/skeleton.h"

namespace bodymodel {

struct SkinningExamples {
  Eigen::MatrixX3d rest;                    // #V by 3 rest positions (the data set's unit)
  std::vector<BoneTransforms> transforms;   // #P poses, each #B affine maps rest → posed
  std::vector<Eigen::MatrixX3d> poses;      // #P meshes, each #V by 3, same vertex order as rest
  Eigen::VectorXd pose_weights;             // #P per-pose importance (MWE §4.2), or empty = 1

  int vertex_count() const { return static_cast<int>(rest.rows()); }
  int pose_count() const { return static_cast<int>(poses.size()); }
  int bone_count() const { return transforms.empty() ? 0 : static_cast<int>(transforms[0].size()); }
  double pose_weight(int p) const { return pose_weights.size() ? pose_weights(p) : 1.0; }
};

// Throws InputError naming the pose (and bone) when: counts disagree, a pose has a different
// vertex count than the rest mesh, anything is NaN/infinite, pose weights are negative, or —
// when `require_rigid` — a transform is not a rotation plus translation (‖RᵀR − I‖ > tol or
// det R ≤ 0).
void validate_examples(const SkinningExamples& ex, bool require_rigid, double rigid_tolerance = 1e-4);

// True if every transform is rigid to `tolerance`; otherwise `problem` says which one is not.
bool transforms_are_rigid(const std::vector<BoneTransforms>& T, double tolerance,
                          std::string* problem = nullptr);

// Influence sets chosen automatically: the `max_influences` bones whose rigid motion best
// explains each vertex over the examples (smallest Σ_p ‖M_b(p) ṽ − q_p‖²), best first.
// returns #V by K (K = min(max_influences, #B)), no -1 slots.
Eigen::MatrixXi choose_influences(const SkinningExamples& ex, int max_influences);

}  // namespace bodymodel
