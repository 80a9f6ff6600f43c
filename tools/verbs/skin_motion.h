// Shared by `bodymodel skin apply` and `skin export-gltf`: the skeleton a rig's bones belong to,
// and the bone maps of a BVH clip on that skeleton.
#pragma once

#include <fmt/format.h>

#include <filesystem>
#include <string>
#include <vector>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/bvh.h"
#include "core/makehuman.h"
#include "core/retarget.h"
#include "core/skeleton.h"
#include "skinning/skinning_rig.h"

namespace bodymodel::cli {

constexpr int kMakeHumanBodyVertices = 13380, kMakeHumanAllVertices = 19158;

// The rig's skeleton: `stored` (from the .npz) when it has bones; otherwise, for a rig on the
// MakeHuman body (13380 body or 19158 full vertices, one influence per default-skeleton bone),
// the default skeleton placed on the rig's rest mesh; otherwise an empty skeleton.
// `source` says which ("stored", "makehuman", "none").
inline Skeleton skeleton_for_rig(const SkinningRig& rig, const Skeleton& stored, std::string* source) {
  if (stored.bone_count() > 0) {
    *source = "stored";
    return stored;
  }
  const int n = rig.vertex_count();
  if (n == kMakeHumanBodyVertices || n == kMakeHumanAllVertices) {
    const MakeHuman mh = MakeHuman::load();
    Skeleton s = n == kMakeHumanBodyVertices ? mh.skeleton_from_body(rig.rest) : mh.skeleton(rig.rest);
    if (s.bone_count() == rig.bone_count) {
      *source = "makehuman";
      return s;
    }
  }
  *source = "none";
  return Skeleton{};
}

struct ClipFrames {
  std::vector<int> frames;               // BVH frame indices used
  std::vector<BoneTransforms> maps;      // bone maps per used frame
  double frame_time = 1.0 / 30;          // seconds between used frames
};

// Bone maps of frames first, first + every, ... (at most `count`, 0 = all) of `bvh` on
// `skeleton`: BVHs with the skeleton's bone names apply directly, others (CMU clips) are
// retargeted (core/retarget.h).
inline ClipFrames clip_bone_maps(const std::string& bvh, const Skeleton& skeleton, int first, int count, int every,
                                 bool root_translation) {
  if (every < 1) throw InputError(fmt::format("--every must be at least 1, found {}", every));
  if (count < 0) throw InputError(fmt::format("--count must be 0 (all) or positive, found {}", count));
  const BvhMotion clip = read_bvh(bvh);
  if (clip.frame_count() == 0) throw InputError("'" + bvh + "' has no frames");
  if (first < 0 || first >= clip.frame_count())
    throw InputError(fmt::format("'{}' has {} frames; --first {} is out of range", bvh, clip.frame_count(), first));
  const std::vector<Pose> poses = poses_from_bvh(clip, skeleton, data_file("makehuman"), root_translation);
  ClipFrames out;
  out.frame_time = clip.frame_time * every;
  for (int f = first; f < clip.frame_count() && (count == 0 || static_cast<int>(out.frames.size()) < count); f += every) {
    out.frames.push_back(f);
    out.maps.push_back(forward_kinematics(skeleton, poses[static_cast<size_t>(f)]));
  }
  return out;
}

}  // namespace bodymodel::cli
