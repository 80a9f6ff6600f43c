#include "tools/pipeline/character_job.h"

#include <fmt/format.h>

#include <chrono>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/mesh_io.h"
#include "core/measure.h"
#include "skinning/gltf_export.h"
#include "tools/pipeline/animate_job.h"
#include "tools/pipeline/character_file.h"
#include "tools/render/render.h"

namespace bodymodel {

namespace fs = std::filesystem;

const RigErrorRow& find_row(const std::vector<RigErrorRow>& rows, const std::string& method, const std::string& split) {
  for (auto& r : rows)
    if (r.method == method && r.split == split) return r;
  throw InputError("no fit error row for " + method + " / " + split);
}

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Held-out pose with the largest SSD mean error: pose morph | SSD | AS | MWE coloured by error.
void write_error_picture(const CharacterExamples& ex, const CharacterRigs& rigs, double scale_mm,
                         const fs::path& png) {
  int worst = -1;
  double worst_err = -1;
  for (size_t p = 0; p < ex.poses.size(); ++p) {
    if (!ex.poses[p].held_out) continue;
    double e = (evaluate_rig(rigs.lbs, ex.transforms[p]) - ex.meshes[p]).rowwise().norm().mean();
    if (e > worst_err) worst_err = e, worst = static_cast<int>(p);
  }
  if (worst < 0) return;
  std::vector<Eigen::MatrixX3d> meshes{ex.meshes[worst]};
  std::vector<Eigen::MatrixX3d> colors{Eigen::MatrixX3d()};
  for (const SkinningRig* r : {&rigs.lbs, &rigs.as, &rigs.mwe}) {
    Eigen::MatrixX3d X = evaluate_rig(*r, ex.transforms[worst]);
    colors.push_back(heat_colors((X - ex.meshes[worst]).rowwise().norm(), 0, scale_mm));
    meshes.push_back(std::move(X));
  }
  const int cell = 220, h = 440;
  Image row = render_row(meshes, ex.F, colors, cell, h);
  Image img(row.width, h + 24);
  img.paste(row, 0, 0);
  img.paste(heat_colorbar(row.width - 40, 12), 20, h + 6);
  img.save_png(png);
}

}  // namespace

CharacterJobResult write_character(const BodyModel& model, const Eigen::MatrixX3d& V, const fs::path& dir,
                                   const nlohmann::json& description, const CharacterJobOptions& o,
                                   const ProgressCallback& progress) {
  validate_character_options(o.character);
  CharacterJobResult res;
  auto t0 = std::chrono::steady_clock::now();
  auto sub = [&](double a, double b) -> ProgressCallback {
    if (!progress) return {};
    return [=](double f, std::string_view w) { return progress(a + (b - a) * f, w); };
  };
  // With judge poses the pose fits of every rig on each take about as long as the rigs' fits.
  const bool judge = !o.judge_poses.empty();
  const double e1 = judge ? 0.45 : 0.6, f1 = judge ? 0.7 : 0.95;
  CharacterExamples ex = make_character_examples(model, V, data_file("makehuman"), o.character, sub(0, e1));
  res.examples_seconds = seconds_since(t0);
  auto t1 = std::chrono::steady_clock::now();
  CharacterRigs rigs = fit_character_rigs(ex, o.character, sub(e1, f1));
  res.fit_seconds = seconds_since(t1);
  res.errors = evaluate_character_rigs(ex, rigs);
  if (judge) {
    auto t2 = std::chrono::steady_clock::now();
    for (auto& p : o.judge_poses)
      if (p.target.rows() != ex.rest.rows())
        throw InputError(fmt::format("judge pose '{}' has {} vertices, the character {}", p.name, p.target.rows(),
                                     ex.rest.rows()));
    res.judged = judge_rigs_on_poses({{"template_lbs", &rigs.template_lbs},
                                      {"smooth_lbs", &rigs.smooth_lbs},
                                      {"lbs", &rigs.lbs},
                                      {"as", &rigs.as},
                                      {"mwe", &rigs.mwe}},
                                     ex.skeleton, ex.driven, ex.F, o.judge_poses, o.judge_fit, sub(f1, 0.95));
    res.judge_seconds = seconds_since(t2);
  }
  for (auto& p : ex.poses) (p.held_out ? res.held_out_poses : res.training_poses)++;
  report_progress(progress, 0.96, "writing");

  write_mesh(dir / "body.obj", V, ex.F);
  write_text_file(dir / "fit.csv", rig_errors_csv(res.errors));
  const PoseErrors pe = per_pose_errors(ex, rigs);
  std::string poses =
      "pose,split,made_by,flipped_before_repair,flipped,lbs_mean_mm,lbs_max_mm,smooth_lbs_mean_mm,smooth_lbs_max_mm,"
      "as_mean_mm,as_max_mm,mwe_mean_mm,mwe_max_mm,mwe_max_vertex,mwe_max_bone\n";
  for (size_t i = 0; i < ex.poses.size(); ++i) {
    const auto& p = ex.poses[i];
    poses += fmt::format("{},{},{},{},{}", csv_field(p.name), p.held_out ? "held_out" : "train",
                         p.name == "rest" ? "the body" : p.blend_a >= 0 ? "encoding-space interpolation"
                                                                        : "pose morph",
                         ex.flipped_before[i], ex.flipped_after[i]);
    for (int m : {2, 1, 3, 4}) poses += fmt::format(",{:.3f},{:.3f}", pe.mean_mm(i, m), pe.max_mm(i, m));
    // The bone carrying the MWE's worst vertex most (template weights).
    const int v = pe.max_vertex(i, 4);
    Eigen::Index bone = 0;
    Eigen::VectorXd(ex.template_weights.row(v).transpose()).maxCoeff(&bone);
    poses += fmt::format(",{},{}\n", v, ex.skeleton.names[bone]);
  }
  for (size_t i = 0; i < ex.poses.size(); ++i) {
    res.flipped_before_repair += ex.flipped_before[i];
    res.flipped_after_repair += ex.flipped_after[i];
  }
  write_text_file(dir / "poses.csv", poses);
  if (judge) write_text_file(dir / "judge.csv", judge_csv(res.judged, o.judge_poses));

  const BodyMeasurements m = measure_body(V, ex.F);
  res.character = description;
  res.character["measured"] = {{"height_cm", m.height_cm}, {"weight_kg", m.weight_kg}, {"volume_l", m.volume_l},
                               {"waist_cm", m.waist_cm}, {"hips_cm", m.hips_cm}, {"chest_cm", m.chest_cm}};
  res.character["training_poses"] = res.training_poses;
  res.character["held_out_poses"] = res.held_out_poses;
  nlohmann::json errs = nlohmann::json::array();
  for (auto& r : res.errors)
    errs.push_back({{"method", r.method}, {"split", r.split}, {"mean_mm", r.mean_mm}, {"max_mm", r.max_mm}});
  res.character["fit_errors"] = errs;
  if (judge) {
    nlohmann::json j = nlohmann::json::array();
    for (auto& r : res.judged)
      if (r.pose == "all")
        j.push_back({{"method", r.method}, {"poses", r.poses}, {"mean_mm", r.mean_mm}, {"max_mm", r.max_mm}});
    res.character["real_pose_errors"] = j;
  }

  CharacterRigFile f;
  f.rig = rigs.mwe;
  // The SSD the MWE refines (the smoothed template weights by default): what animate compares
  // with and the glb carries. The SSD fitted to the pose morphs stretches short edges in unseen
  // poses (vertex-to-vertex noise) and is only reported in fit.csv.
  const SkinningRig& base = o.character.base_on_template_weights ? rigs.smooth_lbs : rigs.lbs;
  f.lbs = base;
  f.template_lbs = rigs.template_lbs;
  f.F = ex.F;
  f.skeleton = ex.skeleton;
  f.driven = ex.driven;
  for (size_t p = 0; p < ex.poses.size(); ++p)
    if (!ex.poses[p].held_out) f.training_transforms.push_back(ex.transforms[p]);
  f.character = res.character;
  save_character_rig(dir / "rig.npz", f);
  if (o.write_pictures) write_error_picture(ex, rigs, o.error_scale_mm, dir / "skinning_error.png");
  if (o.write_glb) {
    GltfExportOptions go;
    go.mesh_name = "character";
    write_skinned_gltf(dir / "character.glb", V, ex.F, {}, ex.skeleton, skin_weights_of(base), nullptr, go);
    res.wrote_glb = true;
  } else {
    res.glb_note = "not asked for";
  }
  report_progress(progress, 1.0, "done");
  return res;
}

}  // namespace bodymodel
