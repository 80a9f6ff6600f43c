#include "core/io/pose_csv.h"

#include <algorithm>
#include <cstdio>
#include <sstream>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/rotation.h"

namespace bodymodel {

std::vector<Eigen::Matrix3d> PoseRecord::world_rotations(const Skeleton& skeleton) const {
  std::vector<Eigen::Matrix3d> Q = bodymodel::world_rotations(skeleton, pose);
  for (auto& q : Q) q = global_rotation * q;
  return Q;
}

void write_pose_csv(const std::filesystem::path& path, const std::vector<std::string>& bone_names,
                    const PoseRecord& r) {
  if (r.pose.rotations.size() != bone_names.size())
    throw InputError(path.string() + ": " + std::to_string(r.pose.rotations.size()) +
                     " bone rotations for " + std::to_string(bone_names.size()) + " bone names");
  std::string s = "bone,rx,ry,rz\n";
  auto row = [&](const std::string& name, const Eigen::Vector3d& v) {
    char buf[128];
    std::snprintf(buf, sizeof buf, ",%.9g,%.9g,%.9g\n", v.x(), v.y(), v.z());
    s += csv_field(name) + buf;
  };
  row("_scale", Eigen::Vector3d(r.scale, 0, 0));
  row("_root_translation_mm", r.pose.root_translation);
  row("_global_rotation", rotation_vector_of(r.global_rotation));
  row("_global_translation_mm", r.global_translation);
  for (size_t b = 0; b < bone_names.size(); ++b) row(bone_names[b], rotation_vector_of(r.pose.rotations[b]));
  write_text_file(path, s);
}

PoseRecord read_pose_csv(const std::filesystem::path& path, const std::vector<std::string>& bone_names,
                         std::vector<std::string>* skipped_bones) {
  const std::vector<CsvRecord> rows = read_csv_file(path);
  PoseRecord r;
  r.pose = Pose::rest(static_cast<int>(bone_names.size()));
  int lineno = 0;
  auto where = [&] { return path.string() + ":" + std::to_string(lineno) + ": "; };
  for (size_t k = 0; k < rows.size(); ++k) {
    lineno = rows[k].line;
    const std::vector<std::string>& f = rows[k].fields;
    if (k == 0 && f.size() == 4 && f[0] == "bone") continue;
    if (f.size() != 4) throw InputError(where() + "expected 'name,rx,ry,rz', found '" + csv_row(f) + "'");
    Eigen::Vector3d v;
    for (int k = 0; k < 3; ++k) {
      try {
        size_t used = 0;
        v[k] = std::stod(f[1 + k], &used);
        if (used != f[1 + k].size()) throw std::invalid_argument("trailing");
      } catch (const std::exception&) {
        throw InputError(where() + "'" + f[1 + k] + "' is not a number");
      }
    }
    if (!v.allFinite()) throw InputError(where() + "non-finite value");
    const std::string& name = f[0];
    if (name == "_scale") r.scale = v.x();
    else if (name == "_root_translation_mm") r.pose.root_translation = v;
    else if (name == "_global_rotation") r.global_rotation = rotation_from_vector(v);
    else if (name == "_global_translation_mm") r.global_translation = v;
    else if (!name.empty() && name[0] == '_') continue;  // other metadata rows
    else {
      const auto it = std::find(bone_names.begin(), bone_names.end(), name);
      if (it != bone_names.end()) {
        r.pose.rotations[it - bone_names.begin()] = rotation_from_vector(v);
      } else if (skipped_bones) {
        skipped_bones->push_back(name);
      } else {
        throw InputError(where() + "unknown bone '" + name + "' (not in the skeleton's " +
                         std::to_string(bone_names.size()) + " bones)");
      }
    }
  }
  return r;
}

}  // namespace bodymodel
