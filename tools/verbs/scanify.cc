// bodymodel scanify MESH... --out scan.ply|DB/ [--scanner pillars] [--noise-mm 1] [--holes on]
//                          [--seed S] [--scale 1000] [--up x] [--landmarks LM.json]
//
// Runs the synthetic database's scanner simulation (tools/synth/scanify.h) on any mesh, so real
// bodies (FAUST, SCAPE) can be registered the way scans are. One mesh and an --out ending in
// .ply: that scan (and <out stem>.landmarks.json with --landmarks). Otherwise --out is a scan
// database folder for `bodymodel register`: scans.csv, scans/<stem>.ply and
// scans/<stem>.landmarks.json (empty {} without --landmarks). A database that exists is added
// to: its scans.csv keeps its rows and gains the new ones; a scan id it already lists (or a
// scan file it does not list) is refused unless --force, which replaces that scan.
#include <fmt/format.h>

#include <atomic>
#include <filesystem>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <regex>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/file_names.h"
#include "core/io/json_text.h"
#include "core/io/mesh_io.h"
#include "core/landmarks.h"
#include "core/up_axis.h"
#include "registration/mesh_scan.h"
#include "tools/console.h"
#include "tools/synth/scanify.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

constexpr double kMaxNoiseMm = 100;  // σ per coordinate; a body scanner's is about 1 mm
constexpr int kMaxPoints = 10'000'000;  // per mesh: points, normals and their index must fit in memory

struct ScanifyArgs {
  std::vector<std::string> meshes;
  std::string out, scanner = "pillars", holes = "on", up = "y", landmarks, subject_regex;
  double noise_mm = 1.0, scale = 1.0, landmark_noise_mm = 0.0;
  unsigned seed = 1;
  int points = ScannerOptions{}.min_points, jobs = 1;
  bool force = false;
};

// The scans.csv of a database scanify adds to (header and rows, by scan id).
struct ExistingScans {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::map<std::string, size_t> row_of;  // scan id → row
  std::vector<int> lines;                 // per row, its line in scans.csv
};

// Reads `db`/scans.csv when `db` exists; refuses a folder that holds files but no scans.csv
// (not a scan database, or one whose table was lost) unless `force`.
ExistingScans existing_scans(const fs::path& db, bool force) {
  ExistingScans e;
  std::error_code ec;
  if (!fs::exists(db, ec)) return e;
  if (!fs::is_directory(db, ec)) throw InputError("--out '" + db.string() + "' exists and is not a folder");
  const fs::path csv = db / "scans.csv";
  if (!fs::exists(csv, ec)) {
    if (!force && fs::directory_iterator(db, ec) != fs::directory_iterator())
      throw InputError("--out '" + db.string() +
                       "' holds files but no scans.csv: not a scan database to add to (use --force to add to it "
                       "anyway, or another folder)");
    return e;
  }
  const std::vector<CsvRecord> records = read_csv_file(csv);
  if (records.empty() || records[0].fields.empty() || records[0].fields[0] != "scan_id")
    throw InputError("'" + csv.string() + "': expected a header starting with 'scan_id' (a scan database's table)");
  e.header = records[0].fields;
  for (size_t r = 1; r < records.size(); ++r) {
    std::vector<std::string> row = records[r].fields;
    if (row.size() != e.header.size())
      throw InputError(fmt::format("'{}' line {}: {} fields, the header has {}", csv.string(), records[r].line,
                                   row.size(), e.header.size()));
    e.row_of[row[0]] = e.rows.size();
    e.rows.push_back(std::move(row));
    e.lines.push_back(records[r].line);
  }
  return e;
}

}  // namespace

namespace {

void add_scanify_options(CLI::App* cmd, ScanifyArgs& a) {
  cmd->add_option("meshes", a.meshes, "Meshes (OBJ/PLY/OFF)")->required();
  cmd->add_option("--out", a.out, "Output scan (.ply, one mesh) or scan database folder")
      ->required();
  cmd->add_option("--scanner", a.scanner,
                  "Scanner model: 'pillars' (four vertical pillars around the subject, as a body "
                  "scanner; the synthetic database's)")
      ->check(CLI::IsMember({"pillars"}))
      ->capture_default_str();
  cmd->add_option("--noise-mm", a.noise_mm, "Gaussian noise per coordinate (mm, σ)")
      ->capture_default_str();
  cmd->add_option("--holes", a.holes,
                  "'on': only what a pillar sees (holes under the arms, between the legs, on top "
                  "of the head); 'off': the whole surface")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  cmd->add_option("--seed", a.seed, "Random seed (each mesh's own seed mixes it with its name)")
      ->capture_default_str();
  cmd->add_option("--points", a.points, "Scan points per mesh (at least)")->capture_default_str();
  cmd->add_option("--scale", a.scale, "Millimetres per mesh unit (1000 for metres)")
      ->capture_default_str();
  cmd->add_option("--up", a.up,
                  "Axis the body stands along in the mesh (x, y, z, -x, -y, -z); rotated onto "
                  "+y (SCAPE: x)")
      ->capture_default_str();
  cmd->add_option("--landmarks", a.landmarks,
                  "JSON {name: vertex index (0-based, of the mesh) or [x, y, z]}, placed once and "
                  "reused for every mesh of the topology (registration/landmarks/faust.json)");
  cmd->add_option("--landmark-noise-mm", a.landmark_noise_mm,
                  "Gaussian noise added to each landmark position (mm, σ per coordinate)")
      ->capture_default_str();
  cmd->add_option("--subject-regex", a.subject_regex,
                  "Regular expression on a mesh's stem whose first group is the subject id "
                  "written to scans.csv (default: the stem)");
  cmd->add_option("--jobs", a.jobs, "Meshes scanned in parallel")->capture_default_str();
  cmd->add_flag("--force", a.force,
                "Replace scans of the same id already in the --out database (and add to a folder without "
                "scans.csv)");
}

// Adding to a database: every clash is found before anything is scanned or written.
ExistingScans check_database_clashes(const ScanifyArgs& a, const fs::path& out, const std::vector<std::string>& stems) {
  ExistingScans existing = existing_scans(out, a.force);
  for (size_t k = 0; k < stems.size() && !a.force; ++k) {
    const auto it = existing.row_of.find(stems[k]);
    std::error_code ec;
    if (it != existing.row_of.end())
      throw InputError(fmt::format("'{}': scan id '{}' is already in '{}' (line {}); use --force to replace it, "
                                   "or another --out",
                                   a.meshes[k], stems[k], (out / "scans.csv").string(),
                                   existing.lines[it->second]));
    if (fs::exists(out / "scans" / (stems[k] + ".ply"), ec))
      throw InputError(fmt::format("'{}': '{}' exists but scans.csv does not list it (left by an interrupted "
                                   "run?); use --force to replace it, or another --out",
                                   a.meshes[k], (out / "scans" / (stems[k] + ".ply")).string()));
  }
  return existing;
}

// scans.csv: the earlier rows first (a replaced scan keeps its place), then the new ones; columns
// by name, so a synth-db table (no source column) gains one.
std::string merged_scan_table(const ExistingScans& existing, const std::vector<std::vector<std::string>>& rows,
                              const std::vector<std::string>& stems) {
  // The earlier rows first (a replaced scan keeps its place), then the new ones; columns by
  // name, so a synth-db table (no source column) gains one.
  std::vector<std::string> header = existing.header;
  const std::vector<std::string> ours = {"scan_id", "subject_id", "pose", "points", "source"};
  for (const auto& c : ours)
    if (std::find(header.begin(), header.end(), c) == header.end()) header.push_back(c);
  std::vector<std::vector<std::string>> table = existing.rows;
  for (auto& r : table) r.resize(header.size());
  for (size_t k = 0; k < rows.size(); ++k) {
    if (rows[k].empty()) continue;  // failed
    const std::vector<std::string>& cells = rows[k];
    std::vector<std::string> row(header.size());
    for (size_t c = 0; c < ours.size(); ++c)
      row[std::find(header.begin(), header.end(), ours[c]) - header.begin()] = cells[c];
    const auto it = existing.row_of.find(stems[k]);
    if (it != existing.row_of.end()) table[it->second] = std::move(row);
    else table.push_back(std::move(row));
  }
  std::string csv = csv_row(header) + "\n";
  for (const auto& r : table) csv += csv_row(r) + "\n";
  return csv;
}

// The scan id (file stem) and subject of every mesh, all checked before anything is written: a
// stem the pattern missed used to fail after the other scans were written.
void scan_ids(const ScanifyArgs& a, bool single, const std::regex& subject_re, std::vector<std::string>& stems,
              std::vector<std::string>& subjects) {
  for (const auto& m : a.meshes) {
    if (!fs::is_regular_file(m))
      throw InputError("'" + m + "': expected a mesh file (OBJ/PLY/OFF), it does not exist");
    const std::string stem = fs::path(m).stem().string();
    // The stem is the database's scan id, which `register` takes for a plain file name (and
    // writes into JSON and CSV): refused here, naming the mesh, rather than there.
    if (!single) check_file_name(stem, "'" + m + "'", "scan id (the file's stem)");
    if (std::find(stems.begin(), stems.end(), stem) != stems.end())
      throw InputError("'" + m + "': two meshes share the name '" + stem + "'");
    stems.push_back(stem);
    // Every subject id before anything is written: a stem the pattern misses used to fail
    // after the other scans were written, leaving a database without its scans.csv.
    std::smatch match;
    if (!a.subject_regex.empty() && (!std::regex_search(stem, match, subject_re) || match.size() < 2))
      throw InputError("--subject-regex '" + a.subject_regex + "' does not match '" + stem +
                       "' with a capture group ('" + m + "'); nothing written");
    subjects.push_back(a.subject_regex.empty() ? stem : match[1].str());
  }
}

void run_scanify(ScanifyArgs& a) {
  // Bounded above too: noise far beyond a body's size makes a cloud no reader takes back, and
  // a point count beyond memory ended in a bare std::bad_alloc.
  if (!(a.noise_mm >= 0 && a.noise_mm <= kMaxNoiseMm))
    throw InputError(fmt::format("--noise-mm must be 0 … {} mm, got {}", kMaxNoiseMm, a.noise_mm));
  if (!(a.landmark_noise_mm >= 0 && a.landmark_noise_mm <= kMaxNoiseMm))
    throw InputError(fmt::format("--landmark-noise-mm must be 0 … {} mm, got {}", kMaxNoiseMm, a.landmark_noise_mm));
  if (!(a.scale > 0) || !std::isfinite(a.scale))
    throw InputError("--scale must be a positive number of millimetres per mesh unit");
  if (a.points < 100 || a.points > kMaxPoints)
    throw InputError(fmt::format("--points must be 100 … {}, got {}", kMaxPoints, a.points));
  if (a.jobs < 1) throw InputError("--jobs must be at least 1");
  const Eigen::Matrix3d up = up_axis_rotation(a.up, "--up");
  std::regex subject_re;
  if (!a.subject_regex.empty()) {
    try {
      subject_re = std::regex(a.subject_regex);
    } catch (const std::regex_error& e) {
      throw InputError("--subject-regex '" + a.subject_regex + "': " + e.what());
    }
  }
  std::string ext = fs::path(a.out).extension().string();
  for (auto& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  const bool single = ext == ".ply";
  if (single && a.meshes.size() != 1)
    throw InputError("--out '" + a.out + "' is one scan file, but " +
                     std::to_string(a.meshes.size()) +
                     " meshes were given: give a folder to make a scan database");
  std::vector<std::string> stems, subjects;
  scan_ids(a, single, subject_re, stems, subjects);
  if (!a.landmarks.empty() && !fs::is_regular_file(a.landmarks))
    throw InputError("--landmarks '" + a.landmarks + "': file not found");
  const fs::path out = a.out;
  // Adding to a database: every clash is found before anything is scanned or written.
  ExistingScans existing;
  if (!single) {
    existing = check_database_clashes(a, out, stems);
    ensure_directory(out / "scans");
  }

  ScanifyOptions options;
  options.scanner.noise_sigma_mm = a.noise_mm;
  options.scanner.min_points = a.points;
  options.holes = a.holes == "on";
  options.mm_per_unit = a.scale;
  cli::ProgressBar bar(fmt::format("scanify {} meshes", a.meshes.size()));
  std::mutex mutex;
  std::atomic<int> done{0};
  std::vector<std::vector<std::string>> rows(a.meshes.size());  // scans.csv cells; empty: failed
  std::vector<std::string> failures;
  tbb::task_arena arena(a.jobs);
  arena.execute([&] {
    tbb::parallel_for(size_t(0), a.meshes.size(), size_t(1), [&](size_t k) {
      const std::string& path = a.meshes[k];
      const std::string& stem = stems[k];
      try {
        Mesh mesh = read_mesh(path);
        // Landmarks from the mesh's own vertices (or positions in its unit), then the frame.
        std::vector<Landmark> landmarks;
        if (!a.landmarks.empty())
          landmarks = read_mesh_landmarks(a.landmarks, registration_landmarks(), mesh.V);
        mesh.V = to_project_frame(mesh.V, a.scale, up);
        ScanifyOptions o = options;
        o.seed = scan_seed(a.seed, stem);
        const PointCloud scan = scanify_mesh(mesh, o, path);
        nlohmann::ordered_json lm = nlohmann::ordered_json::object();
        std::mt19937_64 rng(scan_seed(a.seed + 1, stem));
        std::normal_distribution<double> ln(0.0, a.landmark_noise_mm);
        for (const auto& l : landmarks) {
          Eigen::Vector3d p = a.scale * (up * l.target);
          if (a.landmark_noise_mm > 0) p += Eigen::Vector3d(ln(rng), ln(rng), ln(rng));
          lm[l.name] = {p.x(), p.y(), p.z()};
        }
        const fs::path scan_path = single ? out : out / "scans" / (stem + ".ply");
        const fs::path lm_path = scan_path.parent_path() / (scan_path.stem().string() + ".landmarks.json");
        write_point_cloud(scan_path, scan);
        if (!single || !landmarks.empty()) write_text_file(lm_path, json_text(lm, 1) + "\n");
        rows[k] = {stem, subjects[k], stem, std::to_string(scan.P.rows()), path};
        std::lock_guard<std::mutex> lock(mutex);
        bar.update(double(++done) / double(a.meshes.size()), stem);
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> lock(mutex);
        failures.push_back(std::string(e.what()));
      }
    });
  });
  bar.finish(fmt::format("{} scanned, {} failed", done.load(), failures.size()));
  if (!single) write_text_file(out / "scans.csv", merged_scan_table(existing, rows, stems));
  if (!failures.empty())
    throw InputError(fmt::format("{} of {} meshes failed; first: {}", failures.size(),
                                 a.meshes.size(), failures.front()));
}

}  // namespace

BODYMODEL_VERB(add_scanify_verb) {
  auto a = std::make_shared<ScanifyArgs>();
  auto* cmd = app.add_subcommand(
      "scanify",
      "Scan-like input from any mesh: the synthetic database's scanner simulation (four\n"
      "pillars; holes where no pillar sees the surface; Gaussian noise; normals estimated from\n"
      "the noisy points) run on each mesh, in millimetres with +y up.\n"
      "One mesh and --out X.ply: that scan (and X.landmarks.json with --landmarks). Otherwise\n"
      "--out is a scan database for `bodymodel register`: OUT/scans.csv, OUT/scans/<stem>.ply,\n"
      "OUT/scans/<stem>.landmarks.json (landmark positions from vertex indices of the mesh).\n"
      "An existing database is added to: scans.csv keeps its scans and gains the new ones; a scan\n"
      "id it already has (or an unlisted scan file of that name) is refused unless --force.\n"
      "Example (FAUST, in metres):\n"
      "  bodymodel scanify faust/*.off --scale 1000 --landmarks registration/landmarks/faust.json "
      "--out faust-scans/");
  add_scanify_options(cmd, *a);
  cmd->callback([a] { run_scanify(*a); });
}

}  // namespace bodymodel
