// bodymodel register DB/ --out REG/ [--jobs N] [--shard i/n] [--schedule paper|fast] [--scan ID]
//
// Registers the template (MakeHuman default body, its skeleton and weights) to every scan of a
// scan database (DB/scans.csv, DB/scans/<id>.ply, DB/scans/<id>.landmarks.json). Writes
// REG/<id>.ply (template topology, mm), REG/<id>.pose.csv, REG/<id>.shape.json (the fitted
// MakeHuman macro sliders, unless --no-shape-fit) and REG/registration.csv. Never reads
// DB/truth/ (except the --start-from-truth diagnosis).
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/file_names.h"
#include "core/io/json_text.h"
#include "core/io/mesh_io.h"
#include "core/landmarks.h"
#include "core/makehuman.h"
#include <nlohmann/json.hpp>
#include "core/io/pose_csv.h"
#include "model/database.h"
#include "registration/job.h"
#include "registration/metrics.h"
#include "tools/console.h"
#include "tools/pipeline/batch_jobs.h"
#include "tools/pipeline/folder_settings.h"
#include "tools/verb.h"
#include "tools/verbs/register_common.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct RegisterArgs {
  RegistrationJobOptions job = [] {
    RegistrationJobOptions o;
    o.pose_joints = "segment";
    o.hand_stage = true;
    return o;
  }();
  cli::NegatedRegistrationFlags no;
  std::string db, out, shard, scan;
  int jobs = 1;
  double scan_unit_mm = 1.0;
  std::string start_from_truth;  // evaluation only: "", "mesh" or "pose"
  bool force = false, repair_local_folds = false;
  std::string hand_stage = "on";  // finger curls and thumbs fitted after the body (hand stage)
};

// The scans of scans.csv this run registers: all, --scan's one, or --shard i/n's share.
std::vector<std::string> selected_scan_ids(const fs::path& csv, const std::string& scan, const std::string& shard) {
  std::vector<std::string> ids;
  for (const ScanTableRow& row : read_scan_table(csv)) ids.push_back(row.scan_id);
  if (!scan.empty()) {
    if (std::find(ids.begin(), ids.end(), scan) == ids.end())
      throw InputError("--scan " + scan + ": no such scan in " + csv.string());
    ids = {scan};
  }
  if (!shard.empty()) {
    int i = -1, n = 0;
    char slash = 0;
    std::istringstream ss(shard);
    if (!(ss >> i >> slash >> n) || slash != '/' || n < 1 || i < 0 || i >= n || !ss.eof())
      throw InputError("--shard must be i/n with 0 <= i < n, got '" + shard + "'");
    std::vector<std::string> mine;
    for (size_t k = 0; k < ids.size(); ++k)
      if (int(k % n) == i) mine.push_back(ids[k]);
    ids = mine;
  }
  return ids;
}

// Per-scan summary row of registration.csv.
std::string summary_header() {
  return "scan_id,points,normals_estimated,landmarks,pose_icp_iterations,pose_rms_mm,"
         "pose_landmark_rms_mm,scale,nonrigid_iterations,data_rms_mm,landmark_rms_mm,"
         "matched_vertices,plane_matches,pose_seconds,nonrigid_seconds,seconds,pose_two_sided_mm,"
         "pose_joints,folded_triangles_repaired,shape_rounds,shape_seconds,shape_gender,shape_age,"
         "shape_muscle,shape_weight,shape_height,shape_proportions,shape_cup,local_folds,untangle_max_mm\n";
}

void rebuild_registration_csv(const fs::path& out) {
  std::vector<fs::path> parts;
  for (const auto& e : fs::directory_iterator(out))
    if (e.path().string().size() > 12 &&
        e.path().string().compare(e.path().string().size() - 12, 12, ".summary.csv") == 0)
      parts.push_back(e.path());
  std::sort(parts.begin(), parts.end());
  std::string s = summary_header();
  for (const auto& p : parts) s += read_text_file(p);
  write_text_file(out / "registration.csv", s);
}

// Registers scan `id` of the database and writes its outputs; returns a note for the log.
std::string register_database_scan(const RegisterArgs& a, const RegistrationTemplate& tpl,
                                   const RegistrationSetup& setup, const fs::path& db, const fs::path& out,
                                   const std::string& id, const std::function<void(double)>& progress) {
  const fs::path scan_path = db / "scans" / (id + ".ply");
  const fs::path lm_path = db / "scans" / (id + ".landmarks.json");
  PointCloud scan = read_point_cloud(scan_path);
  if (a.scan_unit_mm != 1.0) scan.P *= a.scan_unit_mm;
  if (!fs::exists(lm_path))
    throw InputError(lm_path.string() +
                     ": expected the scan's landmarks {name: [x, y, z]}, file not found");
  std::vector<Landmark> landmarks = read_landmarks(lm_path, registration_landmarks());
  for (auto& l : landmarks) l.target *= a.scan_unit_mm;
  RegistrationSetup scan_setup = setup;
  RegistrationOptions& scan_options = scan_setup.options;
  if (a.start_from_truth == "mesh") {
    const fs::path truth = db / "truth" / (id + ".ply");
    if (!fs::exists(truth))
      throw InputError(truth.string() + ": --start-from-truth needs the true mesh, not found");
    scan_options.start_vertices = read_mesh(truth).V;
  } else if (a.start_from_truth == "pose") {
    const fs::path truth = db / "truth" / (id + ".pose.csv");
    if (!fs::exists(truth))
      throw InputError(truth.string() + ": --start-from-truth needs the true pose, not found");
    scan_options.start_pose = read_pose_csv(truth, tpl.skeleton.names);
  }
  const RegistrationJobResult job = run_registration_job(
      tpl, scan_setup, scan, landmarks, scan_path.string(),
      [&](double f, std::string_view) { return progress(f), true; });
  const RegistrationResult& r = job.registration;
  const RegistrationSummary& s = job.summary;
  PoseRecord rec;
  rec.scale = r.pose.scale;
  rec.pose = r.pose.pose;
  write_mesh(out / (id + ".ply"), r.V, tpl.mesh.F);
  write_pose_csv(out / (id + ".pose.csv"), tpl.skeleton.names, rec);
  const std::vector<char> local = locally_folded_triangles(r.V, r.rest.V, tpl.mesh.F);
  std::string shape_cols = ",0,0,,,,,,,";
  if (!r.shape && r.shape_coefficients.size() > 0) {  // a model's space: no sliders
    write_text_file(out / (id + ".shape.json"), registration_shape_json(r));
    shape_cols = fmt::format(",{},{:.2f},,,,,,,", s.shape_rounds, s.shape_seconds);
  }
  if (r.shape) {
    const MacroSettings& m = *r.shape;
    write_text_file(out / (id + ".shape.json"), registration_shape_json(r));
    shape_cols = fmt::format(",{},{:.2f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f}",
                             s.shape_rounds, s.shape_seconds, m.gender, m.age, m.muscle,
                             m.weight, m.height, m.proportions, m.cup);
  }
  write_text_file(
      out / (id + ".summary.csv"),
      fmt::format("{},{},{},{},{},{:.4f},{:.4f},{:.6f},{},{:.4f},{:.4f},{},{},{:.2f},{:.2f},"
                  "{:.2f},{:.3f},{},{}{},{},{:.3f}\n",
                  csv_field(id), scan.P.rows(), s.scan.normals_estimated ? 1 : 0, landmarks.size(),
                  s.pose.icp_iterations, s.pose.rms, s.pose.landmark_rms, r.pose.scale,
                  s.nonrigid.iterations, s.nonrigid.data_rms, s.nonrigid.landmark_rms,
                  s.nonrigid.matched_vertices, s.nonrigid.plane_matches, s.pose.seconds,
                  s.nonrigid.seconds, s.seconds, s.pose.two_sided_mm,
                  job.pose_joints, s.folded_triangles, shape_cols,
                  std::count(local.begin(), local.end(), 1), job.untangle.max_displacement));
  return s.scan.normals_estimated ? id + ": the scan has no normals; estimated them (unoriented)"
                                  : std::string();
}

}  // namespace

namespace {

void add_register_options(CLI::App* cmd, RegisterArgs& a) {
  cmd->add_option("db", a.db, "Scan database folder (scans.csv, scans/)")->required();
  cmd->add_option("--out", a.out, "Output folder")->required();
  cmd->add_option("--jobs", a.jobs, "Scans registered in parallel")->capture_default_str();
  cmd->add_option("--shard", a.shard,
                  "i/n: register only scans whose position k in scans.csv has k mod n = i "
                  "(0 ≤ i < n)");
  cli::add_registration_flags(cmd, a.job, a.no);
  cmd->add_option("--transform-length", a.job.transform_length,
                  "Length (mm) normalising the affine transforms (balances Es's linear and "
                  "translation parts)")
      ->capture_default_str();
  cmd->add_option("--scan", a.scan, "Register only this scan id");
  cmd->add_option("--scan-unit-mm", a.scan_unit_mm,
                  "Millimetres per scan unit (1000 for scans in metres)")
      ->capture_default_str();
  cmd->add_option("--pose-joints", a.job.pose_joints,
                  "Pose-fit joints: 'segment' (one rotation per body segment, twist bones, "
                  "finger grasp), 'bone' (every spine, neck, arm and leg bone a free ball "
                  "joint; finger grasp as in 'segment') or 'best' (both, keeping the fit closer "
                  "to the scan)")
      ->check(CLI::IsMember({"segment", "bone", "best"}))
      ->capture_default_str();
  cmd->add_option("--hand-stage", a.hand_stage,
                  "Fingers: 'on' fits the wrists again, then one grasp per hand, one curl per "
                  "finger and the thumbs, after the body (hand_stage_pose_parameters); 'off' "
                  "one grasp rotation per hand, fitted with the body")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  cmd->add_flag("--proportions-with-shape", a.job.proportions_with_shape,
                "With the shape fit, also stretch the shaped body's segments to the landmark "
                "distances");
  cmd->add_option("--start-from-truth", a.start_from_truth,
                  "Evaluation only (synthetic databases): skip the pose fit and start the "
                  "non-rigid fit from DB/truth/<id>.ply ('mesh': measures the non-rigid stage's "
                  "own drift) or from the template posed with DB/truth/<id>.pose.csv ('pose')")
      ->check(CLI::IsMember({"mesh", "pose"}));
  cmd->add_flag("--repair-local-folds", a.repair_local_folds,
                "After the fold repair against the posed template, also re-solve local folds "
                "(a triangle facing against its 2-ring, unlike at rest: the posed template's own "
                "skinning creases) from the rest template's shape (registration/"
                "local_fold_repair.h; on for real bodies, off by default so the synthetic "
                "database's figures stay as measured)");
  cmd->add_flag("--force", a.force,
                "Register again scans that are already done; replace the results in OUT made with other settings "
                "(without it such a folder is refused)");
}

void run_register(RegisterArgs& a) {
  const fs::path db = a.db, out = a.out;
  if (!fs::is_directory(db))
    throw InputError("'" + a.db + "': expected a scan database folder, it does not exist");
  if (a.jobs < 1) throw InputError("--jobs must be at least 1, got " + std::to_string(a.jobs));
  if (!(a.scan_unit_mm > 0) || !std::isfinite(a.scan_unit_mm))
    throw InputError(fmt::format("--scan-unit-mm must be a positive number, got {}", a.scan_unit_mm));
  cli::apply_registration_flags(a.job, a.no);
  a.job.hand_stage = a.hand_stage == "on";
  a.job.folds = a.repair_local_folds ? FoldRepair::local : FoldRepair::keep;
  validate(a.job);
  const std::vector<std::string> ids = selected_scan_ids(db / "scans.csv", a.scan, a.shard);
  // Every setting that changes a registration, and the database by content: a rerun with other
  // settings is refused instead of keeping the earlier results (tools/pipeline/folder_settings.h).
  nlohmann::json settings = {
      {"verb", "register"},          {"database", file_fingerprint(db / "scans.csv")},
      {"schedule", a.job.schedule},     {"fast_steps", a.job.fast_steps},
      {"fast_stiffness_end", a.job.fast_k_end}, {"transform_length", a.job.transform_length},
      {"scan_unit_mm", a.scan_unit_mm},     {"pose_only", a.job.pose_only},
      {"pose_joints", a.job.pose_joints},       {"hand_stage", a.hand_stage},
      {"shape_fit", a.job.shape_fit},       {"proportions", a.job.proportions},
      {"proportions_with_shape", a.job.proportions_with_shape}, {"start_from_truth", a.start_from_truth},
      {"repair_local_folds", a.repair_local_folds}};
  // The untangling of local folds changed these results and added columns to registration.csv:
  // such a folder registered before it is refused (or replaced with --force), not mixed.
  if (a.repair_local_folds) settings["untangle_folds"] = true;
  add_shared_registration_settings(settings, a.job, a.no);
  ResumableFolder folder(out, "register.json", settings, a.force,
                         outputs_named({"registration.csv", "evaluation.csv"},
                                       {".ply", ".pose.csv", ".shape.json", ".summary.csv"}));
  folder.open();
  BatchJobs batch({"scan", "scans", "registered", a.jobs, a.force}, ids);
  const size_t todo = batch.skip_done([&](size_t k) {
    return fs::exists(out / (ids[k] + ".ply")) && fs::exists(out / (ids[k] + ".pose.csv")) &&
           fs::exists(out / (ids[k] + ".summary.csv"));
  }, a.out);
  if (todo == 0) {
    rebuild_registration_csv(out);
    return;
  }

  const RegistrationSetup setup = registration_setup(a.job);
  const RegistrationTemplate tpl = registration_template(a.job);
  batch.run(fmt::format("register {} scans", todo), [&](size_t k, const std::function<void(double)>& progress) {
    return register_database_scan(a, tpl, setup, db, out, ids[k], progress);
  });
  rebuild_registration_csv(out);
  batch.throw_if_failed();
}

}  // namespace

BODYMODEL_VERB(add_register_verb) {
  auto a = std::make_shared<RegisterArgs>();
  auto* cmd = app.add_subcommand(
      "register",
      "Register the template to every scan of a scan database (Hasler et al. 2009 §2):\n"
      "skeleton pose fit (scale, global motion, joint rotations) alternated with a fit of\n"
      "MakeHuman's macro sliders (the template's shape), then non-rigid fit.\n"
      "Writes OUT/<id>.ply (template topology, mm), OUT/<id>.pose.csv, OUT/<id>.shape.json,\n"
      "OUT/registration.csv.\n"
      "Scans already registered are skipped (rerun or split into shards freely); a failed scan\n"
      "is reported and skipped. Never reads DB/truth/ (except --start-from-truth, a diagnosis).");
  add_register_options(cmd, *a);
  cmd->callback([a] { run_register(*a); });
}

}  // namespace bodymodel
