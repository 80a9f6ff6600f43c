// bodymodel register-mesh MESH... --landmarks LM.json --out REG/ [--scale 1000] [--detail]
//
// Registers the template (MakeHuman default body, its skeleton and weights) to meshes of any
// topology — a captured sequence, a reconstruction — with landmarks placed once as vertex
// indices of the mesh and reused for every mesh of the same topology. Writes REG/<stem>.ply
// (template topology, mm), REG/<stem>.pose.csv and REG/register-mesh.csv (per mesh: two-sided
// surface distance to the mesh, folded triangles, time); with --detail also the detail offsets
// REG/<stem>.detail.npz and the detailed mesh REG/<stem>.detailed.ply.
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/json_text.h"
#include "core/io/mesh_io.h"
#include "core/landmarks.h"
#include "core/up_axis.h"
#include <nlohmann/json.hpp>
#include "registration/detail_transfer.h"
#include "registration/job.h"
#include "registration/mesh_scan.h"
#include "registration/metrics.h"
#include "core/io/pose_csv.h"
#include "tools/console.h"
#include "tools/pipeline/batch_jobs.h"
#include "tools/pipeline/folder_settings.h"
#include "tools/verb.h"
#include "tools/verbs/register_common.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct RegisterMeshArgs {
  RegistrationJobOptions job = [] {
    RegistrationJobOptions o;
    // Stiffer end than `register`: a captured mesh has less detail than the template, and a
    // softer end folds its eyelids and armpits (docs/real-registration.md).
    o.fast_k_end = 3.0;
    o.folds = FoldRepair::full;
    return o;
  }();
  cli::NegatedRegistrationFlags no;
  std::vector<std::string> meshes;
  std::string landmarks, out, up = "y", hand_stage = "on";
  double scale = 1.0;
  int jobs = 1, samples = MeshScanOptions{}.samples;
  bool force = false, detail = false, keep_folds = false, rest = false;
};

std::string csv_header() {
  return "mesh,scan_points,landmarks,scale,pose_icp_iterations,pose_rms_mm,nonrigid_iterations,"
         "data_rms_mm,landmark_rms_mm,registered_to_scan_mm,scan_to_registered_mm,"
         "two_sided_mm,registered_to_scan_p95_mm,scan_to_registered_p95_mm,folded_triangles,"
         "flipped_against_scan,detail_scan_to_registered_mm,seconds,local_folds,untangle_max_mm\n";
}

void rebuild_csv(const fs::path& out) {
  std::vector<fs::path> parts;
  for (const auto& e : fs::directory_iterator(out)) {
    const std::string s = e.path().filename().string();
    if (s.size() > 18 && s.compare(s.size() - 18, 18, ".register-mesh.csv") == 0)
      parts.push_back(e.path());
  }
  std::sort(parts.begin(), parts.end());
  std::string s = csv_header();
  for (const auto& p : parts) s += read_text_file(p);
  write_text_file(out / "register-mesh.csv", s);
}

// Registers one mesh and writes its outputs; returns a line for the log.
std::string register_one_mesh(const RegisterMeshArgs& a, const RegistrationTemplate& tpl,
                              const RegistrationSetup& setup, const Eigen::Matrix3d& up, const fs::path& out,
                              const std::string& path, const std::string& stem,
                              const std::function<void(double)>& progress) {
  Mesh mesh = read_mesh(path);
  // Landmarks given as [x, y, z] are in the mesh's own units and axes, like its vertices.
  std::vector<Landmark> landmarks = read_mesh_landmarks(a.landmarks, registration_landmarks(), mesh.V);
  mesh.V = to_project_frame(mesh.V, a.scale, up);
  for (Landmark& l : landmarks) l.target = a.scale * (up * l.target);
  MeshScanOptions so;
  so.samples = a.samples;
  PointCloud scan = mesh_to_scan(mesh, so, path);
  const PointCloud scan_copy = scan;
  const RegistrationJobResult job = run_registration_job(
      tpl, setup, scan, landmarks, path,
      [&](double f, std::string_view) { return progress(0.9 * f), true; });  // the rest: distances, writing
  const RegistrationResult& r = job.registration;
  const RegistrationSummary& s = job.summary;
  const MeshScanDistance d = mesh_scan_distance(r.V, tpl.mesh.F, mesh, &r.pose.V);
  const std::vector<char> local = locally_folded_triangles(r.V, r.rest.V, tpl.mesh.F);
  const int local_folds = int(std::count(local.begin(), local.end(), 1));
  double detail_distance = -1;
  if (a.detail) {
    const SurfaceDetail detail = capture_detail(r.V, tpl.mesh.F, scan_copy);
    const Mesh detailed = apply_detail(r.V, tpl.mesh.F, detail);
    detail_distance = mesh_scan_distance(detailed.V, detailed.F, mesh).scan_to_registered_mean;
    write_detail(out / (stem + ".detail.npz"), detail, tpl.mesh.F);
    write_mesh(out / (stem + ".detailed.ply"), detailed);
  }
  PoseRecord rec;
  rec.scale = r.pose.scale;
  rec.pose = r.pose.pose;
  write_mesh(out / (stem + ".ply"), r.V, tpl.mesh.F);
  if (a.rest) write_mesh(out / (stem + ".rest.ply"), unpose_registration(r, tpl.weights), tpl.mesh.F);
  write_pose_csv(out / (stem + ".pose.csv"), tpl.skeleton.names, rec);
  if (r.shape || r.shape_coefficients.size() > 0) write_text_file(out / (stem + ".shape.json"), registration_shape_json(r));
  write_text_file(
      out / (stem + ".register-mesh.csv"),
      fmt::format("{},{},{},{:.6f},{},{:.4f},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},"
                  "{:.4f},{},{},{:.4f},{:.2f},{},{:.3f}\n",
                  csv_field(stem), scan.P.rows(), landmarks.size(), r.pose.scale, s.pose.icp_iterations,
                  s.pose.rms, s.nonrigid.iterations, s.nonrigid.data_rms, s.nonrigid.landmark_rms,
                  d.registered_to_scan_mean, d.scan_to_registered_mean, d.two_sided_mean,
                  d.registered_to_scan_p95, d.scan_to_registered_p95, d.folded_triangles,
                  d.flipped_against_scan, detail_distance, s.seconds, local_folds,
                  job.untangle.max_displacement));
  return fmt::format("{}: two-sided distance {:.2f} mm (registered→scan {:.2f}, "
                     "scan→registered {:.2f}), {} folded triangles, {} local folds, {:.0f} s",
                     stem, d.two_sided_mean, d.registered_to_scan_mean,
                     d.scan_to_registered_mean, d.folded_triangles, local_folds, s.seconds);
}

}  // namespace

namespace {

void add_register_mesh_options(CLI::App* cmd, RegisterMeshArgs& a) {
  cmd->add_option("meshes", a.meshes, "Scan meshes (OBJ/PLY/OFF), any topology")->required();
  cmd->add_option("--landmarks", a.landmarks,
                  "JSON {name: vertex index (0-based, of the scan mesh) or [x, y, z] in the mesh's units "
                  "and axes}; names as "
                  "in the template's landmark table (head_top, l_knee, ...)")
      ->required();
  cmd->add_option("--out", a.out, "Output folder")->required();
  cmd->add_option("--scale", a.scale,
                  "Millimetres per mesh unit (1000 for meshes in metres)")
      ->capture_default_str();
  cmd->add_option("--up", a.up,
                  "Axis the body stands along in the meshes (x, y, z, -x, -y, -z), rotated onto "
                  "+y before registering (SCAPE: x); the outputs are in that frame, mm")
      ->capture_default_str();
  cli::add_registration_flags(cmd, a.job, a.no);
  cmd->add_option("--samples", a.samples,
                  "Surface samples drawn on each mesh for the registration (besides its vertices)")
      ->capture_default_str();
  cmd->add_option("--jobs", a.jobs, "Meshes registered in parallel")->capture_default_str();
  cmd->add_flag("--detail", a.detail,
                "Detail transfer: also write OUT/<stem>.detail.npz (normal offsets of the "
                "mid-edge subdivision, per triangle) and OUT/<stem>.detailed.ply");
  cmd->add_flag("--rest", a.rest,
                "Also write OUT/<stem>.rest.ply: the registration carried back to the template's rest pose by "
                "inverting the skinning of its fitted pose (the person's size kept): what `build` makes a shape "
                "model of, e.g. in the model loop (workflow/bootstrap.smk)");
  cmd->add_flag("--keep-folds", a.keep_folds,
                "Do not smooth away triangles the non-rigid fit folded over (where the template "
                "is finer than the mesh: eyelids, armpits), neither against the posed template "
                "nor local folds (a triangle facing against its 2-ring, unlike at rest)");
  cmd->add_option("--hand-stage", a.hand_stage, "As `register --hand-stage`: 'on' fits the wrists again, then one grasp per hand, one curl per finger and the "
                  "thumbs, after the body; 'off' one grasp rotation per hand, fitted with the body")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  cmd->add_option("--pose-iterations", a.job.pose_iterations,
                  "ICP iterations of the pose fit (0: landmarks only)")
      ->capture_default_str();
  cmd->add_flag("--force", a.force,
                "Register again meshes that are already done; replace the results in OUT made with other settings "
                "(without it such a folder is refused)");
}

void run_register_mesh(RegisterMeshArgs& a) {
  if (!(a.scale > 0) || !std::isfinite(a.scale))
    throw InputError("--scale must be a positive number of millimetres per mesh unit, got " +
                     fmt::format("{}", a.scale));
  if (a.jobs < 1) throw InputError("--jobs must be at least 1, got " + std::to_string(a.jobs));
  cli::apply_registration_flags(a.job, a.no);
  if (a.keep_folds) a.job.folds = FoldRepair::keep;
  a.job.hand_stage = a.hand_stage == "on";
  validate(a.job);
  const Eigen::Matrix3d up = up_axis_rotation(a.up, "--up");
  if (a.samples < 0) throw InputError("--samples must not be negative");
  const fs::path out = a.out;
  std::vector<std::string> stems;
  for (const auto& m : a.meshes) {
    if (!fs::is_regular_file(m))
      throw InputError("'" + m + "': expected a mesh file (OBJ/PLY/OFF), it does not exist");
    const std::string stem = fs::path(m).stem().string();
    if (std::find(stems.begin(), stems.end(), stem) != stems.end())
      throw InputError("'" + m + "': two meshes share the name '" + stem +
                       "'; their outputs would overwrite each other");
    stems.push_back(stem);
  }
  if (!fs::is_regular_file(a.landmarks))
    throw InputError("--landmarks '" + a.landmarks + "': file not found");
  // Every setting that changes a registration, the landmarks by content: a rerun with other
  // settings is refused instead of keeping the earlier results (tools/pipeline/folder_settings.h).
  nlohmann::json settings = {
      {"verb", "register-mesh"}, {"landmarks", file_fingerprint(a.landmarks)},
      {"scale", a.scale},       {"schedule", a.job.schedule},
      {"fast_steps", a.job.fast_steps}, {"fast_stiffness_end", a.job.fast_k_end},
      {"samples", a.samples},   {"detail", a.detail},
      {"pose_only", a.job.pose_only}, {"keep_folds", a.keep_folds},
      {"proportions", a.job.proportions}, {"shape_fit", a.job.shape_fit},
      {"pose_iterations", a.job.pose_iterations}, {"up", a.up}};
  settings["hand_stage"] = a.hand_stage;
  // The untangling of local folds changed the results and added columns to register-mesh.csv:
  // a folder registered before it is refused (or replaced with --force), not mixed.
  if (!a.keep_folds) settings["untangle_folds"] = true;
  add_shared_registration_settings(settings, a.job, a.no);
  if (a.rest) settings["rest"] = true;
  ResumableFolder folder(out, "register-mesh.json", settings, a.force,
                         outputs_named({"register-mesh.csv"}, {".ply", ".pose.csv", ".shape.json", ".register-mesh.csv",
                                                               ".detail.npz"}));
  folder.open();
  BatchJobs batch({"mesh", "meshes", "registered", a.jobs, a.force}, stems, a.meshes);
  const size_t todo = batch.skip_done([&](size_t k) {
    const std::string& s = stems[k];
    return fs::exists(out / (s + ".ply")) && fs::exists(out / (s + ".pose.csv")) &&
           fs::exists(out / (s + ".register-mesh.csv")) &&
           (!a.detail || fs::exists(out / (s + ".detail.npz"))) && (!a.rest || fs::exists(out / (s + ".rest.ply")));
  }, a.out);
  if (todo == 0) {
    rebuild_csv(out);
    return;
  }

  const RegistrationSetup setup = registration_setup(a.job);
  const RegistrationTemplate tpl = registration_template(a.job);
  batch.run(fmt::format("register {} meshes", todo), [&](size_t k, const std::function<void(double)>& progress) {
    return register_one_mesh(a, tpl, setup, up, out, a.meshes[k], stems[k], progress);
  });
  rebuild_csv(out);
  batch.throw_if_failed();
}

}  // namespace

BODYMODEL_VERB(add_register_mesh_verb) {
  auto a = std::make_shared<RegisterMeshArgs>();
  auto* cmd = app.add_subcommand(
      "register-mesh",
      "Register the template to meshes of any topology (e.g. a captured sequence), with\n"
      "landmarks placed once as vertex indices of the mesh and reused for every mesh:\n"
      "skeleton pose fit, then non-rigid fit to a dense sampling of the mesh (Hasler et al.\n"
      "2009 §2). Writes OUT/<stem>.ply (template topology, mm), OUT/<stem>.pose.csv and\n"
      "OUT/register-mesh.csv (two-sided surface distance to the mesh, folded triangles).\n"
      "Meshes already registered are skipped; a failed mesh is reported and skipped.\n"
      "Example (a sequence in metres):\n"
      "  bodymodel register-mesh frames/*.obj --landmarks lm.json --scale 1000 --out reg/");
  add_register_mesh_options(cmd, *a);
  cmd->callback([a] { run_register_mesh(*a); });
}

}  // namespace bodymodel
