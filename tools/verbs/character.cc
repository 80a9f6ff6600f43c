// bodymodel character model.npz [--where LABEL=VALUE ...] [--seed N | --in body.ply] --out char/
#include <fmt/format.h>

#include <memory>

#include "core/error.h"
#include "core/io/file_names.h"
#include "core/io/mesh_io.h"
#include "model/model_file.h"
#include "model/morph.h"
#include "tools/console.h"
#include "tools/pipeline/character_job.h"
#include "tools/pipeline/conditions.h"
#include "tools/pipeline/output_folder.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

struct CharacterArgs {
  std::string model, in, out;
  std::vector<std::string> where;
  uint64_t seed = 1;
  bool force = false;
  int threads = 0;
  double mwe_s = CharacterOptions{}.mwe.ridge_scale;
  int mwe_components = MweFitOptions{}.components;
  bool paper_pose_morph = false, no_fold_repair = false, fold_rest_reference = false;
  int mwe_smoothing_steps = CharacterOptions{}.mwe_smoothing_steps;
  int mwe_mask_steps = CharacterOptions{}.mwe_mask_steps;
  double fold_max_move_mm = CharacterOptions{}.fold_repair.max_displacement;
  std::vector<std::string> mwe_mask_bones = CharacterOptions{}.mwe_mask_bones;
};

void print_fit_table(const std::vector<RigErrorRow>& rows) {
  fmt::print("{:<13} {:<9} {:>5} {:>9} {:>9} {:>9}\n", "rig", "split", "poses", "mean mm", "p95 mm", "max mm");
  for (auto& r : rows)
    fmt::print("{:<13} {:<9} {:>5} {:>9.2f} {:>9.2f} {:>9.2f}\n", r.method, r.split, r.poses, r.mean_mm, r.p95_mm,
               r.max_mm);
}

}  // namespace

BODYMODEL_VERB(add_character_verb) {
  auto a = std::make_shared<CharacterArgs>();
  auto* cmd = app.add_subcommand(
      "character",
      "Make a rigged character: generate a body from the model (or take --in), pose-morph it into a\n"
      "range of motion (MakeHuman static poses, CMU frames, encoding-space in-betweens), fit SSD,\n"
      "Animation Space and MWE (delta space over SSD) with the template skeleton, and write\n"
      "OUT/body.obj, OUT/rig.npz (MWE + skeleton), OUT/fit.csv (training and held-out errors, mm),\n"
      "OUT/poses.csv, OUT/skinning_error.png and OUT/character.glb (SSD rig, glTF 2.0).");
  cmd->add_option("model", a->model, "Model (.npz from `bodymodel build`, with its skeleton)")->required();
  cmd->add_option("--where", a->where, "LABEL=VALUE or LABEL=LO..HI for the generated body, repeatable");
  cmd->add_option("--seed", a->seed, "Random seed of the generated body")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--in", a->in, "Use this body (model topology, standard pose, mm) instead of generating one");
  cmd->add_option("--out", a->out, "Output folder (must not exist unless --force)")->required();
  cmd->add_flag("--force", a->force, "Replace an existing output folder");
  cmd->add_option("--mwe-s", a->mwe_s, "MWE ridge scale s, relative (λ_h = s·d⁴/σ²(c_h), skinning/fit_mwe.h)")
      ->capture_default_str();
  cmd->add_option("--mwe-components", a->mwe_components, "MWE principal components kept (0 = all with variance)")
      ->capture_default_str();
  cmd->add_flag("--paper-pose-morph", a->paper_pose_morph,
                "Pose morphs as the paper (limb tips only, decoded volume) instead of the model's defaults "
                "(torso anchored, volume kept); for comparisons");
  cmd->add_flag("--no-fold-repair", a->no_fold_repair,
                "Do not repair folds of the pose morphs before fitting (for comparisons)");
  cmd->add_option("--mwe-smoothing-steps", a->mwe_smoothing_steps,
                  "Smoothing steps of MWE's refinement over the SSD (tools/pipeline/character.h)")
      ->capture_default_str();
  cmd->add_option("--mwe-mask-steps", a->mwe_mask_steps,
                  "Smoothing steps of the hands/feet/head mask of MWE's refinement (< 0 = no mask)")
      ->capture_default_str();
  cmd->add_option("--mwe-mask-bones", a->mwe_mask_bones,
                  "Bone name prefixes (with descendants) whose vertices keep the SSD (no MWE refinement)")
      ->capture_default_str();
  cmd->add_option("--fold-max-move-mm", a->fold_max_move_mm,
                  "Fold repair of the pose morphs: refuse region solves moving a vertex farther (mm)")
      ->capture_default_str();
  cmd->add_flag("--fold-rest-reference", a->fold_rest_reference,
                "Fold repair from the rest body's local shape instead of the body skinned into the pose");
  cmd->add_option("--threads", a->threads, "Threads for the pose morphs (0 = all cores)")->capture_default_str();
  cmd->callback([a] {
    if (!a->in.empty() && !a->where.empty()) throw InputError("character: give --where or --in, not both");
    CharacterJobOptions o;
    o.character.threads = a->threads;
    o.character.mwe.ridge_scale = a->mwe_s;
    o.character.mwe.components = a->mwe_components;
    if (a->paper_pose_morph) {
      o.character.pose_morph.anchor_torso = false;
      o.character.pose_morph.preserve_volume = false;
    }
    o.character.repair_folds = !a->no_fold_repair;
    o.character.fold_reference_skinned = !a->fold_rest_reference;
    o.character.fold_repair.max_displacement = a->fold_max_move_mm;
    o.character.mwe_smoothing_steps = a->mwe_smoothing_steps;
    o.character.mwe_mask_steps = a->mwe_mask_steps;
    o.character.mwe_mask_bones = a->mwe_mask_bones;
    validate_character_options(o.character);  // before any work
    StagedFolder out(a->out, a->force);
    auto model = std::make_shared<const BodyModel>(load_model(a->model));
    if (model->rig.empty())
      throw InputError("'" + a->model + "' has no skeleton: rebuild it without --no-rig (a character needs one)");
    Eigen::MatrixX3d V;
    // The description goes into rig.npz: file names only, not the folders of this machine.
    nlohmann::json desc = {{"model", path_label(a->model)}};
    if (!a->in.empty()) {
      Mesh body = read_mesh(a->in);
      model->check_topology(body.V, body.F, "'" + a->in + "'");
      V = body.V;
      desc["input"] = path_label(a->in);
    } else {
      std::vector<LabelCondition> cond = parse_conditions(model->shape.regression, a->where);
      ShapeMorpher morpher(model);
      GenerateOptions go;
      go.morph.sex = sex_of(cond);
      GeneratedBody g = generate_body(morpher, cond, a->seed, go);
      if (!g.satisfied) cli::warn("the generated body does not meet every --where condition:\n" + g.summary.report());
      V = g.V;
      desc["seed"] = a->seed;
      desc["where"] = a->where;
      cli::info(fmt::format("generated body: {:.1f} cm, {:.1f} kg (measured)", g.measured.height_cm,
                            g.measured.weight_kg));
    }
    cli::ProgressBar bar("character");
    CharacterJobResult r = write_character(*model, V, out.path(), desc, o, bar.callback());
    bar.finish(fmt::format("{} training + {} held-out poses; examples {:.0f} s, fits {:.0f} s", r.training_poses,
                           r.held_out_poses, r.examples_seconds, r.fit_seconds));
    out.commit();
    print_fit_table(r.errors);
    const RigErrorRow& lbs = find_row(r.errors, "lbs", "held_out");
    const RigErrorRow& mwe = find_row(r.errors, "mwe", "held_out");
    fmt::print("held-out poses: MWE mean {:.2f} / max {:.2f} mm vs SSD {:.2f} / {:.2f} mm ({})\n", mwe.mean_mm,
               mwe.max_mm, lbs.mean_mm, lbs.max_mm,
               mwe.mean_mm < lbs.mean_mm && mwe.max_mm < lbs.max_mm ? "MWE better" : "MWE NOT better in both");
    fmt::print("flipped triangles over the range of motion: {} as morphed, {} after the fold repair\n",
               r.flipped_before_repair, r.flipped_after_repair);
    if (!r.wrote_glb) cli::warn("no character.glb: " + r.glb_note);
    cli::info("wrote " + a->out);
  });
}

}  // namespace bodymodel
