// Skeleton, skinning weights and linear blend posing.
//
// Convention (MakeHuman / BVH): each bone has a rest head h_b; a pose gives each bone a
// rotation R_b relative to its parent, expressed in world-aligned axes. Forward kinematics:
//   Q_b = Q_parent · R_b,   h'_b = h'_parent + Q_parent (h_b − h_parent)   (root: h'_root = h_root + t)
// and bone b carries a rest point x to M_b(x) = Q_b (x − h_b) + h'_b.
// Linear blend skinning: v' = Σ_b w_b(v) M_b(v).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/Sparse>
#include <string>
#include <string_view>
#include <vector>

namespace bodymodel {

struct Skeleton {
  std::vector<std::string> names;   // #B bone names
  std::vector<int> parents;         // #B parent index, -1 for a root; parents[b] < b always
  Eigen::MatrixX3d heads;           // #B by 3 rest head positions (mm for bodies)
  Eigen::MatrixX3d tails;           // #B by 3 rest tail positions

  int bone_count() const { return static_cast<int>(names.size()); }
  // Index of the bone called `name`, or -1.
  int find(std::string_view name) const;
  // Like find, but throws InputError naming the bone when it does not exist.
  int index(std::string_view name) const;
  // Throws InputError if parents are not topologically ordered or sizes disagree.
  void validate() const;
};

// Skinning weights: #V by #B, each row non-negative and summing to one.
using SkinWeights = Eigen::SparseMatrix<double, Eigen::RowMajor>;

// A pose: per-bone rotation relative to the parent (world-aligned axes) plus root translation.
struct Pose {
  std::vector<Eigen::Matrix3d> rotations;      // #B (identity = rest)
  Eigen::Vector3d root_translation = Eigen::Vector3d::Zero();

  static Pose rest(int bone_count);
};

// Per-bone affine map M_b from rest to posed space (a rigid motion for a pose).
using BoneTransforms = std::vector<Eigen::Affine3d>;

// Forward kinematics: the transforms M_b of every bone for `pose`.
BoneTransforms forward_kinematics(const Skeleton& skeleton, const Pose& pose);

// World rotations Q_b of every bone for `pose`.
std::vector<Eigen::Matrix3d> world_rotations(const Skeleton& skeleton, const Pose& pose);

// Linear blend skinning of the rest vertices V (#V by 3) with weights W (#V by #B).
Eigen::MatrixX3d linear_blend_skinning(const Eigen::MatrixX3d& V, const SkinWeights& W,
                                       const BoneTransforms& M);

}  // namespace bodymodel
