// `bodymodel skin export-gltf`: an LBS character as glTF 2.0 binary (.glb) with its skeleton, up to 4
// weights per vertex, inverse bind matrices and optionally an animation from a BVH clip (or the
// rig's own fitted poses). Positions in metres (input mm × 0.001 by default).
#include <fmt/format.h>

#include <memory>

#include "core/geometry.h"
#include "core/io/mesh_io.h"
#include "core/io/npz.h"
#include "skinning/gltf_export.h"
#include "skinning/rig_io.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/skin_common.h"
#include "tools/verbs/skin_motion.h"

namespace bodymodel::cli {
namespace {

struct GltfArgs {
  std::string rig, mesh, bvh, out;
  int first = 0, count = 0, every = 1;
  bool root_translation = false, no_animation = false;
  double fps = 0, scale = 0.001;
};

SkinWeights weights_of(const SkinningRig& lbs) {
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < lbs.vertex_count(); ++i)
    for (int k = 0; k < lbs.max_influences(); ++k)
      if (lbs.influences(i, k) >= 0 && lbs.coefficients(i, k) > 0)
        t.emplace_back(i, lbs.influences(i, k), lbs.coefficients(i, k));
  SkinWeights W(lbs.vertex_count(), lbs.bone_count);
  W.setFromTriplets(t.begin(), t.end());
  return W;
}

void run_export(const GltfArgs& a) {
  if (!a.rig.empty() && !a.mesh.empty()) throw InputError("give at most one of --rig and --mesh");
  Eigen::MatrixX3d V;
  Eigen::MatrixX3i F;
  Skeleton skeleton;
  SkinWeights W;
  std::vector<BoneTransforms> rig_poses;
  std::string what;
  bool flat = false;   // a rig without a skeleton: unconnected joints
  if (!a.rig.empty()) {
    Skeleton stored;
    SkinningRig rig = load_rig(a.rig, &F, &rig_poses, &stored);
    if (rig.method != SkinningMethod::lbs) {
      // Character rigs (`bodymodel character`) carry their SSD weights beside the MWE rig.
      const Npz z = Npz::load(a.rig);
      if (!z.has("lbs_influences") || !z.has("lbs_coefficients"))
        throw InputError(a.rig + ": a " + skinning_method_name(rig.method) + " rig cannot be written as glTF (linear "
                         "blend skinning only) and the file has no 'lbs_influences'/'lbs_coefficients' SSD weights");
      rig.method = SkinningMethod::lbs;
      rig.influences = z.int_matrix("lbs_influences");
      rig.coefficients = z.matrix("lbs_coefficients");
      rig.validate(a.rig + " (SSD weights)");
    }
    if (F.rows() == 0) throw InputError(a.rig + ": the rig has no faces (key 'faces' is empty)");
    std::string source;
    skeleton = skeleton_for_rig(rig, stored, &source);
    if (skeleton.bone_count() == 0) {
      skeleton = flat_skeleton(rig.bone_count);
      flat = true;
    }
    V = rig.rest;
    W = weights_of(rig);
    what = fmt::format("{} (skeleton: {})", a.rig, source == "none" ? "unconnected bones" : source);
  } else {
    const MakeHuman mh = MakeHuman::load();
    if (a.mesh.empty()) {
      const MakeHuman::Body body = mh.body(MacroSettings{});
      V = body.mesh.V;
      F = body.mesh.F;
      skeleton = body.skeleton;
      W = body.weights;
      what = "the default MakeHuman body";
    } else {
      const Mesh m = read_mesh(a.mesh);
      if (m.V.rows() != kMakeHumanBodyVertices)
        throw InputError(fmt::format("{}: {} vertices, expected the {} of the MakeHuman body (hm08 topology)", a.mesh,
                                     m.V.rows(), kMakeHumanBodyVertices));
      V = m.V;
      F = m.F.rows() ? m.F : mh.body_faces();
      skeleton = mh.skeleton_from_body(V);
      W = mh.body_weights();
      what = a.mesh + " (MakeHuman default skeleton and weights)";
    }
  }
  GltfAnimation anim;
  if (!a.no_animation) {
    if (!a.bvh.empty()) {
      if (flat)
        throw InputError(a.rig + ": the rig has no skeleton, so a BVH clip cannot drive it");
      const ClipFrames clip = clip_bone_maps(a.bvh, skeleton, a.first, a.count, a.every, a.root_translation);
      anim.frames = clip.maps;
      anim.frame_time = clip.frame_time;
      anim.name = std::filesystem::path(a.bvh).stem().string();
    } else if (!rig_poses.empty()) {
      anim.frames = rig_poses;
      anim.name = "fitted poses";
    }
  }
  if (a.fps < 0) throw InputError(fmt::format("--fps must be positive, found {}", a.fps));
  if (a.fps > 0) anim.frame_time = 1.0 / a.fps;
  GltfExportOptions o;
  o.unit_scale = a.scale;
  const GltfExportSummary s = write_skinned_gltf(a.out, V, F, vertex_normals(V, F), skeleton, W,
                                                 anim.frames.empty() ? nullptr : &anim, o);
  info(fmt::format("wrote {} from {}: {} vertices, {} triangles, {} joints, {} animation frames, {:.1f} kB; {} "
                   "vertices had more than 4 weights (largest share dropped {:.3f}, renormalised)",
                   a.out, what, s.vertices, s.triangles, s.joints, s.frames, s.bytes / 1024.0, s.vertices_truncated,
                   s.max_dropped_weight));
}

}  // namespace

BODYMODEL_VERB(add_skin_gltf_verb) {
  CLI::App* skin = skin_group(app);
  auto* cmd = skin->add_subcommand(
      "export-gltf",
      "Write an SSD (linear blend) character as glTF 2.0 binary (.glb): mesh in metres, normals,\n"
      "skeleton, ≤4 weights per vertex, inverse bind matrices, and an animation from --bvh (or the\n"
      "rig's fitted poses). Source: --rig rig.npz, --mesh body.obj (MakeHuman body topology), or\n"
      "neither (the default MakeHuman body).");
  auto a = std::make_shared<GltfArgs>();
  cmd->add_option("--rig", a->rig, "SSD rig .npz (skin fit --method ssd), or a character rig with SSD weights");
  cmd->add_option("--mesh", a->mesh, "A body with the MakeHuman body topology (13380 vertices, mm)");
  cmd->add_option("--bvh", a->bvh, "Animation clip (.bvh; retargeted to the skeleton)");
  cmd->add_option("--first", a->first, "First BVH frame")->capture_default_str();
  cmd->add_option("--count", a->count, "Number of frames (0 = to the end)")->capture_default_str();
  cmd->add_option("--every", a->every, "Use every k-th frame")->capture_default_str();
  cmd->add_flag("--root-translation", a->root_translation, "Apply the clip's root translation");
  cmd->add_flag("--no-animation", a->no_animation, "Rest pose only");
  cmd->add_option("--fps", a->fps, "Frames per second (default: the clip's rate, or 30)");
  cmd->add_option("--scale", a->scale, "Input unit → metres")->capture_default_str();
  cmd->add_option("--out", a->out, "Output .glb")->required();
  cmd->callback([a] { run_export(*a); });
}

}  // namespace bodymodel::cli
