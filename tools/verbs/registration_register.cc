// bodymodel register DB/ --out REG/ [--jobs N] [--shard i/n] [--schedule paper|fast] [--scan ID]
//
// Registers the template (MakeHuman default body, its skeleton and weights) to every scan of a
// scan database (DB/scans.csv, DB/scans/<id>.ply, DB/scans/<id>.landmarks.json). Writes
// REG/<id>.ply (template topology, mm), REG/<id>.pose.csv, REG/<id>.shape.json (the fitted
// MakeHuman macro sliders, unless --no-shape-fit) and REG/registration.csv. Never reads
// DB/truth/ (except the --start-from-truth diagnosis).
#include <fmt/format.h>

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
#include "registration/fit_check.h"
#include "registration/local_fold_repair.h"
#include "registration/register_scan.h"
#include "tools/console.h"
#include "tools/pipeline/batch_jobs.h"
#include "tools/pipeline/folder_settings.h"
#include "tools/pipeline/registration_setup.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct RegisterArgs {
  std::string db, out, schedule = "fast", shard, scan, pose_joints = "segment";
  int jobs = 1;
  int fast_steps = NonrigidOptions{}.fast_steps;
  double fast_k_end = NonrigidOptions{}.fast_k_end;
  double transform_length = NonrigidOptions{}.normalization_length;
  double scan_unit_mm = 1.0;
  std::string start_from_truth;  // evaluation only: "", "mesh" or "pose"
  bool force = false, pose_only = false, no_proportions = false, no_shape_fit = false;
  bool proportions_with_shape = false, repair_local_folds = false;
  std::string hand_stage = "on";  // finger curls and thumbs fitted after the body (hand stage)
};

std::vector<std::string> read_scan_ids(const fs::path& csv) {
  const std::vector<CsvRecord> rows = read_csv_file(csv);
  std::vector<std::string> ids;
  for (size_t r = 0; r < rows.size(); ++r) {
    if (r == 0) {
      if (rows[r].fields[0] != "scan_id")
        throw InputError(csv.string() + ":" + std::to_string(rows[r].line) +
                         ": expected a header starting with 'scan_id', found '" + csv_row(rows[r].fields) + "'");
      continue;
    }
    const std::string& id = rows[r].fields[0];
    // The id names files read (DB/scans/<id>.ply) and written (OUT/<id>.ply): one plain name.
    check_file_name(id, csv.string() + ":" + std::to_string(rows[r].line), "scan id");
    ids.push_back(id);
  }
  return ids;
}

// Per-scan summary row of registration.csv.
std::string summary_header() {
  return "scan_id,points,normals_estimated,landmarks,pose_icp_iterations,pose_rms_mm,"
         "pose_landmark_rms_mm,scale,nonrigid_iterations,data_rms_mm,landmark_rms_mm,"
         "matched_vertices,plane_matches,pose_seconds,nonrigid_seconds,seconds,pose_two_sided_mm,"
         "pose_joints,folded_triangles_repaired,shape_rounds,shape_seconds,shape_gender,shape_age,"
         "shape_muscle,shape_weight,shape_height,shape_proportions,shape_cup\n";
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
  cmd->add_option("db", a->db, "Scan database folder (scans.csv, scans/)")->required();
  cmd->add_option("--out", a->out, "Output folder")->required();
  cmd->add_option("--jobs", a->jobs, "Scans registered in parallel")->capture_default_str();
  cmd->add_option("--shard", a->shard,
                  "i/n: register only scans whose position k in scans.csv has k mod n = i "
                  "(0 ≤ i < n)");
  cmd->add_option("--schedule", a->schedule,
                  "Non-rigid stiffness schedule: 'paper' (1500 steps, §2.3) or 'fast'")
      ->check(CLI::IsMember({"paper", "fast"}))
      ->capture_default_str();
  cmd->add_option("--fast-steps", a->fast_steps, "Steps of the fast schedule")
      ->capture_default_str();
  cmd->add_option("--fast-stiffness-end", a->fast_k_end,
                  "Final smoothness weight β of the fast schedule (starts at k0 = 3000)")
      ->capture_default_str();
  cmd->add_option("--transform-length", a->transform_length,
                  "Length (mm) normalising the affine transforms (balances Es's linear and "
                  "translation parts)")
      ->capture_default_str();
  cmd->add_option("--scan", a->scan, "Register only this scan id");
  cmd->add_option("--scan-unit-mm", a->scan_unit_mm,
                  "Millimetres per scan unit (1000 for scans in metres)")
      ->capture_default_str();
  cmd->add_flag("--pose-only", a->pose_only, "Stop after the skeleton pose fit");
  cmd->add_option("--pose-joints", a->pose_joints,
                  "Pose-fit joints: 'segment' (one rotation per body segment, twist bones, "
                  "finger grasp), 'bone' (every spine, neck, arm and leg bone a free ball "
                  "joint; finger grasp as in 'segment') or 'best' (both, keeping the fit closer "
                  "to the scan)")
      ->check(CLI::IsMember({"segment", "bone", "best"}))
      ->capture_default_str();
  cmd->add_option("--hand-stage", a->hand_stage,
                  "Fingers: 'on' fits the wrists again, then one grasp per hand, one curl per "
                  "finger and the thumbs, after the body (hand_stage_pose_parameters); 'off' "
                  "one grasp rotation per hand, fitted with the body")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  cmd->add_flag("--no-proportions", a->no_proportions,
                "Keep the template's limb proportions (global scale only) instead of stretching "
                "its segments to the landmark distances");
  cmd->add_flag("--no-shape-fit", a->no_shape_fit,
                "Keep the default MakeHuman body's shape (global scale and landmark proportions "
                "only) instead of fitting the macro sliders (gender, age, muscle, weight, "
                "height, proportions, cup) in the pose stage");
  cmd->add_flag("--proportions-with-shape", a->proportions_with_shape,
                "With the shape fit, also stretch the shaped body's segments to the landmark "
                "distances");
  cmd->add_option("--start-from-truth", a->start_from_truth,
                  "Evaluation only (synthetic databases): skip the pose fit and start the "
                  "non-rigid fit from DB/truth/<id>.ply ('mesh': measures the non-rigid stage's "
                  "own drift) or from the template posed with DB/truth/<id>.pose.csv ('pose')")
      ->check(CLI::IsMember({"mesh", "pose"}));
  cmd->add_flag("--repair-local-folds", a->repair_local_folds,
                "After the fold repair against the posed template, also re-solve local folds "
                "(a triangle facing against its 2-ring, unlike at rest: the posed template's own "
                "skinning creases) from the rest template's shape (registration/"
                "local_fold_repair.h; on for real bodies, off by default so the synthetic "
                "database's figures stay as measured)");
  cmd->add_flag("--force", a->force,
                "Register again scans that are already done; replace the results in OUT made with other settings "
                "(without it such a folder is refused)");
  cmd->callback([a] {
    const fs::path db = a->db, out = a->out;
    if (!fs::is_directory(db))
      throw InputError("'" + a->db + "': expected a scan database folder, it does not exist");
    if (a->jobs < 1) throw InputError("--jobs must be at least 1, got " + std::to_string(a->jobs));
    if (!(a->scan_unit_mm > 0))
      throw InputError("--scan-unit-mm must be positive");
    if (a->fast_steps < 1) throw InputError("--fast-steps must be at least 1");
    if (!(a->fast_k_end > 0) || !(a->transform_length > 0))
      throw InputError("--fast-stiffness-end and --transform-length must be positive");
    std::vector<std::string> ids = read_scan_ids(db / "scans.csv");
    if (!a->scan.empty()) {
      if (std::find(ids.begin(), ids.end(), a->scan) == ids.end())
        throw InputError("--scan " + a->scan + ": no such scan in " + (db / "scans.csv").string());
      ids = {a->scan};
    }
    if (!a->shard.empty()) {
      int i = -1, n = 0;
      char slash = 0;
      std::istringstream ss(a->shard);
      if (!(ss >> i >> slash >> n) || slash != '/' || n < 1 || i < 0 || i >= n || !ss.eof())
        throw InputError("--shard must be i/n with 0 <= i < n, got '" + a->shard + "'");
      std::vector<std::string> mine;
      for (size_t k = 0; k < ids.size(); ++k)
        if (int(k % n) == i) mine.push_back(ids[k]);
      ids = mine;
    }
    // Every setting that changes a registration, and the database by content: a rerun with other
    // settings is refused instead of keeping the earlier results (tools/pipeline/folder_settings.h).
    const nlohmann::json settings = {
        {"verb", "register"},          {"database", file_fingerprint(db / "scans.csv")},
        {"schedule", a->schedule},     {"fast_steps", a->fast_steps},
        {"fast_stiffness_end", a->fast_k_end}, {"transform_length", a->transform_length},
        {"scan_unit_mm", a->scan_unit_mm},     {"pose_only", a->pose_only},
        {"pose_joints", a->pose_joints},       {"hand_stage", a->hand_stage},
        {"shape_fit", !a->no_shape_fit},       {"proportions", !a->no_proportions},
        {"proportions_with_shape", a->proportions_with_shape}, {"start_from_truth", a->start_from_truth},
        {"repair_local_folds", a->repair_local_folds}};
    ResumableFolder folder(out, "register.json", settings, a->force,
                           outputs_named({"registration.csv", "evaluation.csv"},
                                         {".ply", ".pose.csv", ".shape.json", ".summary.csv"}));
    folder.open();
    BatchJobs batch({"scan", "scans", "registered", a->jobs, a->force}, ids);
    const size_t todo = batch.skip_done([&](size_t k) {
      return fs::exists(out / (ids[k] + ".ply")) && fs::exists(out / (ids[k] + ".pose.csv")) &&
             fs::exists(out / (ids[k] + ".summary.csv"));
    }, a->out);
    if (todo == 0) {
      rebuild_registration_csv(out);
      return;
    }

    RegistrationSetup setup = makehuman_registration_setup(
        {a->schedule, a->fast_steps, a->fast_k_end, a->pose_only, a->no_proportions, a->no_shape_fit});
    const RegistrationTemplate& tpl = setup.tpl;
    RegistrationOptions& options = setup.options;
    options.nonrigid.normalization_length = a->transform_length;
    options.proportions_with_shape = a->proportions_with_shape;
    if (a->pose_joints == "bone") options.pose.parameters = bone_pose_parameters();
    if (a->pose_joints == "segment") options.pose.parameters = segment_pose_parameters();
    if (a->pose_joints == "best") {
      options.pose.parameters = segment_pose_parameters();
      options.pose_alternatives.push_back(options.pose);
      options.pose_alternatives.back().parameters = bone_pose_parameters();
    }
    if (a->hand_stage == "on") {
      if (options.pose.parameters.empty()) options.pose.parameters = default_pose_parameters();
      options.pose.parameters = with_hand_stage(options.pose.parameters);
      for (auto& alt : options.pose_alternatives) alt.parameters = with_hand_stage(alt.parameters);
    }

    std::vector<std::string> pose_joint_names = {a->pose_joints, "bone"};
    if (a->pose_joints == "best") pose_joint_names[0] = "segment";
    batch.run(fmt::format("register {} scans", todo), [&](size_t k, const auto& progress) {
      const std::string& id = ids[k];
      const fs::path scan_path = db / "scans" / (id + ".ply");
      const fs::path lm_path = db / "scans" / (id + ".landmarks.json");
      PointCloud scan = read_point_cloud(scan_path);
      if (a->scan_unit_mm != 1.0) scan.P *= a->scan_unit_mm;
      if (!fs::exists(lm_path))
        throw InputError(lm_path.string() +
                         ": expected the scan's landmarks {name: [x, y, z]}, file not found");
      std::vector<Landmark> landmarks = read_landmarks(lm_path, body_landmarks());
      for (auto& l : landmarks) l.target *= a->scan_unit_mm;
      RegistrationSummary s;
      auto report = [&](double f, std::string_view) {
        progress(f);
        return true;
      };
      RegistrationOptions scan_options = options;
      if (a->start_from_truth == "mesh") {
        const fs::path truth = db / "truth" / (id + ".ply");
        if (!fs::exists(truth))
          throw InputError(truth.string() + ": --start-from-truth needs the true mesh, not found");
        scan_options.start_vertices = read_mesh(truth).V;
      } else if (a->start_from_truth == "pose") {
        const fs::path truth = db / "truth" / (id + ".pose.csv");
        if (!fs::exists(truth))
          throw InputError(truth.string() + ": --start-from-truth needs the true pose, not found");
        scan_options.start_pose = read_pose_csv(truth, tpl.skeleton.names);
      }
      RegistrationResult r =
          register_scan(tpl, scan, landmarks, scan_options, scan_path.string(), &s, report);
      if (a->repair_local_folds && !a->pose_only) repair_local_folds(r.V, r.rest.V, tpl.mesh.F);
      // Not a body (a sphere), or landmarks not its own: failed, nothing written.
      if (!a->pose_only) {
        const FitCheck fc = check_registration_fit(r.V, r.pose.V, r.rest.V, tpl.mesh.F, scan);
        if (!fc.plausible) throw InputError(scan_path.string() + ": registration failed: " + fc.reason);
      }
      PoseRecord rec;
      rec.scale = r.pose.scale;
      rec.pose = r.pose.pose;
      write_mesh(out / (id + ".ply"), r.V, tpl.mesh.F);
      write_pose_csv(out / (id + ".pose.csv"), tpl.skeleton.names, rec);
      std::string shape_cols = ",0,0,,,,,,,";
      if (r.shape) {
        const MacroSettings& m = *r.shape;
        write_text_file(out / (id + ".shape.json"), json_text(m.to_json(), 2) + "\n");
        shape_cols = fmt::format(",{},{:.2f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f}",
                                 s.shape_rounds, s.shape_seconds, m.gender, m.age, m.muscle,
                                 m.weight, m.height, m.proportions, m.cup);
      }
      write_text_file(
          out / (id + ".summary.csv"),
          fmt::format("{},{},{},{},{},{:.4f},{:.4f},{:.6f},{},{:.4f},{:.4f},{},{},{:.2f},{:.2f},"
                      "{:.2f},{:.3f},{},{}{}\n",
                      csv_field(id), scan.P.rows(), s.scan.normals_estimated ? 1 : 0, landmarks.size(),
                      s.pose.icp_iterations, s.pose.rms, s.pose.landmark_rms, r.pose.scale,
                      s.nonrigid.iterations, s.nonrigid.data_rms, s.nonrigid.landmark_rms,
                      s.nonrigid.matched_vertices, s.nonrigid.plane_matches, s.pose.seconds,
                      s.nonrigid.seconds, s.seconds, s.pose.two_sided_mm,
                      pose_joint_names[s.pose_choice], s.folded_triangles, shape_cols));
      return s.scan.normals_estimated ? id + ": the scan has no normals; estimated them (unoriented)"
                                      : std::string();
    });
    rebuild_registration_csv(out);
    batch.throw_if_failed();
  });
}

}  // namespace bodymodel
