// bodymodel pose model.npz --in body.ply --bvh pose.bvh [--frame k] --out out.obj
#include <fmt/format.h>

#include "core/body_size.h"
#include "core/data_path.h"
#include "core/io/bvh.h"
#include "core/io/mesh_io.h"
#include "core/io/pose_csv.h"
#include "core/retarget.h"
#include "model/pose_edit.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

struct PoseArgs {
  std::string model, in, bvh, pose_csv, truth, out;
  int frame = 0;
  bool no_tips = false, no_joints = false;
  double damping = 1e-3;
  int transfer_neighbours = 8;
  bool every_bone = false;
  bool no_torso = false, no_volume = false;
};

}  // namespace

BODYMODEL_VERB(add_model_pose_verb) {
  auto a = std::make_shared<PoseArgs>();
  auto* cmd = app.add_subcommand(
      "pose",
      "Morph a body into a pose with the full model (§5.4): every joint angle of the pose is a\n"
      "label constraint, the body's other labels are held, and hands, feet and head are\n"
      "positional constraints placed by skinning the body with the model's skeleton.");
  cmd->add_option("model", a->model, "Model (.npz from `bodymodel build`)")->required();
  cmd->add_option("--in", a->in, "Body mesh with the model's topology, standard pose (OBJ/PLY, mm)")->required();
  cmd->add_option("--bvh", a->bvh, "Target pose: a BVH file (MakeHuman skeleton or a CMU clip)");
  cmd->add_option("--frame", a->frame, "Frame of the BVH file")->capture_default_str();
  cmd->add_option("--pose-csv", a->pose_csv, "Target pose as bone,rx,ry,rz rotation vectors (DB/truth/*.pose.csv)");
  cmd->add_option("--truth", a->truth, "Optional true posed mesh: report the mean vertex error (after a rigid fit)");
  cmd->add_flag("--no-tips", a->no_tips, "No positional constraints at hands, feet and head");
  cmd->add_flag("--tips-only", a->no_joints,
                "Constrain only hands, feet and head (the paper), not also elbows and knees");
  cmd->add_option("--damping", a->damping, "Damping of the joint-angle constraints (relative)")->capture_default_str();
  cmd->add_option("--transfer-neighbours", a->transfer_neighbours,
                  "Training scans whose pose change is transferred before the linear correction (0 = the "
                  "paper's linear regression only)")
      ->capture_default_str();
  cmd->add_flag("--no-torso-anchors", a->no_torso,
                "Place the torso by the tip constraints only (the paper), not also rigidly where skinning "
                "puts it");
  cmd->add_flag("--no-volume", a->no_volume,
                "Keep the decoded body's volume (default: offset along the normals to the input body's volume)");
  cmd->add_flag("--every-bone", a->every_bone,
                "Also constrain a few vertices on every bone, placed by skinning (beyond the paper)");
  cmd->add_option("--out", a->out, "Output mesh (OBJ/PLY)")->required();
  cmd->callback([a] {
    if (a->bvh.empty() == a->pose_csv.empty()) throw InputError("pose: give exactly one of --bvh and --pose-csv");
    BodyModel model = model_cli::load_model_for_cli(a->model);
    if (model.rig.empty()) throw InputError("'" + a->model + "' has no skeleton: rebuild it without --no-rig");
    Mesh body = read_mesh(a->in);
    model.check_topology(body.V, body.F, "'" + a->in + "'");
    check_body_size(body.V, "'" + a->in + "'");
    // The truth is checked before any work, so a wrong one fails before the output is written.
    Mesh truth;
    if (!a->truth.empty()) {
      truth = read_mesh(a->truth);
      model.check_topology(truth.V, truth.F, "'" + a->truth + "'");
      check_body_size(truth.V, "'" + a->truth + "'");
    }
    Pose pose;
    if (!a->bvh.empty()) {
      BvhMotion clip = read_bvh(a->bvh);
      Skeleton sk = model.rig.skeleton_for(body.V);
      if (a->frame < 0 || a->frame >= clip.frame_count())
        throw InputError(fmt::format("'{}' has {} frames; --frame {} is out of range", a->bvh, clip.frame_count(), a->frame));
      std::vector<Pose> poses = poses_from_bvh(clip, sk, data_file("makehuman"), false);
      pose = poses[a->frame];
    } else {
      // A file of another skeleton may name bones the model's rig lacks: they are skipped and
      // named. The root translation (a registration's placement on its scan) is not part of
      // the pose the body is morphed into.
      std::vector<std::string> skipped;
      pose = read_pose_csv(a->pose_csv, model.rig.bone_names, &skipped).pose;
      pose.root_translation.setZero();
      if (!skipped.empty())
        cli::warn(fmt::format("'{}': skipped {} bone(s) that the model's skeleton does not have: {}",
                              a->pose_csv, skipped.size(), fmt::join(skipped, ", ")));
    }
    RelativeRotationDecoder decoder(model.tmpl);
    PoseMorphOptions o;
    o.use_tip_constraints = !a->no_tips;
    o.constrain_elbows_and_knees = !a->no_joints;
    o.damping = a->damping;
    o.transfer_neighbours = std::max(0, a->transfer_neighbours);
    o.constrain_every_bone = a->every_bone;
    o.anchor_torso = !a->no_torso;
    o.preserve_volume = !a->no_volume;
    PoseMorphSummary s;
    Eigen::MatrixX3d out = pose_morph(model, decoder, body.V, pose, o, &s);
    write_mesh(a->out, out, body.F);
    fmt::print("joint-angle labels set {}, labels held {}, tip vertices {}, torso anchors {}, |z| = {:.3g}\n",
               s.pose_labels, s.kept_labels, s.tip_vertices, s.torso_anchors, s.change_norm);
    fmt::print("volume: decoded {:.2f} % of the input body's, result {:.2f} % (normal offset {:.2f} mm)\n",
               100 * s.volume_ratio_before, 100 * s.volume_ratio, s.volume_offset_mm);
    {
      // Where skinning the body with the model's rig puts it (the reference for the torso).
      const Eigen::Matrix3d G = canonical_rotation(model.rig, body.V);
      const Eigen::MatrixX3d Vc = body.V * G.transpose();
      const Eigen::MatrixX3d lbs =
          linear_blend_skinning(Vc, model.rig.weights, forward_kinematics(model.rig.skeleton_for(Vc), pose)) * G;
      const TorsoOffset t = torso_offset(out, lbs, torso_weight(model.rig));
      fmt::print("torso vs the skinned body: {:.1f} mm, {:.2f} deg (mean torso distance {:.1f} mm, {:.1f} after "
                 "a torso fit); mean vertex distance {:.1f} mm\n",
                 t.translation_mm, t.rotation_deg, t.mean_distance_mm, t.mean_distance_after_mm,
                 mean_vertex_error_after_rigid_fit(out, lbs));
    }
    if (!a->truth.empty()) {
      fmt::print("mean vertex error vs truth: {:.2f} mm (after a rigid fit)\n",
                 mean_vertex_error_after_rigid_fit(out, truth.V));
    }
    cli::info("wrote " + a->out);
  });
}

}  // namespace bodymodel
