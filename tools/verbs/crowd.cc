// bodymodel crowd model.npz --count 20 --bvh clip.bvh --out crowd/ [--where ...] [--seed N]
#include <fmt/format.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/bvh.h"
#include "core/io/file_names.h"
#include "core/io/mesh_io.h"
#include "model/model_file.h"
#include "model/morph.h"
#include "tools/console.h"
#include "tools/pipeline/animate_job.h"
#include "tools/pipeline/character_job.h"
#include "tools/pipeline/conditions.h"
#include "tools/pipeline/crowd_viewer.h"
#include "tools/pipeline/folder_settings.h"
#include "tools/pipeline/outfit_job.h"
#include "tools/pipeline/output_folder.h"
#include "tools/render/render.h"
#include "tools/verb.h"
#include "tools/viewer/viewer_assets.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct CrowdArgs {
  std::string model, bvh, out, frames_format = "none", outfits, lods = "default";
  std::vector<std::string> where;
  int count = 20;
  uint64_t seed = 1;
  bool force = false, quick = false, no_repair = false, lod_corrections = false, no_lod_corrections = false;
  double fps = 30;
  int max_frames = 0;
};

// A smaller range of motion (2 CMU frames per clip, 4 in-betweens, 1 + 2 held out): about
// half the pose morphs.
void make_quick(CharacterOptions& o) {
  o.range_of_motion.training_frames_per_clip = 2;
  o.range_of_motion.held_out_frames_per_clip = 1;
  o.range_of_motion.training_blends = 4;
  o.range_of_motion.held_out_blends = 2;
}

}  // namespace

namespace {

void add_crowd_options(CLI::App* cmd, CrowdArgs& a) {
  cmd->add_option("model", a.model, "Model (.npz from `bodymodel build`, with its skeleton)")->required();
  cmd->add_option("--count", a.count, "Characters")->capture_default_str()->check(CLI::Range(1, 10000));
  cmd->add_option("--bvh", a.bvh, "Motion clip (BVH) every character performs")->required();
  cmd->add_option("--where", a.where, "LABEL=VALUE or LABEL=LO..HI, repeatable");
  cmd->add_option("--seed", a.seed, "Random seed (character i uses seed·1000003 + i)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--out", a.out, "Output folder")->required();
  cmd->add_flag("--quick", a.quick, "Smaller range of motion (about half the pose morphs)");
  cmd->add_option("--fps", a.fps, "Animation frame rate")->capture_default_str();
  cmd->add_option("--max-frames", a.max_frames, "At most this many animation frames (0 = all)")->capture_default_str();
  cmd->add_option("--frames-format", a.frames_format, "Per-frame meshes: none, ply or obj")->capture_default_str();
  cmd->add_flag("--no-repair", a.no_repair,
                "No fold repair of the animation frames (on by default, as `bodymodel animate`; the glb files "
                "are never repaired)");
  cmd->add_option("--outfits", a.outfits,
                  "Dress every character: a JSON of outfit choices per sex, or 'default' (a street; "
                  "docs/assets.md#outfits): OUT/char_NNN/anim/ dressed.glb, outfit.json, penetration.csv");
  cmd->add_option("--lods", a.lods,
                  "With --outfits: levels of detail in dressed.glb: 'default' (the full body, a MakeHuman proxy "
                  "with simplified assets, the low-poly proxy within 2000 triangles; docs/assets.md#levels-of-detail) "
                  "or 'none' (the full body only)")
      ->capture_default_str();
  cmd->add_flag("--lod-corrections", a.lod_corrections,
                "The default with --outfits and --lods default (given without them it is refused): LOD1 and LOD2 "
                "get their own per-frame garment corrections against their proxy bodies, as LOD0 has "
                "(docs/assets.md#between-keys-and-levels)");
  cmd->add_flag("--no-lod-corrections", a.no_lod_corrections,
                "Only the full level (LOD0) gets garment corrections: smaller glb files, LOD1 and LOD2 over the "
                "penetration bound in about half their frames");
  cmd->add_flag("--force", a.force, "Replace an existing output folder made with other settings");
}

// The dressed crowd's table (OUT/outfits.csv) and summary lines, from each character's outfit.json.
void write_outfit_summary(const CrowdArgs& a, const fs::path& out) {
  std::string csv = "character,sex,skin,items,frames,frames_over_limit,worst_fraction,glb_bytes,"
                    "uncorrected_frames_over_limit,uncorrected_worst_fraction,morph_targets\n";
  int over = 0, frames = 0, over_uncorrected = 0;
  size_t max_bytes = 0;
  for (int i = 0; i < a.count; ++i) {
    const fs::path f = out / fmt::format("char_{:03d}", i) / "anim" / "outfit.json";
    const nlohmann::json j = nlohmann::json::parse(read_text_file(f));
    std::string items;
    for (auto& it : j["items"]) items += (items.empty() ? "" : " ") + it["asset"].get<std::string>() + ":" +
                                         it["srgb"].get<std::string>();
    const auto& p = j["penetration"];
    csv += fmt::format("char_{:03d},{},{},{},{},{},{:.5f},{},{},{:.5f},{}\n", i, j["sex"].get<std::string>(),
                       j["skin"]["srgb"].get<std::string>(), items, p["frames"].get<int>(),
                       p["frames_over_limit"].get<int>(), p["worst_fraction"].get<double>(), j["glb_bytes"].get<size_t>(),
                       p["uncorrected_frames_over_limit"].get<int>(), p["uncorrected_worst_fraction"].get<double>(),
                       j["clip_corrections"]["morph_targets"].get<int>());
    over += p["frames_over_limit"].get<int>(), frames += p["frames"].get<int>();
    over_uncorrected += p["uncorrected_frames_over_limit"].get<int>();
    max_bytes = std::max(max_bytes, j["glb_bytes"].get<size_t>());
  }
  write_text_file(out / "outfits.csv", csv);
  fmt::print("dressed: frames with the body through a garment (> 2 mm over 1 % of its vertices) {} of {} "
             "({} without the per-frame corrections); largest dressed.glb {:.2f} MB\n",
             over, frames, over_uncorrected, max_bytes / 1e6);
  if (a.lods == "none") return;
  // The crowd viewer over the characters' glb files, with the three.js modules it imports.
  std::vector<std::string> glbs;
  for (int i = 0; i < a.count; ++i) glbs.push_back(fmt::format("char_{:03d}/anim/dressed.glb", i));
  const fs::path three = cli::default_three_js().parent_path().parent_path();   // …/three/build/three.min.js
  if (write_crowd_viewer(out, cli::crowd_viewer_html(), glbs, three))
    cli::info("crowd viewer: " + (out / "crowd.html").string() + " (serve the folder over http, e.g. python3 -m http.server)");
  else
    cli::warn("crowd viewer: three.js modules not found under '" + three.string() + "' (scripts/setup.sh); " +
              (out / "crowd.html").string() + " needs them as ./three");
}

// Up to 10 bodies a row, one scale.
void write_crowd_picture(const std::vector<Eigen::MatrixX3d>& bodies, const Eigen::MatrixX3i& F, int count,
                         const fs::path& png) {
  const int per_row = std::min(10, count), rows = (count + per_row - 1) / per_row;
  const int cw = 120, ch = 280;
  Image grid(per_row * cw, rows * ch);
  for (int r = 0; r < rows; ++r) {
    std::vector<Eigen::MatrixX3d> row(bodies.begin() + r * per_row,
                                      bodies.begin() + std::min<int>(count, (r + 1) * per_row));
    grid.paste(render_row(row, F, {}, cw, ch), 0, r * ch);
  }
  grid.save_png(png);
}

// The crowd table and picture from the finished folders (also those of earlier runs), and the
// summary lines.
void write_crowd_summary(const CrowdArgs& a, const fs::path& out, int skipped) {
  std::string csv = "character,height_cm,weight_kg,lbs_held_out_mean_mm,mwe_held_out_mean_mm,mwe_held_out_max_mm,"
                    "max_edge_ratio,p99_edge_ratio,max_flipped,max_flipped_before_repair,max_edge_ratio_before_repair\n";
  std::vector<Eigen::MatrixX3d> bodies;
  Eigen::MatrixX3i F;
  int mwe_better = 0;
  double worst_ratio = 0;
  int worst_flipped = 0, worst_flipped_before = 0;
  for (int i = 0; i < a.count; ++i) {
    const fs::path d = out / fmt::format("char_{:03d}", i);
    CharacterRigFile ch = load_character_rig(d / "rig.npz");
    const auto& c = ch.character;
    double lbs_mean = 0, mwe_mean = 0, mwe_max = 0;
    for (auto& r : c.value("fit_errors", nlohmann::json::array()))
      if (r.value("split", "") == "held_out") {
        if (r.value("method", "") == "lbs") lbs_mean = r.value("mean_mm", 0.0);
        if (r.value("method", "") == "mwe") mwe_mean = r.value("mean_mm", 0.0), mwe_max = r.value("max_mm", 0.0);
      }
    mwe_better += mwe_mean < lbs_mean;
    // Worst edge ratio and flips of the rig over the animation.
    double ratio = 0, p99 = 0, ratio_before = 0;
    int flipped = 0, flipped_before = 0;
    {
      std::istringstream in(read_text_file(d / "anim" / "animation.csv"));
      std::string line;
      std::getline(in, line);
      while (std::getline(in, line)) {
        const std::vector<std::string> f = split_csv_line(line);
        if (f.size() >= 6) ratio = std::max(ratio, std::stod(f[3])), flipped = std::max(flipped, std::stoi(f[5]));
        if (f.size() >= 11) p99 = std::max(p99, std::stod(f[10]));
        if (f.size() >= 17)
          flipped_before = std::max(flipped_before, std::stoi(f[15])), ratio_before = std::max(ratio_before, std::stod(f[16]));
      }
    }
    worst_ratio = std::max(worst_ratio, ratio);
    const auto& m = c.value("measured", nlohmann::json::object());
    csv += fmt::format("char_{:03d},{:.1f},{:.1f},{:.2f},{:.2f},{:.2f},{:.3f},{:.3f},{},{},{:.3f}\n", i,
                       m.value("height_cm", 0.0), m.value("weight_kg", 0.0), lbs_mean, mwe_mean, mwe_max, ratio, p99,
                       flipped, flipped_before, ratio_before);
    worst_flipped = std::max(worst_flipped, flipped);
    worst_flipped_before = std::max(worst_flipped_before, flipped_before);
    bodies.push_back(ch.rig.rest);
    F = ch.F;
  }
  write_text_file(out / "crowd.csv", csv);
  write_crowd_picture(bodies, F, a.count, out / "crowd.png");
  fmt::print("characters                 {} ({} made now, {} from an earlier run)\n", a.count, a.count - skipped,
             skipped);
  fmt::print("MWE better than SSD        {} of {} (held-out mean vertex error)\n", mwe_better, a.count);
  fmt::print("worst edge ratio to rest   {:.2f} over all characters and frames\n", worst_ratio);
  fmt::print("flipped triangles (worst)  {} in a frame{}\n", worst_flipped,
             a.no_repair ? std::string(" (no fold repair)")
                          : fmt::format(" after the fold repair, {} before", worst_flipped_before));
}

void run_crowd(CrowdArgs& a) {
  const fs::path out = a.out;
  // The outfit file and its assets are checked before anything is read or written.
  if (a.lod_corrections && (a.outfits.empty() || a.lods != "default"))
    throw InputError("--lod-corrections: needs --outfits and --lods default (the levels it corrects)");
  std::optional<OutfitKit> kit = outfit_kit_if_asked(a.outfits, data_file("makehuman"), a.lods);
  if (a.lod_corrections && a.no_lod_corrections) throw InputError("--lod-corrections and --no-lod-corrections: give one");
  if (kit) kit->lod_corrections = kit->lods && !a.no_lod_corrections;
  // Every setting that changes a character, the model and clip by content (no paths): a rerun with
  // other settings is refused instead of resumed (tools/pipeline/folder_settings.h). --count may
  // grow: the characters already finished are kept.
  nlohmann::json settings = {{"verb", "crowd"},
                                   {"model", file_fingerprint(a.model)},
                                   {"bvh", file_fingerprint(a.bvh)},
                                   {"where", a.where},
                                   {"seed", a.seed},
                                   {"quick", a.quick},
                                   {"fps", a.fps},
                                   {"max_frames", a.max_frames},
                                   {"frames_format", a.frames_format},
                                   {"repair", !a.no_repair},
                                   {"outfits", a.outfits.empty() || a.outfits == "default" ? a.outfits
                                                                                           : file_fingerprint(a.outfits)}};
  if (!a.outfits.empty()) settings["lods"] = a.lods;
  if (kit && kit->lod_corrections) settings["lod_corrections"] = true;
  ResumableFolder folder(out, "crowd.json", settings, a.force, [](const std::string& n) {
    return n == "crowd.csv" || n == "crowd.png" || n == "outfits.csv" || n == "crowd.html" || n == "three" ||
           n.rfind("char_", 0) == 0;
  });
  auto model = std::make_shared<const BodyModel>(load_model(a.model));
  if (model->rig.empty())
    throw InputError("'" + a.model + "' has no skeleton: rebuild it without --no-rig (a crowd needs one)");
  const std::vector<LabelCondition> cond = parse_conditions(model->shape.regression, a.where);
  const BvhMotion clip = read_bvh(a.bvh);
  if (folder.open()) cli::info("resuming the crowd in " + out.string() + " (finished characters are skipped)");
  std::error_code ec;
  CharacterJobOptions co;
  if (a.quick) make_quick(co.character);
  validate_character_options(co.character);
  AnimateOptions ao;
  ao.fps = a.fps;
  ao.max_frames = a.max_frames;
  ao.format = a.frames_format;
  ao.repair = !a.no_repair;
  ShapeMorpher morpher(model);
  GenerateOptions go;
  go.morph.sex = sex_of(cond);
  cli::ProgressBar bar("crowd");
  int skipped = 0;
  double lead_in_jump = 0;   // the clip's lead-in frame, if retarget_clip dropped one
  auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < a.count; ++i) {
    const fs::path final_dir = out / fmt::format("char_{:03d}", i);
    if (fs::exists(final_dir / "rig.npz", ec)) {
      ++skipped;
      continue;
    }
    auto sub = [&, i](double lo, double hi) -> ProgressCallback {
      ProgressCallback cb = bar.callback();
      return [=](double f, std::string_view w) {
        return cb((i + lo + (hi - lo) * f) / a.count, fmt::format("character {}: {}", i, w));
      };
    };
    StagedFolder dir(final_dir, true);
    const uint64_t seed = a.seed * 1000003ull + static_cast<uint64_t>(i);
    GeneratedBody g = generate_body(morpher, cond, seed, go);
    nlohmann::json desc = {{"model", path_label(a.model)}, {"seed", seed}, {"where", a.where}, {"crowd_index", i}};
    write_character(*model, g.V, dir.path(), desc, co, sub(0, 0.9));
    CharacterRigFile ch = load_character_rig(dir / "rig.npz");
    ClipPoses poses = retarget_clip(clip, ch.skeleton, data_file("makehuman"), true, a.bvh);
    lead_in_jump = poses.lead_in ? poses.lead_in_jump_deg : lead_in_jump;
    ensure_directory(dir / "anim");
    const AnimateResult ar = animate_character(ch, poses, dir / "anim", ao, sub(0.9, 1.0));
    if (kit) {
      std::vector<BoneTransforms> frames;
      for (int f : ar.source_frames) frames.push_back(forward_kinematics(ch.skeleton, restrict_pose(poses.poses[f], ch.driven)));
      write_dressed_character(*kit, ch, outfit_sex_is_male(*model, go.morph.sex, g.encoding, seed), seed, frames,
                              ar.frame_time, dir / "anim");
    }
    dir.commit();
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  bar.finish(fmt::format("{} characters ({} already done) in {:.0f} s", a.count, skipped, secs));
  if (lead_in_jump > 0)
    cli::info(fmt::format("{}: its first frame is a lead-in (a {:.0f}° turn to the next): skipped", a.bvh, lead_in_jump));
  write_crowd_summary(a, out, skipped);
  if (kit) write_outfit_summary(a, out);
  cli::info("wrote " + out.string() + "/crowd.csv, crowd.png" + (kit ? ", outfits.csv" : ""));
}

}  // namespace

BODYMODEL_VERB(add_crowd_verb) {
  auto a = std::make_shared<CrowdArgs>();
  auto* cmd = app.add_subcommand(
      "crowd",
      "A crowd of rigged, animated characters: COUNT bodies generated from the model (--where\n"
      "conditions, seeded), each made a character (as `bodymodel character`) and animated with the\n"
      "clip (as `bodymodel animate`): OUT/char_NNN/ {body.obj, rig.npz, fit.csv, character.glb,\n"
      "anim/animated.glb, anim/animation.csv, anim/frames.png}, OUT/crowd.csv, OUT/crowd.png; with\n"
      "--outfits each character also dressed (anim/dressed.glb, outfit.json, penetration.csv).\n"
      "A rerun with the same settings skips the characters already finished.");
  add_crowd_options(cmd, *a);
  cmd->callback([a] { run_crowd(*a); });
}

}  // namespace bodymodel
