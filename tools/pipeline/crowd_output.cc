#include "tools/pipeline/crowd_output.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/geometry.h"
#include "core/io/csv.h"
#include "core/io/mesh_io.h"
#include "core/plausibility.h"
#include "tools/pipeline/folder_settings.h"

namespace bodymodel {

namespace fs = std::filesystem;

namespace {

constexpr const char* kLabelsHeader =
    "body,file,sex,height_cm,weight_kg,volume_l,waist_cm,hips_cm,chest_cm,neck_cm,body_fat_pct,"
    "constraints_met,iterations,attempts,flipped_triangles,flipped_before_repair,waist_iliac_cm,"
    "arm_circumference_cm,roughness_p95_deg,roughness_max_deg,self_intersections";
constexpr int kColumnMet = 11, kColumnFlipped = 14, kColumnBeforeRepair = 15, kColumnRoughness = 18,
              kColumnSelfIntersections = 20;

// The header of labels.csv: the base columns, then a population crowd's person columns.
std::string labels_header(const CrowdOutputOptions& o) {
  std::string h = kLabelsHeader;
  if (!o.people.empty()) {
    h += ",seqn";
    for (const auto& n : o.recorded_names) h += ",nhanes_" + n;
  }
  return h;
}

int column_count(const std::string& header) { return static_cast<int>(std::count(header.begin(), header.end(), ',')) + 1; }

std::string sex_name(const std::vector<LabelCondition>& conditions) {
  for (auto& c : conditions)
    if (c.label == "sex" && !c.keep) return c.lo < 0.5 ? "female" : "male";
  return "";
}

// A population crowd's people (file and every person's id and conditions), null otherwise.
nlohmann::json population_json(const CrowdOutputOptions& o) {
  if (o.people.empty()) return nullptr;
  nlohmann::json people = nlohmann::json::array();
  for (const auto& p : o.people) {
    nlohmann::json cond = nlohmann::json::array();
    for (auto& c : p.conditions) cond.push_back({c.label, c.lo, c.hi});
    people.push_back({{"id", p.id}, {"conditions", cond}});
  }
  return {{"file", o.population_source}, {"people", people}};
}

nlohmann::json settings_json(const std::string& fingerprint, const std::vector<LabelCondition>& conditions,
                             const CrowdOutputOptions& o) {
  nlohmann::json cond = nlohmann::json::array();
  for (auto& c : conditions) cond.push_back({{"label", c.label}, {"lo", c.lo}, {"hi", c.hi}, {"keep", c.keep}});
  const GenerateOptions& g = o.crowd.generate;
  return {{"generator_version", kCrowdGeneratorVersion},
          {"model", fingerprint},
          {"seed", o.crowd.seed},
          {"conditions", cond},
          {"spread", g.spread},
          {"max_attempts", g.max_attempts},
          {"measure_girths", g.measure_girths},
          {"repair_folds", g.repair_folds},
          {"fold_repair", {g.fold_repair.rings, g.fold_repair.passes, g.fold_repair.local_similarity,
                           g.fold_repair.keep_only_improving, g.fold_repair.max_region_vertices}},
          {"max_iterations", g.morph.max_iterations},
          {"tolerance_cm", g.morph.tolerance_cm},
          {"tolerance_kg", g.morph.tolerance_kg},
          {"tolerance_other", g.morph.tolerance_other},
          {"range_margin", g.morph.range_margin},
          {"format", o.format},
          {"population", population_json(o)}};
}

// Rows of an earlier labels.csv by body index (empty when missing or of another layout).
std::vector<std::optional<std::string>> read_previous_rows(const fs::path& csv, int count, const std::string& header) {
  std::vector<std::optional<std::string>> rows(count);
  std::error_code ec;
  if (!fs::is_regular_file(csv, ec)) return rows;
  std::vector<CsvRecord> records;
  try {
    records = read_csv_file(csv);
  } catch (const InputError&) {
    return rows;  // a table cut mid-row by a kill: its bodies are made again
  }
  if (records.empty() || csv_row(records[0].fields) != header) return rows;
  for (size_t r = 1; r < records.size(); ++r) {
    const auto& cells = records[r].fields;
    if (static_cast<int>(cells.size()) != column_count(header)) continue;
    char* end = nullptr;
    long i = std::strtol(cells[0].c_str(), &end, 10);
    if (!end || *end != '\0' || i < 0 || i >= count) continue;
    rows[i] = csv_row(cells);  // as written: every cell through csv_field
  }
  return rows;
}

std::string labels_csv(const std::vector<std::optional<std::string>>& rows, const std::string& header) {
  std::string csv = header + "\n";
  for (auto& r : rows)
    if (r) csv += *r + "\n";
  return csv;
}

}  // namespace

GenerateCrowdSummary write_crowd(std::shared_ptr<const BodyModel> model,
                                 const std::vector<LabelCondition>& conditions, int count,
                                 const fs::path& out, const CrowdOutputOptions& o,
                                 const ProgressCallback& progress) {
  if (count < 1) throw InputError(fmt::format("generate: --count must be at least 1, got {}", count));
  if (o.format != "obj" && o.format != "ply")
    throw InputError(fmt::format("generate: mesh format '{}' (expected obj or ply)", o.format));
  if (o.crowd.threads < 0) throw InputError(fmt::format("generate: {} threads", o.crowd.threads));
  if (!(std::isfinite(o.crowd.generate.spread) && o.crowd.generate.spread >= 0))
    throw InputError(fmt::format("generate: --spread must be a finite number ≥ 0, got {}", o.crowd.generate.spread));
  if (o.crowd.generate.max_attempts < 1)
    throw InputError(fmt::format("generate: {} attempts per body, expected at least 1", o.crowd.generate.max_attempts));
  const fs::path csv_path = out / "labels.csv";
  if (!o.people.empty() && static_cast<int>(o.people.size()) != count)
    throw InputError(fmt::format("generate: {} people for {} bodies", o.people.size(), count));
  const std::string header = labels_header(o);
  // The settings record of tools/pipeline/folder_settings.h: the same settings resume, others are
  // refused unless force (every body is then made again). Checked before anything is written.
  ResumableFolder folder(out, "generate.json", settings_json(model_fingerprint(*model), conditions, o), o.force,
                         [](const std::string& n) {
                           return n == "labels.csv" ||
                                  (n.rfind("body_", 0) == 0 && n.size() > 4 &&
                                   (n.substr(n.size() - 4) == ".obj" || n.substr(n.size() - 4) == ".ply"));
                         });
  const bool resume = folder.open(o.resume);
  std::vector<std::optional<std::string>> rows(count);
  if (resume) rows = read_previous_rows(csv_path, count, header);

  GenerateCrowdSummary summary;
  summary.count = count;
  for (int i = 0; i < count; ++i) summary.files.push_back(fmt::format("body_{:03d}.{}", i, o.format));
  std::vector<int> todo;
  std::error_code ec;
  for (int i = 0; i < count; ++i) {
    if (rows[i] && split_csv_line(*rows[i])[1] == summary.files[i] && fs::is_regular_file(out / summary.files[i], ec))
      continue;
    rows[i].reset();
    todo.push_back(i);
  }
  summary.skipped = count - static_cast<int>(todo.size());
  summary.generated = static_cast<int>(todo.size());

  const std::string sex = sex_name(conditions);
  std::mutex mutex;  // guards `rows` and the flushes of labels.csv
  auto last_flush = std::chrono::steady_clock::now();
  const auto t0 = last_flush;
  report_progress(progress, 0, fmt::format("{} bodies to generate, {} already there", todo.size(), summary.skipped));
  const Eigen::MatrixX2i edges = unique_edges(model->tmpl->faces());  // one topology: sorted once
  // Each body is written as soon as it is made (on its worker thread), so memory does not grow
  // with the crowd.
  auto write_body = [&](CrowdBody&& b) {
    const int i = b.index;
    const GeneratedBody& g = b.body;
    const int flipped = b.flipped_triangles;
    write_mesh(out / summary.files[i], g.V, model->tmpl->faces());
    const BodyMeasurements& m = g.measured;
    auto num = [](double v) { return std::isfinite(v) ? fmt::format("{:.2f}", v) : std::string(); };
    const Roughness rough = roughness(g.V, model->tmpl->faces(), o.roughness_region, edges);
    const int crossing = self_intersecting_triangle_pairs(g.V, model->tmpl->faces());
    std::string row = fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}", i,
                                  csv_field(summary.files[i]),
                                  o.people.empty() ? sex : o.people[i].sex, num(m.height_cm), num(m.weight_kg),
                                  num(m.volume_l), num(m.waist_cm), num(m.hips_cm), num(m.chest_cm), num(m.neck_cm),
                                  num(m.body_fat_pct), g.satisfied ? 1 : 0, g.summary.iterations, g.attempts, flipped,
                                  o.crowd.generate.repair_folds ? g.folds.flipped_before : flipped,
                                  num(m.waist_iliac_cm), num(m.arm_circumference_cm), num(rough.p95_deg),
                                  num(rough.max_deg), crossing);
    if (!o.people.empty()) {
      row += "," + csv_field(o.people[i].id);
      for (double v : o.people[i].recorded) row += "," + (std::isfinite(v) ? fmt::format("{:.1f}", v) : std::string());
    }
    std::lock_guard<std::mutex> lock(mutex);
    rows[i] = std::move(row);
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - last_flush).count() >= o.labels_flush_seconds) {
      write_text_file(csv_path, labels_csv(rows, header));
      last_flush = now;
    }
  };
  if (o.people.empty())
    generate_crowd_bodies(model, conditions, todo, o.crowd, write_body, progress);
  else
    generate_crowd_bodies_for(
        model, [&](int k) { return o.people[k].conditions; }, todo, o.crowd, write_body, progress);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  write_text_file(csv_path, labels_csv(rows, header));
  for (auto& r : rows) {
    auto cells = split_csv_line(*r);
    summary.constraints_met += cells[kColumnMet] == "1" ? 1 : 0;
    const int flipped = std::atoi(cells[kColumnFlipped].c_str());
    summary.flipped_triangles += flipped;
    summary.max_flipped_triangles = std::max(summary.max_flipped_triangles, flipped);
    summary.flipped_before_repair.push_back(std::atoi(cells[kColumnBeforeRepair].c_str()));
    summary.self_intersections.push_back(std::atoi(cells[kColumnSelfIntersections].c_str()));
    summary.roughness_p95.push_back(std::atof(cells[kColumnRoughness].c_str()));
  }
  return summary;
}

}  // namespace bodymodel
