#include "tools/synth/synthetic_scans.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <signal.h>
#include <unistd.h>

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <atomic>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "core/random_subject.h"
#include "core/error.h"
#include "core/geometry.h"
#include "core/io/atomic_write.h"
#include "tools/pipeline/folder_settings.h"
#include "core/io/bvh.h"
#include "core/io/csv.h"
#include "core/io/interrupt_cleanup.h"
#include "core/io/json_text.h"
#include "core/io/mesh_io.h"
#include "core/landmarks.h"
#include "core/measure.h"
#include "core/point_index.h"
#include "core/retarget.h"
#include "population/ansur_fit.h"
#include "population/people.h"
#include "core/rotation.h"

namespace bodymodel {

namespace fs = std::filesystem;

namespace {

// Depth buffer of one pillar: columns = horizontal angle seen from the pillar, rows = height.
struct PillarView {
  Eigen::Vector2d position;   // (x, z) of the pillar
  Eigen::Vector2d forward;    // unit (x, z) direction from the pillar to the subject's axis
  double y0 = 0, row_mm = 1, col_rad = 1, max_angle = 1;
  int rows = 0, cols = 0;
  std::vector<float> depth;   // rows × cols, +inf where nothing is seen

  // (column, row, depth) of a 3-D point.
  Eigen::Vector3d project(const Eigen::Vector3d& p) const {
    Eigen::Vector2d d(p.x() - position.x(), p.z() - position.y());
    double along = d.dot(forward);
    double across = forward.x() * d.y() - forward.y() * d.x();
    double angle = std::atan2(across, along);
    return {(angle + max_angle) / col_rad, (p.y() - y0) / row_mm, d.norm()};
  }
};

void rasterize(PillarView& view, const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  std::vector<Eigen::Vector3d> proj(V.rows());
  for (Eigen::Index i = 0; i < V.rows(); ++i) proj[i] = view.project(V.row(i).transpose());
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3d &a = proj[F(f, 0)], &b = proj[F(f, 1)], &c = proj[F(f, 2)];
    int c0 = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}))));
    int c1 = std::min(view.cols - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}))));
    int r0 = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}))));
    int r1 = std::min(view.rows - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}))));
    double det = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
    if (std::abs(det) < 1e-12) continue;
    for (int r = r0; r <= r1; ++r)
      for (int col = c0; col <= c1; ++col) {
        double px = col + 0.5, py = r + 0.5;
        double l1 = ((px - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (py - a.y())) / det;
        double l2 = ((b.x() - a.x()) * (py - a.y()) - (px - a.x()) * (b.y() - a.y())) / det;
        double l0 = 1 - l1 - l2;
        if (l0 < -1e-9 || l1 < -1e-9 || l2 < -1e-9) continue;
        float z = static_cast<float>(l0 * a.z() + l1 * b.z() + l2 * c.z());
        float& zb = view.depth[static_cast<size_t>(r) * view.cols + col];
        if (z < zb) zb = z;
      }
  }
}

double sample_depth(const PillarView& v, double col, double row) {
  // Minimum over the 2×2 neighbourhood: tolerant to the sample falling between pixels.
  double best = std::numeric_limits<double>::infinity();
  int c = static_cast<int>(std::floor(col - 0.5)), r = static_cast<int>(std::floor(row - 0.5));
  for (int dr = 0; dr <= 1; ++dr)
    for (int dc = 0; dc <= 1; ++dc) {
      int rr = r + dr, cc = c + dc;
      if (rr < 0 || cc < 0 || rr >= v.rows || cc >= v.cols) continue;
      best = std::min<double>(best, v.depth[static_cast<size_t>(rr) * v.cols + cc]);
    }
  return best;
}

std::string fmt_double(double v, int decimals) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(decimals) << v;
  return s.str();
}

Eigen::Matrix3d random_rotation(std::mt19937_64& rng, double sigma_rad) {
  std::normal_distribution<double> n(0.0, sigma_rad);
  return rotation_from_vector(Eigen::Vector3d(n(rng), n(rng), n(rng)));
}

// Poses a subject can be scanned in. Extreme poses with self-contact or body parts hidden from
// every pillar (benchmark splits, gym01 handstand, sit01 on the floor) are left out: they make
// the scan meaningless as a registration target, as they would in a real scanner.
std::vector<std::string> static_pose_pool(const MakeHuman& mh) {
  static const std::set<std::string> excluded = {"benchmark", "gym01", "sit01"};
  std::vector<std::string> pool;
  for (auto& n : mh.pose_names())
    if (!excluded.count(n)) pool.push_back(n);
  return pool;
}

const std::vector<std::string>& perturbed_bones() {
  static const std::vector<std::string> bones = {
      "spine04",      "spine02",      "neck01",        "head",          "clavicle.L",
      "clavicle.R",   "upperarm01.L", "upperarm01.R",  "lowerarm01.L",  "lowerarm01.R",
      "upperleg01.L", "upperleg01.R", "lowerleg01.L",  "lowerleg01.R",  "foot.L",
      "foot.R"};
  return bones;
}


}  // namespace

PointCloud simulate_scan(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                         const ScannerOptions& o, std::mt19937_64& rng) {
  if (o.pillars < 1) throw InputError("scanner needs at least one pillar");
  // Subject axis and extent.
  Eigen::RowVector3d lo = V.colwise().minCoeff(), hi = V.colwise().maxCoeff();
  Eigen::Vector2d axis(0.5 * (lo.x() + hi.x()), 0.5 * (lo.z() + hi.z()));
  std::vector<PillarView> views(o.pillars);
  for (int k = 0; k < o.pillars; ++k) {
    double th = M_PI / 4 + 2 * M_PI * k / o.pillars;
    PillarView& v = views[k];
    v.position = axis + o.pillar_distance_mm * Eigen::Vector2d(std::cos(th), std::sin(th));
    v.forward = (axis - v.position).normalized();
    v.y0 = lo.y() - 10;
    v.row_mm = o.pixel_mm;
    v.rows = static_cast<int>(std::ceil((hi.y() - lo.y() + 20) / o.pixel_mm));
    v.max_angle = std::atan2(0.5 * (hi - lo).norm() + 50, o.pillar_distance_mm - 600);
    v.max_angle = std::min(v.max_angle, 1.2);
    v.col_rad = o.pixel_mm / 1000.0;
    v.cols = static_cast<int>(std::ceil(2 * v.max_angle / v.col_rad));
    v.depth.assign(static_cast<size_t>(v.rows) * v.cols, std::numeric_limits<float>::infinity());
    rasterize(v, V, F);
  }
  Eigen::MatrixX3d FN = face_normals(V, F);
  const double cos_max = std::cos(o.max_incidence_deg * M_PI / 180);
  std::vector<Eigen::Vector3d> pts;
  std::vector<int> seen_by;
  int requested = o.min_points + o.min_points / 2;
  for (int attempt = 0; attempt < 4 && static_cast<int>(pts.size()) < o.min_points; ++attempt) {
    SurfaceSamples s = sample_surface(V, F, requested, static_cast<unsigned>(rng()));
    for (int i = 0; i < s.P.rows(); ++i) {
      Eigen::Vector3d p = s.P.row(i).transpose();
      Eigen::Vector3d n = FN.row(s.face(i)).transpose();
      int best = -1;
      double best_cos = cos_max;
      for (int k = 0; k < o.pillars; ++k) {
        const PillarView& v = views[k];
        Eigen::Vector3d to(v.position.x() - p.x(), 0, v.position.y() - p.z());
        double c = n.dot(to.normalized());
        if (c <= best_cos) continue;
        Eigen::Vector3d pr = v.project(p);
        if (pr.z() <= sample_depth(v, pr.x(), pr.y()) + 3.0) {
          best = k;
          best_cos = c;
        }
      }
      if (best >= 0) {
        pts.push_back(p);
        seen_by.push_back(best);
      }
    }
    requested *= 2;
  }
  if (static_cast<int>(pts.size()) < o.min_points / 2)
    throw NumericalError("simulated scan saw too little of the surface");
  std::normal_distribution<double> noise(0.0, o.noise_sigma_mm);
  PointCloud cloud;
  cloud.P.resize(pts.size(), 3);
  for (size_t i = 0; i < pts.size(); ++i)
    cloud.P.row(i) = (pts[i] + Eigen::Vector3d(noise(rng), noise(rng), noise(rng))).transpose();
  // Normals estimated from the noisy points, oriented towards the pillar that saw the point.
  PointIndex index(cloud.P);
  cloud.N.resize(pts.size(), 3);
  tbb::parallel_for(size_t(0), pts.size(), [&](size_t i) {
    Eigen::Vector3d p = cloud.P.row(i).transpose();
    auto nb = index.knn(p, o.normal_neighbours);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int j : nb) mean += cloud.P.row(j).transpose();
    mean /= nb.size();
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    for (int j : nb) {
      Eigen::Vector3d d = cloud.P.row(j).transpose() - mean;
      C += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
    Eigen::Vector3d n = es.eigenvectors().col(0);
    const PillarView& v = views[seen_by[i]];
    Eigen::Vector3d to(v.position.x() - p.x(), 0, v.position.y() - p.z());
    if (n.dot(to) < 0) n = -n;
    cloud.N.row(i) = n.transpose();
  });
  return cloud;
}

namespace {

// The pose pool: MakeHuman's static poses, plus frames of the CMU clips (retargeted to the
// MakeHuman skeleton of each subject), four evenly spaced frames per clip.
struct PoolPose {
  std::string name;
  const BvhMotion* motion;
  int frame;
  const RetargetMap* map;  // null: the file uses the skeleton's own bone names
};

struct PosePool {
  std::vector<std::unique_ptr<BvhMotion>> motions;
  std::vector<std::unique_ptr<RetargetMap>> maps;
  std::vector<PoolPose> poses;

  // with_maps = false: names only (the retarget maps are not built).
  PosePool(const MakeHuman& mh, bool with_maps) {
    for (auto& name : static_pose_pool(mh)) {
      motions.push_back(std::make_unique<BvhMotion>(read_bvh(mh.pose_file(name))));
      poses.push_back({name, motions.back().get(), 0, nullptr});
    }
    const fs::path cmu_dir = mh.directory() / "motion" / "cmu";
    std::error_code ec;
    if (!fs::is_directory(cmu_dir, ec)) return;
    std::vector<fs::path> clips;
    for (auto& e : fs::directory_iterator(cmu_dir))
      if (e.path().extension() == ".bvh") clips.push_back(e.path());
    std::sort(clips.begin(), clips.end());
    for (auto& clip : clips) {
      motions.push_back(std::make_unique<BvhMotion>(read_bvh(clip)));
      const RetargetMap* map = nullptr;
      if (with_maps) {
        maps.push_back(std::make_unique<RetargetMap>(RetargetMap::for_clip(*motions.back(), mh.directory())));
        map = maps.back().get();
      }
      const int n = motions.back()->frame_count();
      for (int k = 0; k < 4; ++k) {
        int frame = static_cast<int>((k + 0.5) * n / 4);
        poses.push_back({"cmu" + clip.stem().string() + "-f" + std::to_string(frame),
                         motions.back().get(), frame, map});
      }
    }
  }

  std::vector<std::string> names() const {
    std::vector<std::string> out;
    for (auto& p : poses) out.push_back(p.name);
    return out;
  }
};

std::string description_json(const SyntheticDatabaseOptions& o, const std::vector<std::string>& pool) {
  const ScannerOptions& sc = o.scanner;
  nlohmann::ordered_json meta = {
      {"generator", "bodymodel synth-db"},
      {"seed", o.seed},
      {"subjects", o.subjects},
      {"poses_per_subject", o.poses_per_subject},
      {"units", "millimetres, +y up, bodies face +z"},
      {"noise_sigma_mm", sc.noise_sigma_mm},
      {"landmark_sigma_mm", o.landmark_sigma_mm},
      {"pillars", sc.pillars},
      {"perturbation_deg", o.perturbation_deg},
      {"pose_pool", pool},
      {"density_kg_per_l", MeasureOptions{}.density_kg_per_l},
      {"max_yaw_deg", o.max_yaw_deg},
      {"max_shift_mm", o.max_shift_mm},
      {"scanner", {{"pillar_distance_mm", sc.pillar_distance_mm},
                   {"max_incidence_deg", sc.max_incidence_deg},
                   {"min_points", sc.min_points},
                   {"pixel_mm", sc.pixel_mm},
                   {"normal_neighbours", sc.normal_neighbours}}},
      {"note", "truth/ is for evaluation only: nothing in the pipeline may read it"}};
  if (!o.population.empty()) {
    meta["population"] = {{"file", o.population},
                          {"measurements", o.population_measurements},
                          {"space", o.fit.extended_space ? "extended" : "standard"},
                          {"reused_fits", o.fits}};
  }
  if (o.truth_only) meta["truth_only"] = true;  // no scans/*.ply: for `build`, not `register`
  return json_text(meta, 2) + "\n";
}

// Compares an existing database.json with the expected description; "" when they agree (the
// comparison of every resumable folder's settings record, tools/pipeline/folder_settings.h).
std::string description_difference(const fs::path& file, const std::string& expected) {
  return settings_difference(file, nlohmann::json::parse(expected));
}

// The process id in a write_atomically temporary name ".<name>.tmp<pid>_<n>", or -1.
long temporary_owner(const std::string& n) {
  if (n.size() < 2 || n[0] != '.') return -1;
  const size_t t = n.rfind(".tmp");
  if (t == std::string::npos || t == 0) return -1;
  size_t i = t + 4, j = i;
  while (j < n.size() && std::isdigit(static_cast<unsigned char>(n[j]))) ++j;
  if (j == i || j - i > 9 || j >= n.size() || n[j] != '_') return -1;
  const long pid = std::stol(n.substr(i, j - i));
  return is_atomic_write_temporary(n.c_str(), pid) ? pid : -1;
}

// Removes the write_atomically temporaries in `dir` whose writer no longer runs (a run killed
// by SIGKILL or a power cut cannot remove its own); returns how many.
int remove_stale_temporaries(const fs::path& dir) {
  int removed = 0;
  std::error_code ec;
  for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::end(it); it.increment(ec)) {
    const long pid = temporary_owner(it->path().filename().string());
    if (pid <= 0 || pid == static_cast<long>(::getpid())) continue;
    if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;  // still running
    std::error_code rm;
    if (fs::remove(it->path(), rm)) ++removed;
  }
  return removed;
}

// The four files of one scan.
std::array<fs::path, 4> scan_files(const fs::path& dir, const std::string& id) {
  return {dir / "scans" / (id + ".ply"), dir / "scans" / (id + ".landmarks.json"),
          dir / "truth" / (id + ".ply"), dir / "truth" / (id + ".pose.csv")};
}

// Point count of a scan written by an earlier run when all four of its files exist and parse;
// -1 otherwise (the scan is then made again).
int finished_scan_points(const fs::path& dir, const std::string& id) {
  const auto files = scan_files(dir, id);
  std::error_code ec;
  for (auto& f : files)
    if (!fs::is_regular_file(f, ec)) return -1;
  try {
    const PointCloud scan = read_point_cloud(files[0]);
    if (scan.P.rows() == 0 || !scan.has_normals()) return -1;
    const nlohmann::json lm = nlohmann::json::parse(read_text_file(files[1]));
    if (!lm.is_object() || lm.size() != body_landmarks().size()) return -1;
    const Mesh truth = read_mesh(files[2]);
    if (truth.V.rows() == 0 || truth.F.rows() == 0) return -1;
    const std::string pose = read_text_file(files[3]);
    if (pose.rfind("bone,rx,ry,rz\n_global_rotation,", 0) != 0 || pose.back() != '\n') return -1;
    return static_cast<int>(scan.P.rows());
  } catch (const std::exception&) {
    return -1;
  }
}

}  // namespace

namespace {

// A fit-measurements fit.csv's bodies by person id (SyntheticDatabaseOptions::fits).
struct StoredFit {
  std::string sex, fitted;
  double age_years = 0;
  MacroSettings sliders;
  Eigen::VectorXd modifiers;
  bool reached = false, extrapolated = false;
  std::string reason;
};

// A fit.csv's records (core/io/csv.h: quoted ids and reasons, a byte-order mark, CRLF);
// InputError naming the file when it cannot be read.
std::vector<CsvRecord> fit_csv_records(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError("cannot open '" + path.string() + "'");
  std::vector<CsvRecord> rows = read_csv_file(path);
  if (rows.empty()) throw InputError("'" + path.string() + "' is empty (expected a fit-measurements fit.csv)");
  return rows;
}

// The range fit-measurements writes a column in (its extended space included), or none (a
// column that is not a value checked here).
std::optional<std::pair<double, double>> stored_fit_range(const std::string& column) {
  const FitMeasurementsOptions f;
  if (column == "slider_weight") return std::pair{0.0, std::max(1.0, f.weight_max)};
  if (column == "slider_muscle") return std::pair{std::min(0.0, f.muscle_min), 1.0};
  if (column.rfind("slider_", 0) == 0) return std::pair{0.0, 1.0};
  if (column.rfind("modifier_", 0) == 0) return std::pair{-std::max(1.0, f.modifier_limit), std::max(1.0, f.modifier_limit)};
  if (column == "age_years") return std::pair{0.0, 150.0};
  return std::nullopt;
}

// A value cell of a fit.csv: a finite number within stored_fit_range. A slider far out of
// range made a giant body without a word, and 'nan' failed later naming no file.
double stored_fit_value(const std::string& cell, const fs::path& path, int line, const std::string& column) {
  const auto range = stored_fit_range(column);
  double v = 0;
  size_t used = 0;
  try {
    v = std::stod(cell, &used);
  } catch (const std::logic_error&) {
    used = 0;
  }
  if (cell.empty() || used != cell.size())
    throw InputError(fmt::format("'{}' line {}, column '{}': '{}' is not a number", path.string(), line, column, cell));
  const std::string ranges = fmt::format("MakeHuman's macro sliders are 0 … 1; fit-measurements' extended space "
                                         "reaches weight {}, modifiers ±{}",
                                         FitMeasurementsOptions{}.weight_max, FitMeasurementsOptions{}.modifier_limit);
  if (!std::isfinite(v))
    throw InputError(fmt::format("'{}' line {}, column '{}': '{}' is not a finite number ({})", path.string(), line,
                                 column, cell, ranges));
  if (range && !(v >= range->first && v <= range->second))
    throw InputError(fmt::format("'{}' line {}, column '{}': {} is outside {} … {} ({})", path.string(), line, column,
                                 cell, range->first, range->second, ranges));
  return v;
}

}  // namespace

void check_stored_fits(const std::string& fits) {
  const fs::path path(fits);
  const std::vector<CsvRecord> rows = fit_csv_records(path);
  const std::vector<std::string>& header = rows[0].fields;
  for (size_t r = 1; r < rows.size(); ++r) {
    const int line_no = rows[r].line;
    const std::vector<std::string>& c = rows[r].fields;
    if (c.size() != header.size())
      throw InputError(fmt::format("'{}' line {}: {} cells for {} columns", path.string(), line_no, c.size(),
                                   header.size()));
    for (size_t k = 0; k < header.size(); ++k)
      if (stored_fit_range(header[k])) stored_fit_value(c[k], path, line_no, header[k]);
  }
}

namespace {

std::map<std::string, StoredFit> read_stored_fits(const fs::path& path, const MakeHuman& mh) {
  check_stored_fits(path.string());
  const std::vector<CsvRecord> rows = fit_csv_records(path);
  const std::vector<std::string>& header = rows[0].fields;
  auto col = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    if (it == header.end())
      throw InputError("'" + path.string() + "': no column '" + name + "' (not a fit-measurements fit.csv)");
    return static_cast<size_t>(it - header.begin());
  };
  const size_t id = col("id"), sex = col("sex"), age = col("age_years"), fitted = col("fitted"), reached = col("reached"),
               extrapolated = col("extrapolated"), reason = col("reason");
  const std::vector<std::string> sliders = {"gender", "age",     "muscle",  "weight", "height",   "proportions",
                                            "cup",    "firmness", "african", "asian",  "caucasian"};
  std::vector<size_t> slider_cols, modifier_cols;
  for (const auto& s : sliders) slider_cols.push_back(col("slider_" + s));
  for (const auto& m : mh.measure_modifier_names()) modifier_cols.push_back(col("modifier_" + m));
  std::map<std::string, StoredFit> fits;
  for (size_t r = 1; r < rows.size(); ++r) {
    const int line_no = rows[r].line;
    const std::vector<std::string>& c = rows[r].fields;
    if (c.size() != header.size())
      throw InputError(fmt::format("'{}' line {}: {} cells for {} columns", path.string(), line_no, c.size(),
                                   header.size()));
    {
      StoredFit f;
      f.sex = c[sex];
      f.age_years = stored_fit_value(c[age], path, line_no, header[age]);
      f.fitted = c[fitted];
      f.reached = c[reached] == "1";
      f.extrapolated = c[extrapolated] == "1";
      f.reason = c[reason];
      double* v[] = {&f.sliders.gender, &f.sliders.age,     &f.sliders.muscle,  &f.sliders.weight,
                     &f.sliders.height, &f.sliders.proportions, &f.sliders.cup, &f.sliders.firmness,
                     &f.sliders.african, &f.sliders.asian,  &f.sliders.caucasian};
      for (size_t k = 0; k < slider_cols.size(); ++k)
        *v[k] = stored_fit_value(c[slider_cols[k]], path, line_no, header[slider_cols[k]]);
      f.modifiers.resize(static_cast<Eigen::Index>(modifier_cols.size()));
      for (size_t k = 0; k < modifier_cols.size(); ++k)
        f.modifiers(k) = stored_fit_value(c[modifier_cols[k]], path, line_no, header[modifier_cols[k]]);
      fits[c[id]] = std::move(f);
    }
  }
  return fits;
}

// The population's subjects (SyntheticDatabaseOptions::population): drawn by survey weight with
// the database's seed, each fitted to the person's recorded measurements (in parallel).
std::vector<SyntheticSubject> population_subjects(const MakeHuman& mh, const SyntheticDatabaseOptions& o,
                                                  SyntheticDatabaseSummary& summary, const ProgressCallback& progress) {
  const PeopleTable table = read_people(o.population);
  require_columns(table, {"sex", "age_years"});
  require_columns(table, o.population_measurements);
  PopulationFilter filter;
  filter.required = o.population_measurements;
  const EligibleSummary eligible = eligible_people(table, filter);
  summary.eligible_people = static_cast<int>(eligible.eligible.size());
  const std::vector<int> drawn = sample_population(table, eligible.eligible, o.subjects, o.seed);
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<SyntheticSubject> subjects(drawn.size());
  std::map<std::string, StoredFit> stored;
  if (!o.fits.empty()) stored = read_stored_fits(o.fits, mh);
  std::string fitted_names;
  for (const auto& m : o.population_measurements) fitted_names += (fitted_names.empty() ? "" : ";") + m;
  std::atomic<int> done{0}, reused{0};
  std::mutex mutex;
  std::atomic<bool> cancelled{false};
  tbb::task_arena arena(o.threads > 0 ? o.threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(size_t(0), drawn.size(), [&](size_t k) {
      if (cancelled) return;
      const Person& p = table.people[drawn[k]];
      SyntheticSubject& s = subjects[k];
      s.sex = p.sex == Sex::male ? "male" : "female";
      s.age_years = p.age_years;
      s.person_id = p.id;
      s.recorded = p.measurements;
      const auto it = stored.find(p.id);
      if (it != stored.end() && it->second.sex == s.sex && std::abs(it->second.age_years - p.age_years) < 0.5 &&
          it->second.fitted == fitted_names) {
        const StoredFit& f = it->second;
        s.sliders = f.sliders;
        s.modifiers = f.modifiers;
        s.extrapolated = f.extrapolated;
        s.fit_reached = f.reached;
        s.fit_reason = f.reason;
        ++reused;
      } else {
        const MeasurementFit f = fit_measurements(mh, person_spec(p, o.population_measurements), o.fit);
        s.sliders = f.sliders;
        s.modifiers = f.modifiers;
        s.extrapolated = f.extrapolated;
        s.fit_reached = f.reached;
        s.fit_reason = f.reason;
      }
      const int d = ++done;
      std::lock_guard<std::mutex> lock(mutex);
      try {
        report_progress(progress, 0.5 * d / drawn.size(), "fitting person " + p.id);
      } catch (const Cancelled&) {
        cancelled = true;
      }
    });
  });
  if (cancelled) throw Cancelled{};
  summary.reused_fits = reused;
  summary.fit_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return subjects;
}

std::vector<std::string> split_list(const std::string& list) {
  std::vector<std::string> out;
  std::stringstream ss(list);
  for (std::string item; std::getline(ss, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

// Whether SyntheticDatabaseOptions::population names ANSUR II files (every one of them).
bool ansur_population(const std::string& population) {
  const auto files = split_list(population);
  return !files.empty() && std::all_of(files.begin(), files.end(), [](const std::string& f) { return is_ansur_file(f); });
}

// ANSUR soldiers (SyntheticDatabaseOptions::population lists ANSUR files): drawn uniformly with
// the database's seed, alternating sexes when there are two files, each fitted to the chosen
// columns with the rest completed by its file's own prior.
std::vector<SyntheticSubject> ansur_subjects(const MakeHuman& mh, const SyntheticDatabaseOptions& o,
                                             SyntheticDatabaseSummary& summary, const ProgressCallback& progress) {
  std::vector<AnsurTable> tables;
  for (const auto& f : split_list(o.population)) tables.push_back(read_ansur(f, o.population_measurements));
  std::mt19937_64 rng(o.seed ^ 0x616e737572ULL);
  std::vector<std::vector<int>> order(tables.size());
  for (size_t t = 0; t < tables.size(); ++t) {
    order[t].resize(tables[t].ids.size());
    std::iota(order[t].begin(), order[t].end(), 0);
    std::shuffle(order[t].begin(), order[t].end(), rng);
    summary.eligible_people += static_cast<int>(tables[t].ids.size());
  }
  const MeasurementSet set = ansur_measurement_set(mh);
  const ProportionFitter fitter(mh, set);
  std::vector<AnsurFitRow> rows;
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<SyntheticSubject> subjects(o.subjects);
  std::vector<std::vector<int>> picked(tables.size());
  for (int s = 0; s < o.subjects; ++s) {
    const size_t t = s % tables.size(), k = s / tables.size();
    if (k >= order[t].size()) throw InputError(fmt::format("'{}' has only {} soldiers", tables[t].source.string(), order[t].size()));
    picked[t].push_back(order[t][k]);
  }
  // The recorded columns carried as labels: the set's columns every file has.
  std::vector<std::string> recorded;
  for (const auto& name : set.names)
    if (std::all_of(tables.begin(), tables.end(), [&](const AnsurTable& tb) {
          return std::find(tb.columns.begin(), tb.columns.end(), name) != tb.columns.end();
        }))
      recorded.push_back(name);
  int done_before = 0;
  for (size_t t = 0; t < tables.size(); ++t) {
    AnsurFitOptions fo;
    fo.given = o.population_measurements;
    fo.rows = picked[t];
    fo.prior_rows.resize(tables[t].ids.size());
    std::iota(fo.prior_rows.begin(), fo.prior_rows.end(), 0);
    fo.jobs = o.threads;
    fo.progress = [&](int d, int) { report_progress(progress, 0.5 * (done_before + d) / o.subjects, "fitting soldiers"); };
    AnsurFitRun run = fit_ansur_rows(fitter, set, tables[t], tables[t], fo, false);
    for (size_t i = 0; i < run.people.size(); ++i) {
      SyntheticSubject& subj = subjects[i * tables.size() + t];
      const ProportionFit& f = run.people[i].fit;
      const bool male = tables[t].male[run.people[i].row] == 1;
      subj.sex = male ? "male" : "female";
      subj.age_years = tables[t].values(run.people[i].row, tables[t].column("Age"));
      subj.person_id = run.people[i].id;
      for (const auto& name : recorded)
        subj.ansur_recorded.emplace_back(name, tables[t].values(run.people[i].row, tables[t].column(name)));
      subj.sliders = f.sliders;
      subj.modifiers = f.measure_modifiers;
      subj.shape_modifiers = f.shape_modifiers;
      subj.extrapolated = (f.measure_modifiers.cwiseAbs().array() > 1.0).any() || f.sliders.weight > 1.0;
      std::vector<std::string> misses;
      for (size_t k = 0; k < f.names.size(); ++k)
        if (f.given[k] && !(std::abs(f.measured(k) - f.target(k)) <= ansur_tolerance(f.names[k])))
          misses.push_back(fmt::format("{} by {:+.1f}", f.names[k], f.measured(k) - f.target(k)));
      subj.fit_reached = misses.empty();
      subj.fit_reason = fmt::format("{}", fmt::join(misses, ", "));
    }
    done_before += static_cast<int>(run.people.size());
  }
  summary.fit_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return subjects;
}

std::string csv_value(double v, int decimals) { return std::isfinite(v) ? fmt_double(v, decimals) : std::string(); }

// subjects.csv: the labels measured on the standard-pose truth mesh and the sliders; for a
// population, the person (seqn / subjectid, not a label), the recorded values (nhanes_* /
// ansur2_*), the modifiers and whether the fit reached the person.
std::string subjects_csv(const std::vector<SyntheticSubject>& subjects, const MakeHuman& mh, bool population) {
  std::string csv =
      "subject_id,sex,age_years,height_cm,weight_kg,body_fat_pct,muscle,waist_cm,hips_cm,"
      "chest_cm,neck_cm,waist_iliac_cm,arm_circumference_cm,upper_arm_length_cm,upper_leg_length_cm,"
      "slider_gender,slider_age,slider_muscle,slider_weight,slider_height,"
      "slider_proportions,slider_african,slider_asian,slider_caucasian";
  const bool ansur = population && !subjects.empty() && !subjects[0].ansur_measured.empty();
  if (ansur) {
    csv += ",subjectid";
    for (const auto& [name, value] : subjects[0].ansur_measured) csv += "," + name;
    for (const auto& [name, value] : subjects[0].ansur_recorded) csv += ",ansur2_" + name;
    csv += ",fit_reached,fit_extrapolated,fit_reason";
  } else if (population) {
    csv += ",seqn";
    for (const auto& m : recorded_measurement_names()) csv += ",nhanes_" + m;
    for (const auto& m : mh.measure_modifier_names()) csv += ",modifier_" + m;
    csv += ",fit_reached,fit_extrapolated,fit_reason";
  }
  csv += "\n";
  for (const auto& s : subjects) {
    const auto& k = s.sliders;
    csv += csv_field(s.id) + "," + s.sex + "," + fmt_double(s.age_years, 1) + "," + fmt_double(s.height_cm, 2) + "," +
           fmt_double(s.weight_kg, 2) + "," + fmt_double(s.body_fat_pct, 2) + "," + fmt_double(s.muscle, 1) + "," +
           fmt_double(s.waist_cm, 2) + "," + fmt_double(s.hips_cm, 2) + "," + fmt_double(s.chest_cm, 2) + "," +
           fmt_double(s.neck_cm, 2) + "," + csv_value(s.waist_iliac_cm, 2) + "," +
           csv_value(s.arm_circumference_cm, 2) + "," + csv_value(s.upper_arm_length_cm, 2) + "," +
           csv_value(s.upper_leg_length_cm, 2) + "," + fmt_double(k.gender, 4) + "," + fmt_double(k.age, 4) + "," +
           fmt_double(k.muscle, 4) + "," + fmt_double(k.weight, 4) + "," + fmt_double(k.height, 4) + "," +
           fmt_double(k.proportions, 4) + "," + fmt_double(k.african, 4) + "," + fmt_double(k.asian, 4) + "," +
           fmt_double(k.caucasian, 4);
    if (ansur) {
      csv += "," + csv_field(s.person_id);
      for (const auto& [name, value] : s.ansur_measured) csv += "," + csv_value(value, name == "weightkg" ? 2 : 1);
      for (const auto& [name, value] : s.ansur_recorded) csv += "," + csv_value(value, name == "weightkg" ? 2 : 1);
      csv += std::string(",") + (s.fit_reached ? "yes" : "no") + "," + (s.extrapolated ? "yes" : "no") + "," +
             csv_field(s.fit_reason);
    } else if (population) {
      csv += "," + csv_field(s.person_id);
      for (size_t m = 0; m < recorded_measurement_names().size(); ++m)
        csv += "," + (m < s.recorded.size() ? csv_value(s.recorded[m], 1) : std::string());
      for (size_t m = 0; m < mh.measure_modifier_names().size(); ++m)
        csv += "," + fmt_double(static_cast<Eigen::Index>(m) < s.modifiers.size() ? s.modifiers(m) : 0.0, 4);
      // Text, not 0/1: subjects.csv's numeric columns become model labels, these are not labels.
      csv += std::string(",") + (s.fit_reached ? "yes" : "no") + "," + (s.extrapolated ? "yes" : "no") + "," +
             csv_field(s.fit_reason);
    }
    csv += "\n";
  }
  return csv;
}

}  // namespace

std::string synthetic_database_description(const MakeHuman& mh, const SyntheticDatabaseOptions& o) {
  return description_json(o, PosePool(mh, false).names());
}

bool is_same_synthetic_database(const MakeHuman& mh, const std::string& out,
                                const SyntheticDatabaseOptions& o, std::string* difference) {
  const std::string d =
      description_difference(fs::path(out) / "database.json", synthetic_database_description(mh, o));
  if (difference) *difference = d;
  return d.empty();
}

namespace {

// A subject's labels, measured on its standard-pose mesh (what `bodymodel measure` sees).
void measure_subject(SyntheticSubject& subj, const Eigen::MatrixX3d& posed, const Eigen::MatrixX3i& F) {
  BodyMeasurements m = measure_body(posed, F,
                                    subj.sex == "male" ? Sex::male : Sex::female);
  subj.height_cm = m.height_cm;
  subj.weight_kg = m.weight_kg;
  subj.body_fat_pct = m.body_fat_pct;
  subj.waist_cm = m.waist_cm;
  subj.hips_cm = m.hips_cm;
  subj.chest_cm = m.chest_cm;
  subj.neck_cm = m.neck_cm;
  subj.waist_iliac_cm = m.waist_iliac_cm;
  subj.arm_circumference_cm = m.arm_circumference_cm;
  subj.upper_arm_length_cm = m.upper_arm_length_cm;
  subj.upper_leg_length_cm = m.upper_leg_length_cm;
}

// One scan's files: the posed body placed on the scanner platform (a turn about +y and a
// horizontal shift) as the truth mesh and pose, the simulated scan and its landmarks. Draws from
// `r` in a fixed order, so a scan depends on its seed only.
void write_scan_files(const fs::path& dir, const std::string& id, const MakeHuman::Body& body,
                      const Eigen::MatrixX3d& posed, const Pose& pose, const SyntheticDatabaseOptions& o,
                      std::mt19937_64& r, SyntheticScanInfo& info) {
  std::uniform_real_distribution<double> u(-1, 1);
  RigidMotion place;
  place.R = Eigen::AngleAxisd(u(r) * o.max_yaw_deg * M_PI / 180, Eigen::Vector3d::UnitY())
                .toRotationMatrix();
  place.t = Eigen::Vector3d(u(r) * o.max_shift_mm, 0, u(r) * o.max_shift_mm);
  Eigen::MatrixX3d truth = apply(place, posed);
  PointCloud scan;
  if (!o.truth_only) {
    scan = simulate_scan(truth, body.mesh.F, o.scanner, r);
    write_point_cloud(dir / "scans" / (id + ".ply"), scan);
  }
  nlohmann::ordered_json lm;
  std::normal_distribution<double> ln(0.0, o.landmark_sigma_mm);
  for (auto& [name, v] : body_landmarks()) {
    Eigen::Vector3d p = truth.row(v).transpose() + Eigen::Vector3d(ln(r), ln(r), ln(r));
    lm[name] = {p.x(), p.y(), p.z()};
  }
  write_text_file(dir / "scans" / (id + ".landmarks.json"), json_text(lm, 1) + "\n");
  write_mesh(dir / "truth" / (id + ".ply"), truth, body.mesh.F);
  std::string pose_csv = "bone,rx,ry,rz\n";
  Eigen::Vector3d g = rotation_vector_of(place.R);
  pose_csv += "_global_rotation," + fmt_double(g.x(), 9) + "," + fmt_double(g.y(), 9) + "," +
              fmt_double(g.z(), 9) + "\n";
  pose_csv += "_global_translation_mm," + fmt_double(place.t.x(), 4) + "," +
              fmt_double(place.t.y(), 4) + "," + fmt_double(place.t.z(), 4) + "\n";
  for (int b = 0; b < body.skeleton.bone_count(); ++b) {
    Eigen::Vector3d w = rotation_vector_of(pose.rotations[b]);
    pose_csv += body.skeleton.names[b] + "," + fmt_double(w.x(), 9) + "," +
                fmt_double(w.y(), 9) + "," + fmt_double(w.z(), 9) + "\n";
  }
  write_text_file(dir / "truth" / (id + ".pose.csv"), pose_csv);
  info.points = static_cast<int>(scan.P.rows());
}

}  // namespace

SyntheticDatabaseSummary generate_synthetic_database(const MakeHuman& mh, const std::string& out,
                                                     const SyntheticDatabaseOptions& o,
                                                     const ProgressCallback& progress) {
  if (o.subjects < 1) throw InputError("--subjects must be at least 1");
  if (o.poses_per_subject < 0) throw InputError("--poses-per-subject must be 0 or more");
  auto t0 = std::chrono::steady_clock::now();
  const fs::path dir(out);
  // The stored fits are checked before any folder is made: nothing half-written on a bad file.
  if (!o.population.empty() && !o.fits.empty()) check_stored_fits(o.fits);
  ensure_directory(dir / "scans");
  ensure_directory(dir / "truth");

  SyntheticDatabaseSummary summary;
  const PosePool pose_pool(mh, true);
  const std::vector<PoolPose>& pool = pose_pool.poses;
  summary.pose_pool = pose_pool.names();

  // Subjects and their scan list are drawn up front from the seed, so the database does not
  // depend on thread scheduling (nor on which scans an earlier run already made).
  std::mt19937_64 rng(o.seed);
  struct Job {
    int subject;
    int index;       // 0 = standard pose
    int pose = -1;   // index into pool_motions, -1 for the standard pose
    uint64_t seed;
  };
  std::vector<Job> jobs;
  // A real population: the people are drawn and their bodies fitted before any scan is made.
  std::vector<SyntheticSubject> people;
  const bool ansur = !o.population.empty() && ansur_population(o.population);
  if (!o.population.empty()) people = ansur ? ansur_subjects(mh, o, summary, progress) : population_subjects(mh, o, summary, progress);
  std::shared_ptr<const MeasurementSet> ansur_set;
  if (ansur) ansur_set = std::make_shared<const MeasurementSet>(ansur_measurement_set(mh));
  for (int s = 0; s < o.subjects; ++s) {
    SyntheticSubject subj;
    if (!people.empty()) {
      subj = people[s];
    } else {
      bool male = (s % 2) == 1;
      subj.sliders = random_makehuman_subject(rng, male);
      subj.sex = subj.sliders.gender >= 0.5 ? "male" : "female";
      subj.age_years = subj.sliders.age_years();
    }
    char id[32];
    std::snprintf(id, sizeof id, "s%03d", s);
    subj.id = id;
    subj.muscle = subj.sliders.muscle * 100;
    summary.subjects.push_back(subj);
    jobs.push_back({s, 0, -1, rng()});
    std::vector<int> order(pool.size());
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    for (int p = 0; p < o.poses_per_subject; ++p)
      jobs.push_back({s, p + 1, order[p % order.size()], rng()});
  }
  summary.scans.resize(jobs.size());
  auto scan_id = [&](const Job& job) {
    return summary.subjects[job.subject].id + "_p" + std::to_string(job.index);
  };

  // The description goes first: a resume trusts the scan files only under the same description,
  // so files of another database are removed before it is written.
  const std::string description = description_json(o, summary.pose_pool);
  const bool resume = o.resume && description_difference(dir / "database.json", description).empty();
  for (const fs::path& d : {dir, dir / "scans", dir / "truth"})
    summary.removed_temporaries += remove_stale_temporaries(d);
  if (!resume) {
    std::error_code ec;
    for (auto& job : jobs)
      for (auto& f : scan_files(dir, scan_id(job))) fs::remove(f, ec);
    for (const char* table : {"scans.csv", "subjects.csv"}) fs::remove(dir / table, ec);
    write_text_file(dir / "database.json", description);
  }

  std::atomic<int> done{0}, skipped{0};
  std::mutex progress_mutex;
  std::atomic<bool> cancelled{false};
  tbb::task_arena arena(o.threads > 0 ? o.threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(size_t(0), jobs.size(), [&](size_t j) {
      if (cancelled) return;
      const Job& job = jobs[j];
      SyntheticSubject& subj = summary.subjects[job.subject];
      const std::string id = scan_id(job);
      SyntheticScanInfo& info = summary.scans[j];
      info.id = id;
      info.subject_id = subj.id;
      info.pose = job.pose >= 0 ? pool[job.pose].name : "standard";
      const int kept_points = resume ? finished_scan_points(dir, id) : -1;
      // A kept standard-pose scan still needs its subject's labels (below); a kept posed scan
      // needs nothing more.
      const bool keep = kept_points >= 0;
      if (!keep || job.index == 0) {
        std::mt19937_64 r(job.seed);
        MakeHuman::BuildOptions extrapolate;
        extrapolate.allow_extrapolation = true;  // a fitted body may use the extended space
        MakeHuman::Body body = mh.body(subj.sliders, subj.modifiers, subj.shape_modifiers, extrapolate);
        Pose pose = Pose::rest(body.skeleton.bone_count());
        if (job.pose >= 0) {
          const PoolPose& pp = pool[job.pose];
          pose = pp.map ? Retargeter(*pp.motion, body.skeleton, *pp.map).pose(pp.frame)
                        : bvh_frame_to_pose(*pp.motion, pp.frame, body.skeleton);
          pose.root_translation.setZero();  // the subject stands on the platform
          for (auto& bone : perturbed_bones()) {
            int b = body.skeleton.find(bone);
            if (b >= 0)
              pose.rotations[b] = pose.rotations[b] * random_rotation(r, o.perturbation_deg * M_PI / 180);
          }
        }
        Eigen::MatrixX3d posed =
            linear_blend_skinning(body.mesh.V, body.weights, forward_kinematics(body.skeleton, pose));
        if (job.index == 0) measure_subject(subj, posed, body.mesh.F);
        if (job.index == 0 && ansur_set) {
          const Eigen::VectorXd m = ansur_set->measure(posed);
          subj.ansur_measured.clear();
          for (size_t k = 0; k < ansur_set->names.size(); ++k) subj.ansur_measured.emplace_back(ansur_set->names[k], m(k));
        }
        if (!keep) write_scan_files(dir, id, body, posed, pose, o, r, info);
      }
      if (keep) {
        info.points = kept_points;
        ++skipped;
      }
      int finished = ++done;
      std::lock_guard<std::mutex> lock(progress_mutex);
      try {
        // A population's fits took the first half of the bar.
        const double base = o.population.empty() ? 0.0 : 0.5;
        report_progress(progress, base + (1 - base) * double(finished) / jobs.size(), keep ? id + " (kept)" : id);
      } catch (const Cancelled&) {
        cancelled = true;
      }
    });
  });
  if (cancelled) throw Cancelled{};
  summary.skipped = skipped;

  std::string scans_csv = "scan_id,subject_id,pose,points\n";
  for (auto& s : summary.scans)
    scans_csv += csv_row({s.id, s.subject_id, s.pose}) + "," + std::to_string(s.points) + "\n";
  write_text_file(dir / "subjects.csv", subjects_csv(summary.subjects, mh, !o.population.empty()));
  write_text_file(dir / "scans.csv", scans_csv);
  summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return summary;
}

}  // namespace bodymodel
