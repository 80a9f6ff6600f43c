#include "core/io/shape_space_file.h"

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/json_text.h"

namespace bodymodel {

namespace {
constexpr const char* kFormat = "bodymodel-shape-space";

Eigen::VectorXd vector_of(const nlohmann::json& j, const std::string& key, const std::string& what) {
  if (!j.contains(key) || !j[key].is_array()) throw InputError(what + ": no array '" + key + "'");
  Eigen::VectorXd v(j[key].size());
  for (size_t i = 0; i < j[key].size(); ++i) {
    if (!j[key][i].is_number()) throw InputError(what + ": '" + key + "' entry " + std::to_string(i) + " is not a number");
    v[i] = j[key][i].get<double>();
  }
  return v;
}
}  // namespace

std::string shape_space_json(const ShapeSpace& s) {
  nlohmann::json j;
  j["format"] = kFormat;
  j["version"] = 1;
  j["source"] = s.source;
  j["people"] = s.people;
  j["explained"] = s.explained;
  j["parameters"] = s.parameters;
  j["mean"] = std::vector<double>(s.mean.data(), s.mean.data() + s.mean.size());
  j["sd"] = std::vector<double>(s.sd.data(), s.sd.data() + s.sd.size());
  if (s.has_sex())
    j["sex_direction"] = std::vector<double>(s.sex_direction.data(), s.sex_direction.data() + s.sex_direction.size());
  nlohmann::json rows = nlohmann::json::array();
  for (Eigen::Index r = 0; r < s.basis.rows(); ++r) {
    std::vector<double> row(s.basis.cols());
    for (Eigen::Index c = 0; c < s.basis.cols(); ++c) row[c] = s.basis(r, c);
    rows.push_back(row);
  }
  j["basis"] = rows;
  return json_text(j, 1) + "\n";
}

namespace {
ShapeSpace shape_space_of(const nlohmann::json& j, const std::string& what) {
  if (!j.is_object() || j.value("format", std::string()) != kFormat)
    throw InputError(what + ": not a shape-space file (expected \"format\": \"" + kFormat + "\"; make one with bodymodel shape-space)");
  if (j.value("version", 0) != 1) throw InputError(what + ": shape-space version " + j.value("version", nlohmann::json()).dump() + ", expected 1");
  ShapeSpace s;
  if (!j.contains("parameters") || !j["parameters"].is_array()) throw InputError(what + ": no array 'parameters'");
  for (const auto& p : j["parameters"]) {
    if (!p.is_string()) throw InputError(what + ": a parameter name is not a string");
    s.parameters.push_back(p.get<std::string>());
  }
  s.mean = vector_of(j, "mean", what);
  s.sd = vector_of(j, "sd", what);
  if (j.contains("sex_direction")) {
    s.sex_direction = vector_of(j, "sex_direction", what);
    if (s.sex_direction.size() != static_cast<Eigen::Index>(s.parameters.size()))
      throw InputError(what + ": 'sex_direction' needs one value per parameter");
  }
  if (!j.contains("basis") || !j["basis"].is_array() || j["basis"].size() != s.parameters.size())
    throw InputError(what + ": 'basis' needs one row per parameter (" + std::to_string(s.parameters.size()) + ")");
  s.basis.resize(s.parameters.size(), s.sd.size());
  for (size_t r = 0; r < s.parameters.size(); ++r) {
    const auto& row = j["basis"][r];
    if (!row.is_array() || row.size() != size_t(s.sd.size()))
      throw InputError(what + ": basis row " + std::to_string(r) + " needs " + std::to_string(s.sd.size()) + " numbers (one per sd)");
    for (size_t c = 0; c < row.size(); ++c) {
      if (!row[c].is_number()) throw InputError(what + ": basis row " + std::to_string(r) + " has a non-number");
      s.basis(r, c) = row[c].get<double>();
    }
  }
  s.explained = j.value("explained", 0.0);
  s.people = j.value("people", 0);
  s.source = j.value("source", std::string());
  if (s.mean.size() != s.basis.rows()) throw InputError(what + ": 'mean' needs one value per parameter");
  if (!s.mean.allFinite() || !s.sd.allFinite() || !s.basis.allFinite() || !s.sex_direction.allFinite() ||
      (s.sd.array() <= 0).any())
    throw InputError(what + ": a non-finite value or an sd that is not positive");
  return s;
}
}  // namespace

ShapeSpace read_shape_space(const std::filesystem::path& path) {
  const std::string what = path.string();
  try {
    return shape_space_of(nlohmann::json::parse(read_text_file(path)), what);
  } catch (const nlohmann::json::exception& e) {  // parse errors, and a value of the wrong type
    throw InputError(what + ": not a valid shape-space file (" + e.what() + ")");
  }
}

}  // namespace bodymodel
