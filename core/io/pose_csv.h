// Pose files (CSV): a header "bone,rx,ry,rz", then one row per bone "name,rx,ry,rz" (rotation
// vector, radians, relative to the parent in world-aligned axes, as core/skeleton.h), plus rows
// whose name starts with '_':
//   _scale,s,0,0                    global scale of template and skeleton about the root head
//   _root_translation_mm,x,y,z      Pose::root_translation
//   _global_rotation,rx,ry,rz       a rigid placement applied after posing (the synthetic
//   _global_translation_mm,x,y,z    database's truth files use these two)
// Other '_' rows are metadata and are ignored.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "core/skeleton.h"

namespace bodymodel {

struct PoseRecord {
  double scale = 1.0;
  Pose pose;                 // #B rotations in the order of the bone names read or written with
  Eigen::Matrix3d global_rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d global_translation = Eigen::Vector3d::Zero();  // mm

  // World orientation of every bone: global_rotation · Q_b (#B 3×3 matrices).
  std::vector<Eigen::Matrix3d> world_rotations(const Skeleton& skeleton) const;
};

// Writes atomically: the '_' rows, then one row per bone in the order of `bone_names` (#B, the
// size of record.pose.rotations).
void write_pose_csv(const std::filesystem::path& path, const std::vector<std::string>& bone_names,
                    const PoseRecord& record);

// Reads a pose file for a skeleton with bone names `bone_names` (#B); bones missing from the
// file stay at rest. InputError naming the file and line for a malformed row or a non-finite
// number. A row naming a bone that is not in `bone_names` is bad input (a file of another
// skeleton): InputError naming the file, line and bone — unless `skipped_bones` is given, then
// the row is skipped and the bone's name appended there, for the caller to report.
PoseRecord read_pose_csv(const std::filesystem::path& path, const std::vector<std::string>& bone_names,
                         std::vector<std::string>* skipped_bones = nullptr);

}  // namespace bodymodel
