// bodymodel build REG/ --db DB/ --out model.npz
#include <fmt/format.h>

#include "core/data_path.h"
#include "core/error.h"
#include "core/makehuman.h"
#include "model/database.h"
#include "model/model_file.h"
#include "tools/console.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

struct BuildArgs {
  std::string reg, db, out;
  double shape_variance = 0.995, full_variance = 0.99;
  int max_components = -1;
  bool no_rig = false;
};

}  // namespace

BODYMODEL_VERB(add_model_build_verb) {
  auto a = std::make_shared<BuildArgs>();
  auto* cmd = app.add_subcommand(
      "build",
      "Build the statistical model (Hasler et al. 2009 §4) from registered meshes: encodes every\n"
      "scan (relative rotation encoding), PCA of all scans (full model: pose and shape) and of the\n"
      "standard-pose scans (shape-only model), semantic regression of every label (subjects.csv\n"
      "columns and the joint rotations of DB/truth/<scan>.pose.csv), semantic basis. Writes an .npz\n"
      "(see model/model_file.h for its keys).");
  cmd->add_option("registered", a->reg,
                  "Folder of template-topology meshes named <scan_id>.ply/.obj (DB/truth works)")
      ->required();
  cmd->add_option("--db", a->db, "Database folder with subjects.csv and scans.csv")->required();
  cmd->add_option("--out", a->out, "Output model (.npz)")->required();
  cmd->add_option("--shape-variance", a->shape_variance,
                  "Fraction of variance the shape model's components keep")
      ->capture_default_str();
  cmd->add_option("--full-variance", a->full_variance,
                  "Fraction of variance the full model's components keep")
      ->capture_default_str();
  cmd->add_option("--max-components", a->max_components, "Cap on components per model (-1: none)")
      ->capture_default_str();
  cmd->add_flag("--no-rig", a->no_rig,
                "Do not attach the MakeHuman skeleton (pose morphing and region masks need it)");
  cmd->callback([a] {
    cli::ProgressBar read_bar("reading");
    DatabaseReadSummary rs;
    ModelBuildInput in = read_registered_database(a->reg, a->db, &rs, read_bar.callback());
    read_bar.finish(fmt::format("{} of {} scans ({} with pose labels)", rs.scans_read, rs.scans_listed,
                                rs.scans_with_pose_labels));
    if (!rs.missing.empty())
      cli::warn(fmt::format("{} scans listed in scans.csv have no mesh in {} (first: {}); built without them",
                            rs.missing.size(), a->reg, rs.missing[0]));
    ModelBuildOptions o;
    o.shape_pca.variance_threshold = a->shape_variance;
    o.full_pca.variance_threshold = a->full_variance;
    o.shape_pca.max_components = o.full_pca.max_components = a->max_components;
    cli::ProgressBar bar("build");
    ModelBuildSummary s;
    BodyModel model = build_body_model(in, o, &s, bar.callback());
    bar.finish();
    cli::info(fmt::format("shape model: {} subjects, {} components keep {:.2f}% of the variance (threshold {})",
                          s.shape_pca.samples, s.shape_pca.components, 100 * s.shape_pca.explained,
                          a->shape_variance));
    cli::info(fmt::format("full model:  {} scans, {} components keep {:.2f}% of the variance (threshold {})",
                          s.full_pca.samples, s.full_pca.components, 100 * s.full_pca.explained,
                          a->full_variance));
    cli::info(fmt::format("labels: {} subject labels, {} joint-angle labels ({} never vary: dropped)",
                          in.subject_labels.size(), s.pose_labels_kept, s.pose_labels_dropped));
    if (!a->no_rig) {
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
    model.metadata["source"] = {{"registered", a->reg}, {"database", a->db}};
    save_model(a->out, model);
    cli::info("wrote " + a->out);
  });
}

}  // namespace bodymodel
