#include "model/database.h"

#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/io/file_names.h"
#include "core/io/mesh_io.h"
#include "core/skeleton.h"
#include "model/format.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  std::stringstream ss(line);
  while (std::getline(ss, cell, ',')) {
    while (!cell.empty() && (cell.back() == '\r' || cell.back() == ' ')) cell.pop_back();
    out.push_back(cell);
  }
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

std::vector<std::vector<std::string>> read_csv(const fs::path& path) {
  std::ifstream f(path);
  if (!f) throw InputError(fmt::format("cannot open '{}'", path.string()));
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(f, line)) {
    if (line.empty() || line == "\r") continue;
    rows.push_back(split_csv(line));
  }
  if (rows.empty()) throw InputError(fmt::format("'{}' is empty (expected a header line)", path.string()));
  for (size_t i = 1; i < rows.size(); ++i)
    if (rows[i].size() != rows[0].size())
      throw InputError(fmt::format("'{}' line {}: {} fields, the header has {}", path.string(), i + 1,
                                   rows[i].size(), rows[0].size()));
  return rows;
}

bool parse_double(const std::string& s, double& v) {
  if (s.empty()) return false;
  char* end = nullptr;
  v = std::strtod(s.c_str(), &end);
  return end && *end == '\0';
}

std::string unit_of(const std::string& name) {
  auto ends = [&](const std::string& suf) {
    return name.size() >= suf.size() && name.compare(name.size() - suf.size(), suf.size(), suf) == 0;
  };
  if (ends("_cm")) return "cm";
  if (ends("_kg")) return "kg";
  if (ends("_pct") || name == "muscle") return "%";
  if (ends("_years")) return "years";
  if (ends("_l")) return "L";
  return "";
}

int column(const std::vector<std::string>& header, const std::string& name, const fs::path& path) {
  for (size_t i = 0; i < header.size(); ++i)
    if (header[i] == name) return static_cast<int>(i);
  throw InputError(fmt::format("'{}': no '{}' column in the header", path.string(), name));
}

}  // namespace

SubjectTable read_subject_table(const fs::path& path) {
  auto rows = read_csv(path);
  const auto& h = rows[0];
  int id_col = column(h, "subject_id", path);
  SubjectTable t;
  std::vector<int> cols;
  int sex_col = -1;
  for (size_t c = 0; c < h.size(); ++c) {
    if (static_cast<int>(c) == id_col) continue;
    if (h[c] == "seqn") continue;  // a population subject's person id (synth-db --population), not a label
    if (h[c] == "sex") {
      sex_col = static_cast<int>(c);
      continue;
    }
    // A label column holds numbers and at least one of them (an all-empty column, e.g. a text
    // column no row filled in, is not a label).
    bool numeric = rows.size() > 1, any = false;
    double v;
    for (size_t r = 1; r < rows.size() && numeric; ++r) {
      if (rows[r][c].empty()) continue;
      if (!parse_double(rows[r][c], v)) numeric = false;
      any = true;
    }
    if (numeric && any) cols.push_back(static_cast<int>(c));
  }
  if (sex_col >= 0) t.labels.push_back({"sex", ""});
  for (int c : cols) t.labels.push_back({h[c], unit_of(h[c])});
  t.values.resize(rows.size() - 1, t.labels.size());
  for (size_t r = 1; r < rows.size(); ++r) {
    t.ids.push_back(rows[r][id_col]);
    int k = 0;
    if (sex_col >= 0) {
      const std::string& s = rows[r][sex_col];
      if (s == "female" || s == "f" || s == "F")
        t.values(r - 1, k) = 0;
      else if (s == "male" || s == "m" || s == "M")
        t.values(r - 1, k) = 1;
      else if (s.empty())
        t.values(r - 1, k) = std::numeric_limits<double>::quiet_NaN();
      else
        throw InputError(fmt::format("'{}' line {}: sex must be female or male, got '{}'", path.string(), r + 1, s));
      ++k;
    }
    for (int c : cols) {
      double v = std::numeric_limits<double>::quiet_NaN();
      if (!rows[r][c].empty()) parse_double(rows[r][c], v);
      t.values(r - 1, k++) = v;
    }
  }
  return t;
}

std::vector<ScanTableRow> read_scan_table(const fs::path& path) {
  auto rows = read_csv(path);
  int a = column(rows[0], "scan_id", path), b = column(rows[0], "subject_id", path),
      c = column(rows[0], "pose", path);
  std::vector<ScanTableRow> out;
  for (size_t r = 1; r < rows.size(); ++r) {
    // A scan id names files (REG/<id>.ply, DB/truth/<id>.pose.csv): it must stay in its folder.
    check_file_name(rows[r][a], fmt::format("'{}' line {}", path.string(), r + 1), "scan id");
    out.push_back({rows[r][a], rows[r][b], rows[r][c]});
  }
  return out;
}

ModelBuildInput read_registered_database(const fs::path& reg, const fs::path& db,
                                         DatabaseReadSummary* summary, const ProgressCallback& progress) {
  if (!fs::is_directory(reg)) throw InputError(fmt::format("'{}' is not a folder of registered meshes", reg.string()));
  if (!fs::is_directory(db)) throw InputError(fmt::format("'{}' is not a database folder", db.string()));
  SubjectTable subjects = read_subject_table(db / "subjects.csv");
  std::map<std::string, int> subject_row;
  for (size_t i = 0; i < subjects.ids.size(); ++i) subject_row[subjects.ids[i]] = static_cast<int>(i);
  auto scans = read_scan_table(db / "scans.csv");
  DatabaseReadSummary sum;
  sum.scans_listed = static_cast<int>(scans.size());

  ModelBuildInput in;
  in.subject_labels = subjects.labels;
  std::vector<Eigen::VectorXd> subject_rows;
  std::vector<std::map<std::string, Eigen::Vector3d>> poses;
  std::vector<char> has_pose;
  std::set<std::string> bones_seen;
  std::vector<std::string> bone_order;
  for (size_t s = 0; s < scans.size(); ++s) {
    const auto& row = scans[s];
    report_progress(progress, double(s) / scans.size(), row.scan_id);
    auto it = subject_row.find(row.subject_id);
    if (it == subject_row.end())
      throw InputError(fmt::format("'{}': scan '{}' names subject '{}', which subjects.csv does not list",
                                   (db / "scans.csv").string(), row.scan_id, row.subject_id));
    fs::path mesh_path;
    for (const char* ext : {".ply", ".obj"})
      if (fs::exists(reg / (row.scan_id + ext))) {
        mesh_path = reg / (row.scan_id + ext);
        break;
      }
    if (mesh_path.empty()) {
      sum.missing.push_back(row.scan_id);
      continue;
    }
    Mesh m = read_mesh(mesh_path);
    if (in.meshes.empty())
      in.F = m.F;
    else if (m.V.rows() != in.meshes[0].rows() || m.F.rows() != in.F.rows() || m.F != in.F)
      throw InputError(fmt::format("'{}': {} vertices / {} triangles with different faces than '{}' "
                                   "({} / {}): registered meshes must share the template's topology",
                                   mesh_path.string(), m.V.rows(), m.F.rows(), in.scan_ids[0],
                                   in.meshes[0].rows(), in.F.rows()));
    in.meshes.push_back(std::move(m.V));
    in.scan_ids.push_back(row.scan_id);
    in.subject_ids.push_back(row.subject_id);
    in.is_standard_pose.push_back(row.pose == "standard" ? 1 : 0);
    subject_rows.push_back(subjects.values.row(it->second).transpose());
    // Pose labels.
    std::map<std::string, Eigen::Vector3d> pose;
    fs::path pose_path = db / "truth" / (row.scan_id + ".pose.csv");
    bool have = false;
    if (fs::exists(pose_path)) {
      auto prow = read_csv(pose_path);
      for (size_t r = 1; r < prow.size(); ++r) {
        if (prow[r].size() < 4) continue;
        const std::string& bone = prow[r][0];
        if (bone.empty() || bone[0] == '_') continue;  // _global_rotation, _global_translation_mm
        Eigen::Vector3d w;
        for (int c = 0; c < 3; ++c)
          if (!parse_double(prow[r][1 + c], w(c)))
            throw InputError(fmt::format("'{}' line {}: '{}' is not a number", pose_path.string(), r + 1, prow[r][1 + c]));
        pose[bone] = w;
        if (bones_seen.insert(bone).second) bone_order.push_back(bone);
      }
      have = true;
      ++sum.scans_with_pose_labels;
    }
    poses.push_back(std::move(pose));
    has_pose.push_back(have ? 1 : 0);
  }
  if (in.meshes.empty())
    throw InputError(fmt::format("no registered mesh found in '{}' for any of the {} scans of '{}' (expected "
                                 "<scan_id>.ply or .obj, e.g. '{}.ply')",
                                 reg.string(), scans.size(), (db / "scans.csv").string(),
                                 scans.empty() ? std::string("s000_p0") : scans[0].scan_id));
  const int S = static_cast<int>(in.meshes.size());
  in.subject_label_values.resize(S, in.subject_labels.size());
  for (int s = 0; s < S; ++s) in.subject_label_values.row(s) = subject_rows[s].transpose();
  for (const auto& bone : bone_order)
    for (const char* ax : {"rx", "ry", "rz"}) in.pose_labels.push_back({"pose:" + bone + ":" + ax, "rad"});
  in.pose_label_values.resize(S, in.pose_labels.size());
  for (int s = 0; s < S; ++s)
    for (size_t b = 0; b < bone_order.size(); ++b) {
      auto it = poses[s].find(bone_order[b]);
      for (int c = 0; c < 3; ++c) {
        double v;
        if (it != poses[s].end())
          v = it->second(c);
        else
          v = (has_pose[s] || in.is_standard_pose[s]) ? 0.0 : std::numeric_limits<double>::quiet_NaN();
        in.pose_label_values(s, 3 * b + c) = v;
      }
    }
  sum.scans_read = S;
  if (summary) *summary = sum;
  return in;
}

}  // namespace bodymodel
