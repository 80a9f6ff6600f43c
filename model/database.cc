#include "model/database.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <set>

#include "core/error.h"
#include "core/io/csv.h"
#include "core/io/file_names.h"
#include "core/io/mesh_io.h"
#include "core/measure.h"
#include "core/skeleton.h"
#include "model/format.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

// The project's one CSV reader (core/io/csv.h): quoted fields, a byte-order mark, CRLF.
std::vector<std::vector<std::string>> read_csv(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(fmt::format("cannot open '{}'", path.string()));
  std::vector<std::vector<std::string>> rows;
  const std::vector<CsvRecord> records = read_csv_file(path);
  for (const auto& r : records) rows.push_back(r.fields);
  if (rows.empty()) throw InputError(fmt::format("'{}' is empty (expected a header line)", path.string()));
  for (size_t i = 1; i < rows.size(); ++i)
    if (rows[i].size() != rows[0].size())
      throw InputError(fmt::format("'{}' line {}: {} fields, the header has {}", path.string(), records[i].line,
                                   rows[i].size(), rows[0].size()));
  return rows;
}

bool parse_double(const std::string& s, double& v) {
  if (s.empty()) return false;
  char* end = nullptr;
  v = std::strtod(s.c_str(), &end);
  return end && *end == '\0';
}

// Larger label values are no body's (heights in cm, weights in kg, ages, percentages) and
// overflow the regression's sums of squares.
constexpr double kMaxLabelMagnitude = 1e6;

std::string unit_of(const std::string& name);

// A label cell: empty = unknown (NaN); otherwise a finite number of a body's range, else an
// InputError naming the file, line and column (inf or 1e308 used to reach the model file, or
// fail in the regression naming nothing).
double label_value(const std::string& cell, const fs::path& path, size_t line, const std::string& column) {
  if (cell.empty()) return std::numeric_limits<double>::quiet_NaN();
  double v = 0;
  if (!parse_double(cell, v))
    throw InputError(fmt::format("'{}' line {}, column '{}': '{}' is not a number", path.string(), line, column, cell));
  if (!std::isfinite(v))
    throw InputError(fmt::format("'{}' line {}, column '{}': '{}' is not a finite number (leave the cell empty for "
                                 "an unknown value)",
                                 path.string(), line, column, cell));
  if (std::abs(v) > kMaxLabelMagnitude)
    throw InputError(fmt::format("'{}' line {}, column '{}': {} is outside the range of a body's label (|value| ≤ {:g})",
                                 path.string(), line, column, cell, kMaxLabelMagnitude));
  const std::string unit = unit_of(column);
  if (v < 0 && (unit == "cm" || unit == "kg" || unit == "L" || unit == "years"))
    throw InputError(fmt::format("'{}' line {}, column '{}': {} is negative, a length, mass, volume or age is not",
                                 path.string(), line, column, cell));
  return v;
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
    // A population subject's person id (synth-db --population: NHANES seqn, ANSUR subjectid), not a label.
    if (h[c] == "seqn" || h[c] == "subjectid") continue;
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
    for (int c : cols) t.values(r - 1, k++) = label_value(rows[r][c], path, r + 1, h[c]);
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
    check_file_name(rows[r][a], fmt::format("{}:{}", path.string(), r + 1), "scan id");
    out.push_back({rows[r][a], rows[r][b], rows[r][c]});
  }
  return out;
}

fs::path find_registered_mesh(const fs::path& dir, const std::string& stem) {
  for (const char* ext : {".ply", ".obj", ".off"}) {
    fs::path p = dir / (stem + ext);
    std::error_code ec;
    if (fs::is_regular_file(p, ec)) return p;
  }
  return {};
}

std::vector<MeshTableRow> read_mesh_table(const fs::path& path) {
  auto rows = read_csv(path);
  const int a = column(rows[0], "mesh", path), b = column(rows[0], "subject", path),
            c = column(rows[0], "pose", path);
  std::vector<MeshTableRow> out;
  std::set<std::string> seen;
  for (size_t r = 1; r < rows.size(); ++r) {
    MeshTableRow row{rows[r][a], rows[r][b], rows[r][c]};
    if (row.mesh.empty() || row.subject.empty())
      throw InputError(fmt::format("'{}' line {}: empty mesh or subject", path.string(), r + 1));
    if (row.mesh.find('/') != std::string::npos || row.mesh.find('\\') != std::string::npos)
      throw InputError(fmt::format("'{}' line {}: mesh '{}' must be a file stem, not a path", path.string(), r + 1,
                                   row.mesh));
    if (!seen.insert(row.mesh).second)
      throw InputError(fmt::format("'{}' line {}: mesh '{}' is listed twice", path.string(), r + 1, row.mesh));
    out.push_back(std::move(row));
  }
  if (out.empty()) throw InputError(fmt::format("'{}' lists no meshes (only a header)", path.string()));
  return out;
}

// The labels the subjects table gives (sex and every numeric column but mesh, subject and pose),
// one value vector per subject; a subject listed twice must not contradict itself.
struct GivenLabels {
  std::vector<LabelInfo> labels;
  std::vector<std::string> names;
  std::vector<std::string> subject_order;
  std::map<std::string, Eigen::VectorXd> subject_values;
};

GivenLabels given_labels(const fs::path& csv, const std::vector<MeshTableRow>& table) {
  GivenLabels G;
  std::vector<std::string>& given = G.names;
  std::vector<std::string>& subject_order = G.subject_order;
  std::map<std::string, Eigen::VectorXd>& subject_values = G.subject_values;
  // Label columns (everything but mesh, subject, pose).
  auto rows = read_csv(csv);
  const auto& h = rows[0];
  std::vector<int> label_cols;
  int sex_col = -1;
  for (size_t c = 0; c < h.size(); ++c) {
    if (h[c] == "mesh" || h[c] == "subject" || h[c] == "pose") continue;
    if (h[c] == "sex") {
      sex_col = static_cast<int>(c);
      continue;
    }
    bool numeric = true;
    double v;
    for (size_t r = 1; r < rows.size() && numeric; ++r)
      if (!rows[r][c].empty() && !parse_double(rows[r][c], v)) numeric = false;
    if (numeric) label_cols.push_back(static_cast<int>(c));
  }
  if (sex_col >= 0) {
    G.labels.push_back({"sex", ""});
    given.push_back("sex");
  }
  for (int c : label_cols) {
    G.labels.push_back({h[c], unit_of(h[c])});
    given.push_back(h[c]);
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::map<std::string, size_t> subject_line;
  for (size_t r = 1; r < rows.size(); ++r) {
    const std::string& subj = table[r - 1].subject;
    Eigen::VectorXd v = Eigen::VectorXd::Constant(given.size(), nan);
    int k = 0;
    if (sex_col >= 0) {
      const std::string& s = rows[r][sex_col];
      if (s == "female" || s == "f" || s == "F")
        v(k) = 0;
      else if (s == "male" || s == "m" || s == "M")
        v(k) = 1;
      else if (!s.empty())
        throw InputError(fmt::format("'{}' line {}: sex must be female or male, got '{}'", csv.string(), r + 1, s));
      ++k;
    }
    for (int c : label_cols) v(k++) = label_value(rows[r][c], csv, r + 1, h[c]);
    auto it = subject_values.find(subj);
    if (it == subject_values.end()) {
      subject_values[subj] = v;
      subject_line[subj] = r + 1;
      subject_order.push_back(subj);
    } else {
      for (Eigen::Index j = 0; j < v.size(); ++j) {
        const double a = it->second(j), b = v(j);
        if (std::isnan(a) && !std::isnan(b)) it->second(j) = b;
        else if (!std::isnan(a) && !std::isnan(b) && a != b)
          throw InputError(fmt::format("'{}' line {}: subject '{}' has {} = {}, but {} on line {}", csv.string(), r + 1,
                                       subj, given[j], b, a, subject_line[subj]));
      }
    }
  }
  return G;
}

// Labels that do not vary between subjects (or are known for fewer than two) carry nothing a
// regression can use: dropped (one person in many poses has none). Returns their names.
std::vector<std::string> drop_constant_labels(ModelBuildInput& in, const std::map<std::string, int>& standard) {
  const Eigen::Index n = in.subject_label_values.rows();
  std::vector<std::string> dropped;
  std::vector<int> keep;
  for (int j = 0; j < static_cast<int>(in.subject_labels.size()); ++j) {
    std::set<double> distinct;
    for (const auto& [subj, i] : standard)
      if (std::isfinite(in.subject_label_values(i, j))) distinct.insert(in.subject_label_values(i, j));
    if (distinct.size() >= 2) keep.push_back(j);
    else dropped.push_back(in.subject_labels[j].name);
  }
  std::vector<LabelInfo> labels;
  Eigen::MatrixXd values(n, keep.size());
  for (size_t q = 0; q < keep.size(); ++q) {
    labels.push_back(in.subject_labels[keep[q]]);
    values.col(q) = in.subject_label_values.col(keep[q]);
  }
  in.subject_labels = std::move(labels);
  in.subject_label_values = std::move(values);
  return dropped;
}

ModelBuildInput read_registered_folder(const fs::path& reg, const fs::path& csv, const RegisteredFolderOptions& o,
                                       RegisteredFolderSummary* summary, const ProgressCallback& progress) {
  if (!fs::is_directory(reg)) throw InputError(fmt::format("'{}' is not a folder of registered meshes", reg.string()));
  if (!(o.mm_per_unit > 0) || !std::isfinite(o.mm_per_unit))
    throw InputError(fmt::format("millimetres per unit must be positive, got {}", o.mm_per_unit));
  if (o.up_axis < 0 || o.up_axis > 2) throw InputError(fmt::format("up axis must be 0, 1 or 2, got {}", o.up_axis));
  const auto table = read_mesh_table(csv);
  // Every listed mesh must exist: report them all at once.
  std::vector<fs::path> paths;
  std::vector<std::string> missing;
  for (const auto& r : table) {
    paths.push_back(find_registered_mesh(reg, r.mesh));
    if (paths.back().empty()) missing.push_back(r.mesh);
  }
  if (!missing.empty()) {
    std::string names;
    for (size_t i = 0; i < std::min<size_t>(3, missing.size()); ++i) names += (i ? ", " : "") + missing[i];
    throw InputError(fmt::format("'{}' names {} mesh(es) that '{}' does not have as .ply/.obj/.off ({}{})",
                                 csv.string(), missing.size(), reg.string(), names, missing.size() > 3 ? ", ..." : ""));
  }
  GivenLabels G = given_labels(csv, table);
  ModelBuildInput in;
  in.subject_labels = G.labels;
  const std::vector<std::string>& given = G.names;
  const std::vector<std::string>& subject_order = G.subject_order;
  std::map<std::string, Eigen::VectorXd>& subject_values = G.subject_values;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // Meshes.
  RegisteredFolderSummary sum;
  const size_t n = table.size();
  for (size_t i = 0; i < n; ++i) {
    report_progress(progress, 0.9 * static_cast<double>(i) / static_cast<double>(n), table[i].mesh);
    Mesh m = read_mesh(paths[i]);
    if (in.meshes.empty()) {
      in.F = m.F;
    } else if (o.use_first_mesh_faces) {
      if (m.V.rows() != in.meshes[0].rows())
        throw InputError(fmt::format("'{}': {} vertices, '{}' has {}: registered meshes must have the same vertices",
                                     paths[i].string(), m.V.rows(), paths[0].string(), in.meshes[0].rows()));
      if (m.F.rows() != in.F.rows() || m.F != in.F) ++sum.meshes_with_other_faces;
    } else if (m.V.rows() != in.meshes[0].rows() || m.F.rows() != in.F.rows() || m.F != in.F) {
      throw InputError(fmt::format("'{}': {} vertices / {} triangles with different faces than '{}' "
                                   "({} / {}): registered meshes must share one topology (or, if only the "
                                   "triangulation differs, use the first mesh's faces)",
                                   paths[i].string(), m.V.rows(), m.F.rows(), paths[0].string(),
                                   in.meshes[0].rows(), in.F.rows()));
    }
    in.meshes.push_back(m.V * o.mm_per_unit);
    in.scan_ids.push_back(table[i].mesh);
    in.subject_ids.push_back(table[i].subject);
  }
  // Standard-pose mesh per subject.
  std::map<std::string, int> standard;
  for (size_t i = 0; i < n; ++i)
    if (table[i].pose == o.standard_pose && !standard.count(table[i].subject)) standard[table[i].subject] = static_cast<int>(i);
  for (const auto& subj : subject_order)
    if (!standard.count(subj)) {
      for (size_t i = 0; i < n; ++i)
        if (table[i].subject == subj) {
          standard[subj] = static_cast<int>(i);
          break;
        }
      ++sum.subjects_without_standard_pose;
    }
  in.is_standard_pose.assign(n, 0);
  for (const auto& [subj, i] : standard) in.is_standard_pose[i] = 1;
  // Measured labels on the standard-pose meshes.
  std::vector<std::string> measured;
  if (o.measure_labels)
    for (const char* name : {"height_cm", "weight_kg", "volume_l", "chest_cm", "waist_cm", "hips_cm", "neck_cm"})
      if (std::find(given.begin(), given.end(), name) == given.end()) measured.push_back(name);
  std::map<std::string, Eigen::VectorXd> measured_values;
  for (const auto& subj : subject_order) {
    Eigen::VectorXd v = Eigen::VectorXd::Constant(measured.size(), nan);
    if (!measured.empty()) {
      const int i = standard[subj];
      report_progress(progress, 0.9 + 0.1 * static_cast<double>(measured_values.size()) / subject_order.size(),
                      "measuring " + table[i].mesh);
      MeasureOptions mo;
      mo.up_axis = o.up_axis;
      mo.density_kg_per_l = o.density_kg_per_l;
      try {
        const BodyMeasurements b = measure_body(in.meshes[i], in.F, Sex::unknown, mo);
        const double all[] = {b.height_cm, b.weight_kg, b.volume_l, b.chest_cm, b.waist_cm, b.hips_cm, b.neck_cm};
        const char* names[] = {"height_cm", "weight_kg", "volume_l", "chest_cm", "waist_cm", "hips_cm", "neck_cm"};
        for (size_t j = 0; j < measured.size(); ++j)
          for (int q = 0; q < 7; ++q)
            if (measured[j] == names[q]) v(j) = all[q] > 0 ? all[q] : nan;
      } catch (const InputError& e) {
        if (sum.measurement_failures++ == 0) sum.first_measurement_failure = table[i].mesh + ": " + e.what();
      }
    }
    measured_values[subj] = v;
  }
  for (const auto& name : measured) in.subject_labels.push_back({name, unit_of(name)});
  in.subject_label_values.resize(n, in.subject_labels.size());
  for (size_t i = 0; i < n; ++i) {
    const auto& subj = table[i].subject;
    Eigen::VectorXd row(in.subject_labels.size());
    row << subject_values[subj], measured_values[subj];
    in.subject_label_values.row(i) = row.transpose();
  }
  sum.dropped_labels = drop_constant_labels(in, standard);
  in.pose_label_values.resize(n, 0);
  sum.meshes = static_cast<int>(n);
  sum.subjects = static_cast<int>(subject_order.size());
  sum.measured_labels = measured;
  report_progress(progress, 1.0, "read");
  if (summary) *summary = sum;
  return in;
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
