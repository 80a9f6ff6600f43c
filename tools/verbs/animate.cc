// bodymodel animate char/rig.npz --bvh clip.bvh --out frames/
#include <fmt/format.h>

#include <memory>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/bvh.h"
#include "tools/console.h"
#include "tools/pipeline/animate_job.h"
#include "tools/pipeline/output_folder.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

struct AnimateArgs {
  std::string rig, bvh, out;
  AnimateOptions options;
  bool force = false, no_translation = false, no_repair = false, whole_limb_twist = false, drive_fingers = false;
};

}  // namespace

BODYMODEL_VERB(add_animate_verb) {
  auto a = std::make_shared<AnimateArgs>();
  auto* cmd = app.add_subcommand(
      "animate",
      "Animate a character rig (char/rig.npz from `bodymodel character`) with a BVH clip: CMU clips\n"
      "are retargeted to the template skeleton (MakeHuman-named files apply directly). Writes\n"
      "OUT/frame_NNNN.ply, OUT/animation.csv (per frame: largest and smallest edge-length ratio to\n"
      "rest and flipped triangles, for the rig, its SSD and the template weights; the rig before and\n"
      "after the fold repair), OUT/frames.png and OUT/animated.glb (SSD rig with the clip, not\n"
      "repaired). Frames are fold-repaired unless --no-repair.");
  cmd->add_option("rig", a->rig, "Character rig (.npz from `bodymodel character`)")->required();
  cmd->add_option("--bvh", a->bvh, "Motion clip (BVH)")->required();
  cmd->add_option("--out", a->out, "Output folder (must not exist unless --force)")->required();
  cmd->add_option("--fps", a->options.fps, "Output frame rate (the clip is sampled)")->capture_default_str();
  cmd->add_option("--max-frames", a->options.max_frames, "At most this many frames (0 = all)")->capture_default_str();
  cmd->add_option("--format", a->options.format, "Frame meshes: ply, obj or none")->capture_default_str();
  cmd->add_flag("--details", a->options.details,
                "Also write OUT/details.csv: each flipped triangle and each edge over --details-ratio x rest, "
                "per frame, with its dominant bone and joint angles");
  cmd->add_option("--details-ratio", a->options.details_edge_ratio, "Edge ratio listed by --details")
      ->capture_default_str();
  cmd->add_flag("--whole-limb-twist", a->whole_limb_twist,
                "Retarget: the limb's whole twist at its first bone (upperarm01, upperleg01, ...), as before "
                "the twist split (for comparison)");
  cmd->add_flag("--drive-fingers", a->drive_fingers,
                "Retarget: fingers and thumbs follow the clip (CMU's are estimated from one or two hand markers)");
  cmd->add_flag("--no-repair", a->no_repair,
                "No fold repair of the frames (on by default: each frame's flipped triangles are re-solved "
                "from the rest mesh's local shape, core/fold_repair.h; animated.glb is never repaired)");
  cmd->add_flag("--repair-vertex-rotations", a->options.repair_vertex_rotations,
                "Fold repair: turn the rest shape by each vertex's blended bone rotation instead of one "
                "Procrustes fit per region (for comparison)");
  cmd->add_option("--repair-rings", a->options.repair_options.rings,
                  "Fold repair: vertex rings grown around the flipped triangles (first pass)")
      ->capture_default_str();
  cmd->add_option("--repair-passes", a->options.repair_options.passes,
                  "Fold repair: passes while flips remain (pass p grows rings + p rings)")
      ->capture_default_str();
  cmd->add_option("--repair-max-edge-ratio", a->options.repair_options.max_edge_ratio,
                  "Fold repair: refuse a region's solve that stretches an edge beyond this x rest (0 = no test)")
      ->capture_default_str();
  cmd->add_flag("--no-translation", a->no_translation, "Keep the root in place (no travel)");
  cmd->add_flag("--force", a->force, "Replace an existing output folder");
  cmd->callback([a] {
    StagedFolder out(a->out, a->force);
    CharacterRigFile ch = load_character_rig(a->rig);
    BvhMotion clip = read_bvh(a->bvh);
    RetargetOptions ro = RetargetOptions::for_animation();
    if (a->whole_limb_twist) ro.first_bone_twist = 1;
    if (a->drive_fingers) ro.drive_fingers = true;
    ClipPoses poses = retarget_clip(clip, ch.skeleton, data_file("makehuman"), !a->no_translation, a->bvh, ro);
    cli::info(fmt::format("{}: {} frames at {:.0f} fps, mapped by {}", a->bvh, poses.poses.size(),
                          1 / poses.frame_time, poses.mapping));
    if (poses.lead_in)
      cli::info(fmt::format("its first frame is a lead-in (a {:.0f}° turn to the next, the motion starts after it): skipped",
                            poses.lead_in_jump_deg));
    if (!poses.ignored_joints.empty()) {
      std::string list;
      for (size_t i = 0; i < poses.ignored_joints.size(); ++i) list += (i ? ", " : "") + poses.ignored_joints[i];
      cli::info(fmt::format("{} clip joints drive no bone (ignored): {}", poses.ignored_joints.size(), list));
    }
    a->options.repair = !a->no_repair;
    cli::ProgressBar bar("animate");
    AnimateResult r = animate_character(ch, poses, out.path(), a->options, bar.callback());
    bar.finish(fmt::format("{} frames, skinning + checks {:.1f} s", r.frames, r.seconds));
    out.commit();
    fmt::print("frames                      {} ({:.1f} fps)\n", r.frames, 1 / r.frame_time);
    fmt::print("max edge ratio to rest      rig {:.2f}, its SSD {:.2f}, template weights {:.2f}\n",
               r.max_edge_ratio(r.rig), r.max_edge_ratio(r.lbs), r.max_edge_ratio(r.template_lbs));
    fmt::print("flipped triangles (worst)   rig {}, its SSD {}, template weights {}\n", r.max_flipped(r.rig),
               r.max_flipped(r.lbs), r.max_flipped(r.template_lbs));
    if (a->options.repair) {
      int frames_flipped = 0;
      for (auto& c : r.rig_before_repair) frames_flipped += c.flipped > 0;
      fmt::print("before the fold repair      rig: worst frame {} flipped, {} of {} frames with flips, max edge "
                 "ratio {:.2f}\n",
                 r.max_flipped(r.rig_before_repair), frames_flipped, r.frames, r.max_edge_ratio(r.rig_before_repair));
      fmt::print("fold repair cost            {:.2f} x the rig's skinning ({:.3f} s vs {:.3f} s, same run; "
                 "the glb is not repaired)\n",
                 r.skin_seconds > 0 ? r.repair_seconds / r.skin_seconds : 0.0, r.repair_seconds, r.skin_seconds);
    }
    cli::info("wrote " + a->out);
  });
}

}  // namespace bodymodel
