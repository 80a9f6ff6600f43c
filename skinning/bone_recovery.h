// Bone recovery for mesh sequences without a skeleton (Jacka et al. 2007 §3.1, after James &
// Twigg 2005): each triangle's rotation sequence (polar decomposition of its deformation gradient
// from the rest frame to every example) is clustered into #bones groups (k-means, k-means++ seeded
// — a deterministic stand-in for mean shift with a chosen cluster count); each cluster is a rigid
// section and gets one rigid transform per frame (Kabsch on its vertices). A few EM-like rounds
// (after Anguelov et al., as Jacka did) reassign each vertex to the bone that moves it best and
// refit the transforms.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/progress.h"
#include "core/skeleton.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

struct BoneRecoveryOptions {
  int bones = 24;                 // rigid sections (clusters)
  int kmeans_iterations = 40;
  int refinement_rounds = 4;      // vertex reassignment + transform refit rounds
  unsigned seed = 1;
};

struct BoneRecoverySummary {
  int bones = 0, frames = 0, kmeans_iterations = 0;
  double rms_rigid_residual = 0;  // RMS ‖M_{bone(v)} v − q‖ over vertices and frames
  double seconds = 0;
  std::string brief() const;
};

struct RecoveredBones {
  Eigen::VectorXi vertex_bone;              // #V rigid section of each vertex
  Eigen::VectorXi triangle_bone;            // #F cluster of each triangle (k-means result)
  std::vector<BoneTransforms> transforms;   // #P frames × #bones rigid maps rest → frame
};

// rest #V by 3, F #F by 3, frames: #P meshes #V by 3. Throws InputError if bones > #F or < 1,
// a frame's vertex count differs, or any input is NaN.
RecoveredBones recover_bones(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3i& F,
                             const std::vector<Eigen::MatrixX3d>& frames,
                             const BoneRecoveryOptions& options = {},
                             BoneRecoverySummary* summary = nullptr,
                             const ProgressCallback& progress = {});

// Rigid transforms of a new frame Q (#V by 3) for a partition into rigid sections (#V labels in
// 0..bones-1): Kabsch per section; a section with fewer than 3 vertices keeps the identity.
BoneTransforms fit_section_transforms(const Eigen::MatrixX3d& rest, const Eigen::VectorXi& vertex_bone,
                                      int bones, const Eigen::MatrixX3d& Q);

// What the fixed-weight transform fit needs of an SSD rig's weights, independent of the frame
// (Le & Deng 2012's SSDR: the per-bone Procrustes sums are linear in the other bones' maps, so
// they follow from weight moments instead of a pass over the vertices). With ṽ = (v, 1) and a
// bone's members i (weight w_ib > 1e-8): cross[b] = (k, Σ_i w_ib w_ik ṽ ṽᵀ) for every bone k
// sharing a member with b (b itself included), self[b] = Σ_i w_ib² ṽ ṽᵀ.
struct FixedWeightMoments {
  int bones = 0;
  std::vector<int> members;   // per bone
  std::vector<std::vector<std::pair<int, Eigen::Matrix4d>>> cross;
  std::vector<Eigen::Matrix4d> self;
};
FixedWeightMoments fixed_weight_moments(const SkinningRig& lbs_rig);

// Bone transforms of a frame Q with an SSD rig's weights held fixed (SSDR-style, Kavan & Le 2012:
// each bone in turn solves a weighted Procrustes problem on the residual of the others), starting
// from `initial`. Transforms stay rigid; `initial` must be rigid (InputError otherwise).
// The sums come from the weight moments (computed here when `moments` is null; pass them to share
// them between frames): one pass over the vertices per frame instead of one per bone and iteration.
BoneTransforms fit_transforms_with_fixed_weights(const SkinningRig& lbs_rig, const Eigen::MatrixX3d& Q,
                                                 const BoneTransforms& initial, int iterations = 5,
                                                 const FixedWeightMoments* moments = nullptr);
// The same fit summing over each bone's vertices in every iteration: the implementation before the
// moments, kept as the reference of the tests and the benchmark (equal up to rounding).
BoneTransforms fit_transforms_with_fixed_weights_per_vertex(const SkinningRig& lbs_rig, const Eigen::MatrixX3d& Q,
                                                            const BoneTransforms& initial, int iterations = 5);

}  // namespace bodymodel
