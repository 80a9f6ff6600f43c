// Pose files (CSV): one row per bone "name,rx,ry,rz" (rotation vector, radians, relative to the
// parent in world-aligned axes, as core/skeleton.h), plus rows whose name starts with '_':
//   _scale,s,0,0                    global scale of template and skeleton about the root head
//   _root_translation_mm,x,y,z      Pose::root_translation
//   _global_rotation,rx,ry,rz       a rigid placement applied after posing (the synthetic
//   _global_translation_mm,x,y,z    database's truth files use these two)
#pragma once

#include <Eigen/Core>
#include <filesystem>

#include "core/skeleton.h"

namespace bodymodel {

struct PoseRecord {
  double scale = 1.0;
  Pose pose;
  Eigen::Matrix3d global_rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d global_translation = Eigen::Vector3d::Zero();

  // World orientation of every bone: global_rotation · Q_b.
  std::vector<Eigen::Matrix3d> world_rotations(const Skeleton& skeleton) const;
};

// Writes atomically. Bones listed in skeleton order.
void write_pose_csv(const std::filesystem::path& path, const Skeleton& skeleton,
                    const PoseRecord& record);

// Reads a pose file for `skeleton`; bones missing from the file stay at rest. InputError naming
// the file and line for a malformed row or an unknown bone name.
PoseRecord read_pose_csv(const std::filesystem::path& path, const Skeleton& skeleton);

// Rotation vector ↔ matrix.
Eigen::Vector3d rotation_to_vector(const Eigen::Matrix3d& R);
Eigen::Matrix3d vector_to_rotation(const Eigen::Vector3d& v);
// Angle of A·Bᵀ in degrees.
double rotation_angle_deg(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B);

}  // namespace bodymodel
