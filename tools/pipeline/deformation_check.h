// Plausibility of an animated mesh frame against its rest shape: exploded triangles show as
// edges much longer than at rest, flipped ones as triangles whose normal turns against the
// rotation of the bone that mostly carries them.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/skeleton.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

struct FrameCheck {
  double max_edge_ratio = 1;   // max over edges of |e'| / |e|
  double min_edge_ratio = 1;
  double p99_edge_ratio = 1;   // 99th percentile over edges of |e'| / |e|
  int worst_edge = -1;         // index into the checker's edges
  int flipped = 0;             // triangles with n' · (R_b n) < 0
};

class DeformationChecker {
 public:
  // rest #V by 3, F #F by 3, lbs: an SSD rig of the same vertices whose largest weight per
  // triangle (summed over its corners) names the triangle's dominant bone.
  DeformationChecker(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3i& F, const SkinningRig& lbs);
  // X #V by 3 posed vertices; M the bone maps of the frame (#B).
  FrameCheck check(const Eigen::MatrixX3d& X, const BoneTransforms& M) const;
  const Eigen::MatrixX2i& edges() const { return E_; }
  double rest_length(int edge) const { return rest_length_(edge); }
  // Bone with the largest weight at vertex v in the SSD rig given to the constructor.
  int dominant_bone_of_vertex(int v) const { return vertex_bone_(v); }
  // Bone with the largest summed corner weight of triangle f (its flip reference).
  int dominant_bone_of_face(int f) const { return dominant_bone_(f); }
  // Indices of the triangles that check() counts as flipped.
  std::vector<int> flipped_faces(const Eigen::MatrixX3d& X, const BoneTransforms& M) const;
  // The flip references of a frame: each triangle's rest normal turned by the rotation of its
  // dominant bone, #F by 3 (unit). Triangle f is flipped when its normal · row f < 0.
  Eigen::MatrixX3d reference_normals(const BoneTransforms& M) const;

 private:
  Eigen::MatrixX3i F_;
  Eigen::MatrixX2i E_;
  Eigen::VectorXd rest_length_;
  Eigen::MatrixX3d rest_normals_;
  Eigen::VectorXi dominant_bone_;
  Eigen::VectorXi vertex_bone_;
};

}  // namespace bodymodel
