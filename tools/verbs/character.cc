// bodymodel character model.npz [--where LABEL=VALUE ...] [--seed N | --in body.ply [--unpose]]
//                    [--judge-poses REG/*.ply] --out char/
#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>

#include "core/body_size.h"
#include "core/data_path.h"
#include "core/error.h"
#include "core/io/csv.h"
#include "core/io/file_names.h"
#include "core/io/mesh_io.h"
#include "core/io/pose_csv.h"
#include "core/up_axis.h"
#include "model/model_file.h"
#include "model/morph.h"
#include "tools/console.h"
#include "tools/pipeline/character_job.h"
#include "tools/pipeline/conditions.h"
#include "tools/pipeline/outfit_job.h"
#include "tools/pipeline/output_folder.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

struct CharacterArgs {
  std::string model, in, out;
  std::vector<std::string> where, judge_poses;
  std::string judge_scans, outfits, lods = "default";
  bool unpose = false;
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

namespace fs = std::filesystem;

// The pose a registration was fitted in: `register-mesh` writes <stem>.pose.csv beside <stem>.ply.
fs::path pose_file_beside(const std::string& mesh) { return fs::path(mesh).replace_extension(".pose.csv"); }

// The start of the pose fits: the registration's pose, the rest pose when there is none. A row
// naming a bone the model's skeleton lacks is refused (the reader names the file, line and bone):
// skipping it would start the fit from a pose the file does not describe.
Pose start_pose_for(const std::string& mesh, const std::vector<std::string>& bone_names) {
  const fs::path p = pose_file_beside(mesh);
  std::error_code ec;
  if (!fs::exists(p, ec)) return Pose::rest(static_cast<int>(bone_names.size()));
  return read_pose_csv(p, bone_names).pose;
}

// Two-sided distance (mm) of each registration to its scan from `register-mesh.csv` in the
// folder of `mesh`, by mesh stem; empty when the file is not there.
std::map<std::string, double> registration_distances(const std::string& mesh) {
  std::map<std::string, double> out;
  const fs::path csv = fs::path(mesh).parent_path() / "register-mesh.csv";
  std::error_code ec;
  if (!fs::is_regular_file(csv, ec)) return out;
  const std::vector<CsvRecord> rows = read_csv_file(csv);
  if (rows.empty()) return out;
  const std::vector<std::string>& head = rows[0].fields;
  const auto col = std::find(head.begin(), head.end(), "two_sided_mm") - head.begin();
  if (col >= static_cast<long>(head.size()) || head.empty() || head[0] != "mesh") return out;
  for (size_t r = 1; r < rows.size(); ++r) {
    const std::vector<std::string>& v = rows[r].fields;
    if (static_cast<long>(v.size()) <= col) continue;
    try {
      out[v[0]] = std::stod(v[col]);
    } catch (const std::exception&) {
      throw InputError("'" + csv.string() + "': two_sided_mm of '" + v[0] + "' is not a number");
    }
  }
  return out;
}

// The scan a judged registration was made from: DIR/<stem>.{off,ply,obj}, brought into the
// project's frame with the scale and up axis `register-mesh` recorded beside the registration
// (register-mesh.json).
Mesh judge_scan_for(const std::string& mesh, const std::string& dir) {
  const std::string stem = fs::path(mesh).stem().string();
  fs::path scan;
  for (const char* ext : {".off", ".ply", ".obj"})
    if (std::error_code ec; fs::exists(fs::path(dir) / (stem + ext), ec)) {
      scan = fs::path(dir) / (stem + ext);
      break;
    }
  if (scan.empty()) throw InputError("--judge-scans: no " + stem + ".off/.ply/.obj in '" + dir + "'");
  const fs::path settings = fs::path(mesh).parent_path() / "register-mesh.json";
  std::ifstream in(settings);
  if (!in)
    throw InputError("--judge-scans: '" + settings.string() +
                     "' is missing (register-mesh's settings: the scans' scale and up axis)");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    throw InputError("'" + settings.string() + "': not JSON (" + e.what() + ")");
  }
  if (!j.contains("scale") || !j["scale"].is_number() || !j.contains("up") || !j["up"].is_string())
    throw InputError("'" + settings.string() + "': needs \"scale\" (number) and \"up\" (axis)");
  Mesh m = read_mesh(scan);
  m.V = to_project_frame(m.V, j["scale"].get<double>(), up_axis_rotation(j["up"].get<std::string>(), "'" +
                         settings.string() + "' up"));
  check_body_size(m.V, "--judge-scans '" + scan.string() + "' (unit and axes from '" + settings.string() + "')",
                  "register-mesh --scale", j["scale"].get<double>());
  return m;
}

void print_judge_table(const std::vector<JudgeRow>& rows, const std::vector<JudgePose>& poses) {
  double reg = 0;
  int nreg = 0;
  for (auto& p : poses)
    if (std::isfinite(p.registration_mm)) reg += p.registration_mm, ++nreg;
  fmt::print("rigs posed onto {} real poses (the same pose fit for every rig), vertex error:\n", poses.size());
  fmt::print("{:<13} {:>5} {:>9} {:>9} {:>9} {:>9} {:>14}\n", "rig", "poses", "mean mm", "rms mm", "p95 mm", "max mm",
             "scan 2-sided");
  for (auto& r : rows)
    if (r.pose == "all")
      fmt::print("{:<13} {:>5} {:>9.2f} {:>9.2f} {:>9.2f} {:>9.2f} {:>14}\n", r.method, r.poses, r.mean_mm, r.rms_mm,
                 r.p95_mm, r.max_mm,
                 std::isfinite(r.scan_two_sided_mm) ? fmt::format("{:.2f}", r.scan_two_sided_mm) : "-");
  if (nreg) fmt::print("registrations' two-sided distance to their scans (a floor for every rig): {:.2f} mm mean over {}\n",
                       reg / nreg, nreg);
  // MWE against MakeHuman's weights pose by pose.
  int better = 0;
  for (auto& p : poses) {
    double m = 0, t = 0;
    for (auto& r : rows) {
      if (r.pose != p.name) continue;
      if (r.method == "mwe") m = r.mean_mm;
      if (r.method == "template_lbs") t = r.mean_mm;
    }
    better += m < t;
  }
  fmt::print("MWE below MakeHuman's weights (template_lbs) in mean error on {} of {} poses\n", better, poses.size());
}

}  // namespace

namespace {

void add_character_options(CLI::App* cmd, CharacterArgs& a) {
  cmd->add_option("model", a.model, "Model (.npz from `bodymodel build`, with its skeleton)")->required();
  cmd->add_option("--where", a.where, "LABEL=VALUE or LABEL=LO..HI for the generated body, repeatable");
  cmd->add_option("--seed", a.seed, "Random seed of the generated body")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--in", a.in, "Use this body (model topology, standard pose, mm) instead of generating one");
  cmd->add_option("--out", a.out, "Output folder (must not exist unless --force)")->required();
  cmd->add_flag("--force", a.force, "Replace an existing output folder");
  cmd->add_flag("--unpose", a.unpose,
                "The --in body is posed (e.g. a registration of a real person): unpose it by inverting linear blend "
                "skinning in a pose fitted to it, pulled towards <in>.pose.csv beside it (register-mesh writes "
                "one); body.obj is the unposed body");
  cmd->add_option("--judge-scans", a.judge_scans,
                  "Folder of the scans the judge poses were registered to (<stem>.off/.ply/.obj, in the unit and "
                  "axes register-mesh.json beside the registrations records): also the posed rigs' two-sided "
                  "surface distance to them")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--judge-poses", a.judge_poses,
                  "Also judge every rig on these real poses of the body (meshes of the model's topology, mm, +y up, "
                  "e.g. `register-mesh` outputs; each <stem>.pose.csv beside a mesh starts its pose fit): judge.csv")
      ->check(CLI::ExistingFile);
  cmd->add_option("--mwe-s", a.mwe_s, "MWE ridge scale s, relative (λ_h = s·d⁴/σ²(c_h), skinning/fit_mwe.h)")
      ->capture_default_str();
  cmd->add_option("--mwe-components", a.mwe_components, "MWE principal components kept (0 = all with variance)")
      ->capture_default_str();
  cmd->add_flag("--paper-pose-morph", a.paper_pose_morph,
                "Pose morphs as the paper (limb tips only, decoded volume) instead of the model's defaults "
                "(torso anchored, volume kept); for comparisons");
  cmd->add_flag("--no-fold-repair", a.no_fold_repair,
                "Do not repair folds of the pose morphs before fitting (for comparisons)");
  cmd->add_option("--mwe-smoothing-steps", a.mwe_smoothing_steps,
                  "Smoothing steps of MWE's refinement over the SSD (tools/pipeline/character.h)")
      ->capture_default_str();
  cmd->add_option("--mwe-mask-steps", a.mwe_mask_steps,
                  "Smoothing steps of the hands/feet/head mask of MWE's refinement (< 0 = no mask)")
      ->capture_default_str();
  cmd->add_option("--mwe-mask-bones", a.mwe_mask_bones,
                  "Bone name prefixes (with descendants) whose vertices keep the SSD (no MWE refinement)")
      ->capture_default_str();
  cmd->add_option("--fold-max-move-mm", a.fold_max_move_mm,
                  "Fold repair of the pose morphs: refuse region solves moving a vertex farther (mm)")
      ->capture_default_str();
  cmd->add_flag("--fold-rest-reference", a.fold_rest_reference,
                "Fold repair from the rest body's local shape instead of the body skinned into the pose");
  cmd->add_option("--threads", a.threads, "Threads for the pose morphs (0 = all cores)")->capture_default_str();
  cmd->add_option("--outfits", a.outfits,
                  "Also dress the character: a JSON of outfit choices per sex, or 'default' (docs/assets.md#outfits), "
                  "drawn with --seed: OUT/dressed.glb (rest pose), OUT/outfit.json, OUT/penetration.csv");
  cmd->add_option("--lods", a.lods,
                  "With --outfits: levels of detail in dressed.glb: 'default' (the full body, a MakeHuman proxy "
                  "with simplified assets, the low-poly proxy within 2000 triangles; docs/assets.md#levels-of-detail) "
                  "or 'none' (the full body only)")
      ->capture_default_str();
}

// The character in the folder dressed in an outfit drawn with the seed (rest pose).
void dress_character_folder(const OutfitKit& kit, const BodyModel& model, Sex sex, const Eigen::VectorXd& encoding,
                            uint64_t seed, const fs::path& dir) {
  const CharacterRigFile ch = load_character_rig(dir / "rig.npz");
  const DressedCharacterResult r =
      write_dressed_character(kit, ch, outfit_sex_is_male(model, sex, encoding, seed), seed, {}, 1.0 / 30, dir);
  std::string items;
  for (const DrawnItem& i : r.drawn.items) items += " " + i.asset + " " + i.hex;
  cli::info(fmt::format("dressed ({}, skin {}):{}; {:.2f} MB; garment vertices > 2 mm inside at rest: {:.2f} % (worst)",
                        r.drawn.male ? "male" : "female", r.drawn.skin_hex, items, r.glb_bytes / 1e6,
                        r.penetration.fraction.size() ? 100 * r.penetration.fraction.maxCoeff() : 0.0));
}

void run_character(CharacterArgs& a) {
  if (!a.in.empty() && !a.where.empty()) throw InputError("character: give --where or --in, not both");
  CharacterJobOptions o;
  o.character.threads = a.threads;
  o.character.mwe.ridge_scale = a.mwe_s;
  o.character.mwe.components = a.mwe_components;
  if (a.paper_pose_morph) {
    o.character.pose_morph.anchor_torso = false;
    o.character.pose_morph.preserve_volume = false;
  }
  o.character.repair_folds = !a.no_fold_repair;
  o.character.fold_reference_skinned = !a.fold_rest_reference;
  o.character.fold_repair.max_displacement = a.fold_max_move_mm;
  o.character.mwe_smoothing_steps = a.mwe_smoothing_steps;
  o.character.mwe_mask_steps = a.mwe_mask_steps;
  o.character.mwe_mask_bones = a.mwe_mask_bones;
  validate_character_options(o.character);  // before any work
  if (a.unpose && a.in.empty()) throw InputError("character: --unpose needs --in (the posed body)");
  if (!a.judge_scans.empty() && a.judge_poses.empty())
    throw InputError("character: --judge-scans needs --judge-poses (the registrations of those scans)");
  const std::optional<OutfitKit> kit = outfit_kit_if_asked(a.outfits, data_file("makehuman"), a.lods);  // before any write
  StagedFolder out(a.out, a.force);
  auto model = std::make_shared<const BodyModel>(load_model(a.model));
  if (model->rig.empty())
    throw InputError("'" + a.model + "' has no skeleton: rebuild it without --no-rig (a character needs one)");
  // Judge poses read and checked before any work.
  for (auto& f : a.judge_poses) {
    Mesh m = read_mesh(f);
    model->check_topology(m.V, m.F, "'" + f + "'");
    check_body_size(m.V, "--judge-poses '" + f + "'");
    JudgePose p;
    p.name = fs::path(f).stem().string();
    p.target = m.V;
    p.start = start_pose_for(f, model->rig.bone_names);
    const auto reg = registration_distances(f);
    if (auto it = reg.find(p.name); it != reg.end()) p.registration_mm = it->second;
    if (!a.judge_scans.empty()) p.scan = judge_scan_for(f, a.judge_scans);
    o.judge_poses.push_back(std::move(p));
  }
  Eigen::MatrixX3d V;
  Eigen::VectorXd encoding;  // of a generated body
  Sex sex = Sex::unknown;    // the outfit's sex: --where's, else predicted from the encoding
  // The description goes into rig.npz: file names only, not the folders of this machine.
  nlohmann::json desc = {{"model", path_label(a.model)}};
  if (!a.in.empty()) {
    Mesh body = read_mesh(a.in);
    model->check_topology(body.V, body.F, "'" + a.in + "'");
    check_body_size(body.V, "'" + a.in + "'");
    V = body.V;
    desc["input"] = path_label(a.in);
    if (a.unpose) {
      cli::ProgressBar ub("unpose");
      // The pose is fitted, pulled towards the registration's own pose when register-mesh wrote one.
      const fs::path pose_file = pose_file_beside(a.in);
      std::error_code ec;
      UnposeOptions uo = unpose_with_prior();
      if (!fs::exists(pose_file, ec)) {
        uo.fit.prior_mm_per_rad = 0;
        cli::warn("no " + pose_file.string() + ": the pose is fitted from rest without a prior (see docs/skinning.md)");
      }
      const UnposeResult u = unpose_body(*model, V, start_pose_for(a.in, model->rig.bone_names), uo, ub.callback());
      ub.finish(fmt::format("posed template to the body, RMS per round {:.2f} mm ... {:.2f} mm", u.rms_mm.front(),
                            u.rms_mm.back()));
      V = u.rest;
      desc["unposed"] = true;
      desc["unpose_rms_mm"] = u.rms_mm.back();
      desc["unpose_prior_mm_per_rad"] = uo.fit.prior_mm_per_rad;
    }
  } else {
    std::vector<LabelCondition> cond = parse_conditions(model->shape.regression, a.where);
    ShapeMorpher morpher(model);
    GenerateOptions go;
    go.morph.sex = sex_of(cond);
    const GeneratedBody g = generate_body(morpher, cond, a.seed, go);
    encoding = g.encoding, sex = go.morph.sex;
    if (!g.satisfied) cli::warn("the generated body does not meet every --where condition:\n" + g.summary.report());
    V = g.V;
    desc["seed"] = a.seed, desc["where"] = a.where;
    cli::info(fmt::format("generated body: {:.1f} cm, {:.1f} kg (measured)", g.measured.height_cm,
                          g.measured.weight_kg));
  }
  cli::ProgressBar bar("character");
  CharacterJobResult r = write_character(*model, V, out.path(), desc, o, bar.callback());
  bar.finish(fmt::format("{} training + {} held-out poses; examples {:.0f} s, fits {:.0f} s{}", r.training_poses,
                         r.held_out_poses, r.examples_seconds, r.fit_seconds,
                         r.judged.empty() ? "" : fmt::format(", real poses {:.0f} s", r.judge_seconds)));
  if (kit) dress_character_folder(*kit, *model, sex, encoding, a.seed, out.path());
  out.commit();
  print_fit_table(r.errors);
  const RigErrorRow& lbs = find_row(r.errors, "lbs", "held_out");
  const RigErrorRow& mwe = find_row(r.errors, "mwe", "held_out");
  fmt::print("held-out poses: MWE mean {:.2f} / max {:.2f} mm vs SSD {:.2f} / {:.2f} mm ({})\n", mwe.mean_mm,
             mwe.max_mm, lbs.mean_mm, lbs.max_mm,
             mwe.mean_mm < lbs.mean_mm && mwe.max_mm < lbs.max_mm ? "MWE better" : "MWE NOT better in both");
  fmt::print("flipped triangles over the range of motion: {} as morphed, {} after the fold repair\n",
             r.flipped_before_repair, r.flipped_after_repair);
  if (!r.judged.empty()) print_judge_table(r.judged, o.judge_poses);
  if (!r.wrote_glb) cli::warn("no character.glb: " + r.glb_note);
  cli::info("wrote " + a.out);
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
      "OUT/poses.csv, OUT/skinning_error.png and OUT/character.glb (SSD rig, glTF 2.0); with\n"
      "--judge-poses also OUT/judge.csv: every rig posed onto real poses of the body by the same\n"
      "pose fit, and its vertex error there (docs/skinning.md, character rigs on real poses).");
  add_character_options(cmd, *a);
  cmd->callback([a] { run_character(*a); });
}

}  // namespace bodymodel
