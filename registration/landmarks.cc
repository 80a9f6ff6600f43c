#include "registration/landmarks.h"

#include <cmath>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {

int template_landmark_vertex(const LandmarkTable& table, const std::string& name,
                             const std::filesystem::path& path) {
  for (const auto& [n, v] : table)
    if (n == name) return v;
  std::string known;
  for (const auto& [n, v] : table) known += (known.empty() ? "" : ", ") + n;
  throw InputError(path.string() + ": unknown landmark name '" + name + "'; the template knows: " + known);
}

std::vector<Landmark> read_landmarks(const std::filesystem::path& path,
                                     const LandmarkTable& table) {
  const std::string text = read_text_file(path);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const std::exception& e) {
    throw InputError(path.string() + ": expected a JSON object {name: [x, y, z]}, parse error: " +
                     e.what());
  }
  if (!j.is_object())
    throw InputError(path.string() + ": expected a JSON object {name: [x, y, z]}, found " +
                     std::string(j.type_name()));
  std::vector<Landmark> out;
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& name = it.key();
    const int vertex = template_landmark_vertex(table, name, path);
    const auto& a = it.value();
    if (!a.is_array() || a.size() != 3 || !a[0].is_number() || !a[1].is_number() ||
        !a[2].is_number())
      throw InputError(path.string() + ": landmark '" + name +
                       "' must be an array of three numbers, found " + a.dump());
    Landmark l;
    l.vertex = vertex;
    l.name = name;
    l.target = {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
    if (!l.target.allFinite())
      throw InputError(path.string() + ": landmark '" + name + "' is not finite");
    out.push_back(std::move(l));
  }
  return out;
}

void check_landmarks(const std::vector<Landmark>& landmarks, int vertex_count,
                     const std::string& what) {
  for (const auto& l : landmarks) {
    if (l.vertex < 0 || l.vertex >= vertex_count)
      throw InputError(what + ": landmark '" + l.name + "' refers to vertex " +
                       std::to_string(l.vertex) + ", expected 0.." +
                       std::to_string(vertex_count - 1));
    if (!l.target.allFinite())
      throw InputError(what + ": landmark '" + l.name + "' has a non-finite position");
  }
}

}  // namespace bodymodel
