// bodymodel build REG/ --subjects subjects.csv --out model.npz [--scale 1000]
// bodymodel build REG/ --db DB/ --out model.npz            (a synth-db database)
#include <fmt/format.h>

#include <filesystem>
#include <fmt/ranges.h>

#include "core/data_path.h"
#include "core/error.h"
#include "core/makehuman.h"
#include "model/database.h"
#include "model/generate_crowd.h"
#include "model/model_file.h"
#include "model/quantise.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

struct BuildArgs {
  std::string reg, db, subjects, out;
  double shape_variance = 0.995, full_variance = 0.99;
  int max_components = -1;
  bool no_rig = false;
  double scale = 1.0;
  std::string standard_pose = "standard";
  std::string up = "y";
  bool no_measure = false;
  bool first_mesh_faces = false;
  int quantise = 32;
  int parts = 0;
};

int axis_of(const std::string& s) {
  if (s == "x") return 0;
  if (s == "y") return 1;
  if (s == "z") return 2;
  throw InputError("--up must be x, y or z, got '" + s + "'");
}

}  // namespace

namespace {

void add_build_options(CLI::App* cmd, BuildArgs& a) {
  cmd->add_option("registered", a.reg, "Folder of registered meshes of one topology")->required();
  auto* db = cmd->add_option("--db", a.db, "synth-db database folder (scans.csv, subjects.csv, truth/)");
  auto* subj = cmd->add_option("--subjects", a.subjects, "CSV with columns mesh,subject,pose (+ label columns)");
  db->excludes(subj);
  subj->excludes(db);
  cmd->add_option("--out", a.out, "Output model (.npz)")->required();
  cmd->add_option("--scale", a.scale, "Millimetres per mesh unit (1000 for metres: FAUST, SCAPE); models are in mm")
      ->capture_default_str();
  cmd->add_option("--standard-pose", a.standard_pose,
                  "Pose name of each subject's standard-pose mesh (--subjects; a subject without one uses its "
                  "first listed mesh)")
      ->capture_default_str();
  cmd->add_option("--up", a.up, "Up axis of the meshes for the measured labels: x, y or z")->capture_default_str();
  cmd->add_flag("--no-measure", a.no_measure, "Do not measure height, weight and girths on the meshes");
  cmd->add_flag("--first-mesh-faces", a.first_mesh_faces,
                "With --subjects: the meshes share their vertices but not their triangles (SCAPE re-triangulates "
                "each pose): use the first mesh's triangles for all");
  cmd->add_option("--shape-variance", a.shape_variance,
                  "Fraction of variance the shape model's components keep")
      ->capture_default_str();
  cmd->add_option("--full-variance", a.full_variance,
                  "Fraction of variance the full model's components keep")
      ->capture_default_str();
  cmd->add_option("--components,--max-components", a.max_components,
                  "Keep at most this many components per model (-1: as many as the variance thresholds keep)")
      ->capture_default_str();
  cmd->add_option("--quantise", a.quantise,
                  "Store the PCA bases as 8- or 16-bit integers (32: float32). 20 random bodies decoded both ways "
                  "must agree within 0.5 mm, else 16 bits, then float32, are written (docs/model.md)")
      ->check(CLI::IsMember({8, 16, 32}))
      ->capture_default_str();
  cmd->add_option("--parts", a.parts,
                  "Also write a part-wise pose model: the triangles in this many parts (k-means of their rest "
                  "positions), each its own PCA of the full model's training encodings (0: none). Only `fit` and "
                  "`eval-model` read such a file (docs/model.md §5.4)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_flag("--no-rig", a.no_rig,
                "Do not attach the MakeHuman skeleton (pose morphing and region masks need it; only "
                "attached to MakeHuman-topology models)");
}

// The meshes and labels: a folder of registrations with a subjects table, or a scan database's
// registrations.
ModelBuildInput read_build_input(const BuildArgs& a) {
  ModelBuildInput in;
  cli::ProgressBar read_bar("reading");
  if (!a.subjects.empty()) {
    RegisteredFolderOptions ro;
    ro.mm_per_unit = a.scale;
    ro.standard_pose = a.standard_pose;
    ro.up_axis = axis_of(a.up);
    ro.measure_labels = !a.no_measure;
    ro.use_first_mesh_faces = a.first_mesh_faces;
    RegisteredFolderSummary rs;
    in = read_registered_folder(a.reg, a.subjects, ro, &rs, read_bar.callback());
    read_bar.finish(fmt::format("{} meshes of {} subjects", rs.meshes, rs.subjects));
    if (rs.meshes_with_other_faces > 0)
      cli::info(fmt::format("{} meshes had other triangles than the first: the first mesh's are used for all",
                            rs.meshes_with_other_faces));
    if (rs.subjects_without_standard_pose > 0)
      cli::info(fmt::format("{} of {} subjects have no mesh with pose '{}': their first listed mesh is their "
                            "standard pose",
                            rs.subjects_without_standard_pose, rs.subjects, a.standard_pose));
    if (!rs.measured_labels.empty())
      cli::info(fmt::format("measured on each subject's standard-pose mesh (up = {}, 1.01 kg/L): {}", a.up,
                            fmt::join(rs.measured_labels, ", ")));
    if (rs.measurement_failures > 0)
      cli::warn(fmt::format("{} subjects could not be measured (labels unknown), first: {}", rs.measurement_failures,
                            rs.first_measurement_failure));
    if (!rs.dropped_labels.empty())
      cli::info(fmt::format("labels dropped (fewer than two subjects with different values): {}",
                            fmt::join(rs.dropped_labels, ", ")));
  } else {
    DatabaseReadSummary rs;
    in = read_registered_database(a.reg, a.db, &rs, read_bar.callback());
    read_bar.finish(fmt::format("{} of {} scans ({} with pose labels)", rs.scans_read, rs.scans_listed,
                                rs.scans_with_pose_labels));
    if (!rs.missing.empty())
      cli::warn(fmt::format("{} scans listed in scans.csv have no mesh in {} (first: {}); built without them",
                            rs.missing.size(), a.reg, rs.missing[0]));
  }
  return in;
}

// The MakeHuman skeleton and its joint regressor, when the meshes have MakeHuman's topology.
void attach_rig(const BuildArgs& a, const ModelBuildInput& in, BodyModel& model) {
  const bool makehuman_topology = in.meshes.empty() || in.meshes[0].rows() == MakeHuman::kBodyVertexCount;
  if (!a.no_rig && !makehuman_topology) {
    cli::info(fmt::format("{} vertices, not MakeHuman's {}: no skeleton attached (pose morphing and region "
                          "masks unavailable; fit, generate and morph work)",
                          in.meshes[0].rows(), MakeHuman::kBodyVertexCount));
  } else if (!a.no_rig) {
    try {
      cli::info("attaching the MakeHuman skeleton (joint regressor fitted on random bodies)");
      ModelRigSummary rsum;
      model.rig = fit_makehuman_rig(MakeHuman::load(), {}, &rsum);
      model.metadata["rig_joint_error_mm"] = {{"mean", rsum.mean_joint_error_mm}, {"max", rsum.max_joint_error_mm}};
      cli::info(fmt::format("joint regressor error: mean {:.2f} mm, max {:.2f} mm", rsum.mean_joint_error_mm,
                            rsum.max_joint_error_mm));
    } catch (const InputError& e) {
      cli::warn(std::string("no skeleton attached (pose morphing and masks unavailable): ") + e.what());
    }
  }
}

// With --parts: the part-wise model of the full model's training samples (model/part_pca.h).
void attach_parts(const BuildArgs& a, const ModelBuildSummary& s, BodyModel& model) {
  if (a.parts <= 0) return;
  // The part-wise PCA sees the samples through the full model's coefficients: exact only when
  // it kept every component.
  if (s.full_pca.components < s.full_pca.samples - 1)
    cli::warn(fmt::format("--parts: the full model keeps {} of {} components, so the parts see the training meshes "
                          "only through them (use --full-variance 1 for the meshes themselves)",
                          s.full_pca.components, s.full_pca.samples - 1));
  model.parts = build_part_model(model.full.pca, *model.tmpl, a.parts);
  std::vector<int> triangles(model.parts.part_count(), 0), components(model.parts.part_count(), 0);
  for (int p : model.parts.triangle_part) ++triangles[p];
  for (int p : model.parts.component_part) ++components[p];
  model.metadata["parts"] = {{"count", model.parts.part_count()},
                             {"components", model.parts.pca.component_count()},
                             {"triangles", triangles},
                             {"part_components", components},
                             {"split", "k-means of the rest-pose triangle centroids"}};
  cli::info(fmt::format("part-wise model: {} parts of {} triangles, {} components ({})", model.parts.part_count(),
                        fmt::join(triangles, ", "), model.parts.pca.component_count(), fmt::join(components, ", ")));
}

void run_build(BuildArgs& a) {
  if (a.db.empty() && a.subjects.empty())
    throw InputError("build needs --subjects CSV (mesh,subject,pose) or --db DB/ to say which meshes to use");
  if (!(a.scale > 0) || !std::isfinite(a.scale))
    throw InputError(fmt::format("--scale must be a positive number of millimetres per mesh unit, got {}", a.scale));
  if (a.max_components == 0 || a.max_components < -1)
    throw InputError(fmt::format("--components must be ≥ 1 or -1, got {}", a.max_components));
  ModelBuildInput in = read_build_input(a);
  // A body in metres read as millimetres is 2 mm tall: say so before building nonsense labels.
  if (!in.meshes.empty()) {
    const Eigen::MatrixX3d& V = in.meshes[0];
    const double extent = (V.colwise().maxCoeff() - V.colwise().minCoeff()).maxCoeff();
    if (extent < 100)
      cli::warn(fmt::format("the first mesh is {:.3g} mm across after --scale {}: if the files are in metres, "
                            "use --scale 1000",
                            extent, a.scale));
  }
  ModelBuildOptions o;
  o.shape_pca.variance_threshold = a.shape_variance;
  o.full_pca.variance_threshold = a.full_variance;
  o.shape_pca.max_components = o.full_pca.max_components = a.max_components;
  o.allow_pose_only = !a.subjects.empty();
  cli::ProgressBar bar("build");
  ModelBuildSummary s;
  BodyModel model = build_body_model(in, o, &s, bar.callback());
  bar.finish();
  if (model.metadata.value("shape_model", "") == "full")
    cli::info("one subject: a pose model (the shape model is the full model)");
  else
    cli::info(fmt::format("shape model: {} subjects, {} components keep {:.2f}% of the variance (threshold {})",
                          s.shape_pca.samples, s.shape_pca.components, 100 * s.shape_pca.explained,
                          a.shape_variance));
  cli::info(fmt::format("full model:  {} meshes, {} components keep {:.2f}% of the variance (threshold {})",
                        s.full_pca.samples, s.full_pca.components, 100 * s.full_pca.explained,
                        a.full_variance));
  cli::info(fmt::format("labels: {} subject labels, {} joint-angle labels ({} never vary: dropped)",
                        in.subject_labels.size(), s.pose_labels_kept, s.pose_labels_dropped));
  attach_rig(a, in, model);
  attach_parts(a, s, model);
  namespace fs = std::filesystem;
  auto absolute = [](const std::string& p) { return fs::absolute(p).lexically_normal().string(); };
  if (!a.subjects.empty())
    model.metadata["source"] = {{"registered", absolute(a.reg)},
                                {"subjects", absolute(a.subjects)},
                                {"mm_per_unit", a.scale},
                                {"up_axis", a.up},
                                {"standard_pose", a.standard_pose},
                                {"first_mesh_faces", a.first_mesh_faces}};
  else
    model.metadata["source"] = {{"registered", a.reg}, {"database", a.db}, {"mm_per_unit", 1.0}};
  const ModelFileOptions storage = model_cli::choose_basis_storage(model, a.quantise, 64, 20, 0.5);
  // The training subjects' diversity every `generate` prints, measured once here on the model as
  // it is stored (so a crowd need not decode the subjects on every run).
  model.metadata["subject_diversity"] = subject_diversity_record(with_quantised_bases(model, storage), kDiversitySample);
  save_model(a.out, model, storage);
  cli::info("wrote " + a.out);
}

}  // namespace

BODYMODEL_VERB(add_model_build_verb) {
  auto a = std::make_shared<BuildArgs>();
  auto* cmd = app.add_subcommand(
      "build",
      "Build the statistical model (Hasler et al. 2009 §4) from registered meshes of one topology:\n"
      "encodes every mesh (relative rotation encoding), PCA of all meshes (full model: pose and\n"
      "shape) and of one standard-pose mesh per subject (shape-only model), semantic regression of\n"
      "every label, semantic basis. Writes an .npz (see model/model_file.h for its keys).\n"
      "Which meshes: --subjects CSV with columns mesh,subject,pose (mesh = file stem in REG/, .ply,\n"
      ".obj or .off; other columns are subject labels, a sex column female/male), or --db DB/ of\n"
      "`synth-db` (scans.csv, subjects.csv, joint rotations from DB/truth). With --subjects, height,\n"
      "weight (volume × 1.01 kg/L), volume and girths are measured on each subject's standard-pose\n"
      "mesh. One subject in many poses (SCAPE) gives a pose model (shape model = full model).\n"
      "Examples:\n"
      "  bodymodel build $BODYMODEL_DATA/faust-registrations --subjects faust.csv --scale 1000 \\\n"
      "      --standard-pose p0 --out faust.npz\n"
      "  bodymodel build DB/truth --db DB/ --out model.npz");
  add_build_options(cmd, *a);
  cmd->callback([a] { run_build(*a); });
}

}  // namespace bodymodel
