// bodymodel makehuman-body --gender .. --age .. ... [--pose NAME|file.bvh [--frame k]] --out body.obj|ply
//
// Builds a MakeHuman body from the macro sliders (README §5.2 of the data), optionally poses it
// with a static pose or a frame of a BVH clip (CMU clips are retargeted), and writes the
// body-only mesh (13380 vertices, 26756 triangles) in millimetres.
#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/bvh.h"
#include "core/io/mesh_io.h"
#include "core/makehuman.h"
#include "core/retarget.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/slider_options.h"

namespace bodymodel {
namespace {

struct MakeHumanBodyArgs {
  MacroSettings settings;
  std::optional<double> african, asian, caucasian;
  std::string pose;
  int frame = 0;
  bool translation = false;
  bool raw_targets = false;
  std::string out;
};

// The macro sliders with the ethnic ones given: set the given ones, the others share the rest
// (MakeHuman's rule); several given must sum to one.
MacroSettings settings_of(const MakeHumanBodyArgs& a) {
  MacroSettings s = a.settings;
  int given = 0;
  for (auto [name, v] : {std::pair<const char*, std::optional<double>>{"african", a.african},
                         {"asian", a.asian}, {"caucasian", a.caucasian}})
    if (v) ++given;
  if (given == 1) {
    if (a.african) s.set_ethnic("african", *a.african);
    if (a.asian) s.set_ethnic("asian", *a.asian);
    if (a.caucasian) s.set_ethnic("caucasian", *a.caucasian);
  } else if (given > 1) {
    nlohmann::json j = s.to_json();
    j.erase("african"), j.erase("asian"), j.erase("caucasian");
    if (a.african) j["african"] = *a.african;
    if (a.asian) j["asian"] = *a.asian;
    if (a.caucasian) j["caucasian"] = *a.caucasian;
    s = MacroSettings::from_json(j);
    const double sum = s.african + s.asian + s.caucasian;
    if (std::abs(sum - 1) > 1e-6)
      throw InputError(fmt::format("--african/--asian/--caucasian must sum to 1 (got {:.4f})", sum));
  }
  s.validate();
  return s;
}

// The --pose clip: a BVH file, or a CMU clip or static pose of the data by name.
std::optional<BvhMotion> read_pose_clip(const MakeHumanBodyArgs& a, const std::filesystem::path& mh_dir,
                                        std::filesystem::path& file) {
  std::optional<BvhMotion> clip;
  file = a.pose;
  if (!a.pose.empty()) {
    std::error_code ec;
    if (!std::filesystem::exists(file, ec)) {
      if (a.pose.find('/') != std::string::npos || file.extension() == ".bvh")
        throw InputError("pose file '" + a.pose + "' does not exist");
      file = mh_dir / "motion" / "cmu" / (a.pose + ".bvh");
      if (!std::filesystem::exists(file, ec)) file = mh_dir / "motion" / "poses" / (a.pose + ".bvh");
      if (!std::filesystem::exists(file, ec)) {
        std::string known;
        for (const auto& sub : {"poses", "cmu"})
          for (const auto& e : std::filesystem::directory_iterator(mh_dir / "motion" / sub, ec))
            if (e.path().extension() == ".bvh") known += " " + e.path().stem().string();
        throw InputError("unknown pose '" + a.pose + "' (known:" + known + ")");
      }
    }
    clip = read_bvh(file);
    if (a.frame < 0 || a.frame >= clip->frame_count())
      throw InputError(fmt::format("--frame {}: '{}' has frames 0..{}", a.frame, file.string(),
                                   clip->frame_count() - 1));
  }

  return clip;
}

void run(const MakeHumanBodyArgs& a) {
  const MacroSettings s = settings_of(a);
  if (!a.out.empty()) {
    const std::string ext = std::filesystem::path(a.out).extension().string();
    if (ext != ".obj" && ext != ".ply" && ext != ".OBJ" && ext != ".PLY")
      throw InputError("--out '" + a.out + "': expected an .obj or .ply file name");
  }

  // Resolve and read the pose first, so a bad --pose fails before the model is loaded.
  const std::filesystem::path mh_dir = data_file("makehuman");
  std::filesystem::path file;
  const std::optional<BvhMotion> clip = read_pose_clip(a, mh_dir, file);

  MakeHuman::Options options;
  options.substitute_defective_height_targets = !a.raw_targets;
  const MakeHuman mh = MakeHuman::load(mh_dir, options);
  MakeHuman::Body body = mh.body(s);
  const double rest_height_mm = makehuman_body_height(body.mesh.V);

  std::string pose_text = "rest (A-pose)";
  if (clip) {
    int named = 0;
    for (const auto& j : clip->joints) named += body.skeleton.find(j.name) >= 0;
    Pose pose;
    if (named * 2 >= body.skeleton.bone_count()) {
      check_clip_by_bone_name(*clip, body.skeleton);  // renamed, duplicate or misplaced joints
      BvhPoseOptions o;
      o.apply_root_translation = a.translation;
      pose = bvh_frame_to_pose(*clip, a.frame, body.skeleton, o);
      pose_text = fmt::format("{} frame {} (MakeHuman skeleton, by bone name)", file.string(), a.frame);
    } else {
      RetargetOptions o;
      o.apply_root_translation = a.translation;
      const Retargeter rt(*clip, body.skeleton, RetargetMap::for_clip(*clip, mh.directory()), o);
      pose = rt.pose(a.frame);
      pose_text = fmt::format("{} frame {} (retargeted, {} bones driven)", file.string(), a.frame,
                              rt.driven_bone_count());
    }
    body.mesh.V = linear_blend_skinning(body.mesh.V, body.weights,
                                        forward_kinematics(body.skeleton, pose));
  }

  fmt::print("settings: gender {:.3f}  age {:.3f} ({:.1f} years)  muscle {:.3f}  weight {:.3f}  "
             "height {:.3f}  proportions {:.3f}  cup {:.3f}  firmness {:.3f}\n",
             s.gender, s.age, s.age_years(), s.muscle, s.weight, s.height, s.proportions, s.cup,
             s.firmness);
  fmt::print("ethnic:   african {:.3f}  asian {:.3f}  caucasian {:.3f}\n", s.african, s.asian,
             s.caucasian);
  // Mention the README §10.1 substitution only when it changes this body.
  for (const auto& t : mh.substituted_targets())
    for (const auto& [name, w] : mh.target_weights(s))
      if (name == t)
        fmt::print("note:     defective upstream target {} (weight {:.3f}) replaced by its "
                   "averagemuscle sibling\n", t, w);
  fmt::print("pose:     {}\n", pose_text);
  fmt::print("height:   {:.1f} mm = {:.2f} cm (rest pose, y-extent of the body)\n", rest_height_mm,
             rest_height_mm / 10);
  if (clip)
    fmt::print("posed:    y-extent {:.1f} mm\n",
               body.mesh.V.col(1).maxCoeff() - body.mesh.V.col(1).minCoeff());
  if (!a.out.empty()) {
    write_mesh(a.out, body.mesh);
    fmt::print("wrote:    {} ({} vertices, {} triangles, mm)\n", a.out, body.mesh.V.rows(),
               body.mesh.F.rows());
  }
}

}  // namespace

BODYMODEL_VERB(add_makehuman_body_verb) {
  auto a = std::make_shared<MakeHumanBodyArgs>();
  auto* cmd = app.add_subcommand(
      "makehuman-body",
      "Build a MakeHuman body from macro sliders (each in [0,1]), optionally posed, and write the\n"
      "body-only mesh in millimetres (13380 vertices; vertex order = the template).");
  cli::add_macro_slider_options(cmd, a->settings);
  cmd->add_option("--african", a->african, "ethnic weight; the others are rescaled to sum 1")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--asian", a->asian, "ethnic weight")->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--caucasian", a->caucasian, "ethnic weight")->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--pose", a->pose,
                  "a pose name (motion/poses: standing01, sit01, tpose, ...; or a CMU clip "
                  "02_02, 03_03, 12_03) or a BVH file; other skeletons are retargeted");
  cmd->add_option("--frame", a->frame, "frame of the BVH to use")->capture_default_str();
  cmd->add_flag("--translation", a->translation,
                "apply the BVH root translation (default: rotations only)");
  cmd->add_flag("--raw-targets", a->raw_targets,
                "use the defective upstream height targets as shipped (data README §10.1)");
  cmd->add_option("--out", a->out, "output mesh (.obj or .ply); omit to only print the figures");
  cmd->callback([a] { run(*a); });
}

}  // namespace bodymodel
