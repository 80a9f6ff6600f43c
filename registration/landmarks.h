// Landmarks: named points placed on a scan, matched to template vertices by name.
//
// A landmark file is JSON {"name": [x, y, z], ...} in the scan's unit. The template side is a
// table name → template vertex index (e.g. core/landmarks.h body_landmarks()).
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace bodymodel {

// One landmark correspondence: template vertex `vertex` should land on `target` (scan unit).
struct Landmark {
  int vertex = -1;
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  std::string name;
};

using LandmarkTable = std::vector<std::pair<std::string, int>>;

// Reads a landmark JSON file and pairs each entry with the template vertex of the same name in
// `table`. Throws InputError naming the file when the JSON is malformed, a value is not three
// finite numbers, or a name is not in the table (listing the known names).
std::vector<Landmark> read_landmarks(const std::filesystem::path& path, const LandmarkTable& table);

// The template vertex of landmark `name`; an unknown name is an InputError naming `path` (the
// landmark file it came from) and listing the names the table knows.
int template_landmark_vertex(const LandmarkTable& table, const std::string& name,
                             const std::filesystem::path& path);

// Checks landmark vertex indices against a template of `vertex_count` vertices and that the
// targets are finite; InputError naming `what` otherwise.
void check_landmarks(const std::vector<Landmark>& landmarks, int vertex_count,
                     const std::string& what = "landmarks");

// The template vertices the landmarks pull, in order.
inline std::vector<int> landmark_vertices(const std::vector<Landmark>& landmarks) {
  std::vector<int> out;
  out.reserve(landmarks.size());
  for (const Landmark& l : landmarks) out.push_back(l.vertex);
  return out;
}

}  // namespace bodymodel
