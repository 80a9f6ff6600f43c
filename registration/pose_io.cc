#include "registration/pose_io.h"

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {

Eigen::Vector3d rotation_to_vector(const Eigen::Matrix3d& R) {
  Eigen::AngleAxisd a(R);
  return a.angle() * a.axis();
}

Eigen::Matrix3d vector_to_rotation(const Eigen::Vector3d& v) {
  const double a = v.norm();
  if (a < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(a, v / a).toRotationMatrix();
}

double rotation_angle_deg(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  const Eigen::Matrix3d D = A * B.transpose();
  return std::acos(std::clamp((D.trace() - 1.0) / 2.0, -1.0, 1.0)) * 180.0 / M_PI;
}

std::vector<Eigen::Matrix3d> PoseRecord::world_rotations(const Skeleton& skeleton) const {
  std::vector<Eigen::Matrix3d> Q = bodymodel::world_rotations(skeleton, pose);
  for (auto& q : Q) q = global_rotation * q;
  return Q;
}

void write_pose_csv(const std::filesystem::path& path, const Skeleton& skeleton,
                    const PoseRecord& r) {
  std::string s = "bone,rx,ry,rz\n";
  auto row = [&](const std::string& name, const Eigen::Vector3d& v) {
    char buf[128];
    std::snprintf(buf, sizeof buf, ",%.9g,%.9g,%.9g\n", v.x(), v.y(), v.z());
    s += name + buf;
  };
  row("_scale", Eigen::Vector3d(r.scale, 0, 0));
  row("_root_translation_mm", r.pose.root_translation);
  row("_global_rotation", rotation_to_vector(r.global_rotation));
  row("_global_translation_mm", r.global_translation);
  for (int b = 0; b < skeleton.bone_count(); ++b)
    row(skeleton.names[b], rotation_to_vector(r.pose.rotations[b]));
  write_text_file(path, s);
}

PoseRecord read_pose_csv(const std::filesystem::path& path, const Skeleton& skeleton) {
  std::istringstream in(read_text_file(path));
  PoseRecord r;
  r.pose = Pose::rest(skeleton.bone_count());
  std::string line;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || (lineno == 1 && line.rfind("bone,", 0) == 0)) continue;
    std::vector<std::string> f;
    std::stringstream ls(line);
    std::string cell;
    while (std::getline(ls, cell, ',')) f.push_back(cell);
    if (f.size() != 4)
      throw InputError(path.string() + ":" + std::to_string(lineno) +
                       ": expected 'name,rx,ry,rz', found '" + line + "'");
    Eigen::Vector3d v;
    for (int k = 0; k < 3; ++k) {
      try {
        size_t used = 0;
        v[k] = std::stod(f[1 + k], &used);
        if (used != f[1 + k].size()) throw std::invalid_argument("trailing");
      } catch (const std::exception&) {
        throw InputError(path.string() + ":" + std::to_string(lineno) + ": '" + f[1 + k] +
                         "' is not a number");
      }
    }
    if (!v.allFinite())
      throw InputError(path.string() + ":" + std::to_string(lineno) + ": non-finite value");
    const std::string& name = f[0];
    if (name == "_scale") r.scale = v.x();
    else if (name == "_root_translation_mm") r.pose.root_translation = v;
    else if (name == "_global_rotation") r.global_rotation = vector_to_rotation(v);
    else if (name == "_global_translation_mm") r.global_translation = v;
    else if (!name.empty() && name[0] == '_') continue;  // other metadata rows
    else {
      const int b = skeleton.find(name);
      if (b < 0)
        throw InputError(path.string() + ":" + std::to_string(lineno) + ": unknown bone '" +
                         name + "' (not in the template skeleton)");
      r.pose.rotations[b] = vector_to_rotation(v);
    }
  }
  return r;
}

}  // namespace bodymodel
