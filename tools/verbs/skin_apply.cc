// `bodymodel skin apply rig.npz --bvh clip.bvh --out frames/`: pose a rig (SSD, AS or MWE) with
// every frame of a BVH clip, retargeted to the rig's skeleton, one mesh per frame. Frames already
// in the folder are kept (a rerun resumes); each file is written atomically.
#include <fmt/format.h>

#include <memory>

#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "skinning/rig_io.h"
#include "tools/console.h"
#include "tools/pipeline/folder_settings.h"
#include "tools/verb.h"
#include "tools/verbs/skin_common.h"
#include "tools/verbs/skin_motion.h"

namespace bodymodel::cli {
namespace {

struct ApplyArgs {
  std::string rig, bvh, out, format = "obj";
  int first = 0, count = 0, every = 1;
  bool root_translation = false, force = false;
};

void run_apply(const ApplyArgs& a) {
  if (a.format != "obj" && a.format != "ply")
    throw InputError("--format must be obj or ply, found '" + a.format + "'");
  // Frame k is a function of the rig, the clip and the root translation: a folder of frames made
  // from others is refused, not resumed (tools/pipeline/folder_settings.h). --first, --count and
  // --every only choose frames.
  const nlohmann::json settings = {{"verb", "skin apply"},
                                   {"rig", file_fingerprint(a.rig)},
                                   {"bvh", file_fingerprint(a.bvh)},
                                   {"root_translation", a.root_translation}};
  ResumableFolder folder(a.out, "skin-apply.json", settings, a.force, [](const std::string& n) {
    return n.rfind("frame_", 0) == 0 && (n.size() > 4 && (n.substr(n.size() - 4) == ".obj" || n.substr(n.size() - 4) == ".ply"));
  });
  Eigen::MatrixX3i F;
  Skeleton stored;
  const SkinningRig rig = load_rig(a.rig, &F, nullptr, &stored);
  if (F.rows() == 0) throw InputError(a.rig + ": the rig has no faces (key 'faces' is empty): cannot write meshes");
  std::string source;
  const Skeleton skeleton = skeleton_for_rig(rig, stored, &source);
  if (skeleton.bone_count() == 0)
    throw InputError(a.rig + ": the rig has no skeleton (no 'skeleton_names' key, and it is not on the MakeHuman "
                     "body): a BVH clip cannot drive its " + std::to_string(rig.bone_count) + " bones");
  const ClipFrames clip = clip_bone_maps(a.bvh, skeleton, a.first, a.count, a.every, a.root_translation);
  folder.open();
  int written = 0, kept = 0;
  ProgressBar bar("skin apply");
  for (size_t k = 0; k < clip.frames.size(); ++k) {
    const auto file = std::filesystem::path(a.out) / fmt::format("frame_{:05d}.{}", clip.frames[k], a.format);
    bar.update(double(k) / clip.frames.size(), file.filename().string());
    if (std::filesystem::exists(file)) {   // complete: files appear only by an atomic rename
      ++kept;
      continue;
    }
    const Eigen::MatrixX3d V = evaluate_rig(rig, clip.maps[k]);
    if (!V.allFinite()) throw NumericalError(fmt::format("skin apply: frame {} produced non-finite positions", clip.frames[k]));
    write_mesh(file, V, F);
    ++written;
  }
  bar.finish();
  info(fmt::format("{} rig ({} vertices, {} bones, skeleton: {}): {} frames of {} → {} ({} written, {} already there)",
                   skinning_method_name(rig.method), rig.vertex_count(), rig.bone_count, source, clip.frames.size(),
                   a.bvh, a.out, written, kept));
}

}  // namespace

BODYMODEL_VERB(add_skin_apply_verb) {
  CLI::App* skin = skin_group(app);
  auto* cmd = skin->add_subcommand(
      "apply",
      "Pose a rig (.npz from `skin fit` or `bodymodel character`) with a BVH clip, one mesh per frame\n"
      "(frame_NNNNN.obj). The clip is retargeted to the rig's skeleton (stored in the .npz, or the\n"
      "MakeHuman default skeleton for rigs on the MakeHuman body). Existing frames of the same rig and clip\n"
      "are skipped; OUT/skin-apply.json records them.");
  auto a = std::make_shared<ApplyArgs>();
  cmd->add_option("rig", a->rig, "Rig (.npz)")->required();
  cmd->add_option("--bvh", a->bvh, "Motion clip (.bvh: MakeHuman bone names or a CMU clip)")->required();
  cmd->add_option("--out", a->out, "Output folder")->required();
  cmd->add_option("--first", a->first, "First BVH frame")->capture_default_str();
  cmd->add_option("--count", a->count, "Number of frames (0 = to the end)")->capture_default_str();
  cmd->add_option("--every", a->every, "Use every k-th frame")->capture_default_str();
  cmd->add_flag("--root-translation", a->root_translation, "Apply the clip's root translation (default: in place)");
  cmd->add_option("--format", a->format, "obj or ply")->capture_default_str();
  cmd->add_flag("--force", a->force,
                "Replace the frames in OUT made from another rig, clip or root translation (without it such a "
                "folder is refused; frames of the same ones are kept)");
  cmd->callback([a] { run_apply(*a); });
}

}  // namespace bodymodel::cli
