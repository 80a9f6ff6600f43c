// Animating a character rig (tools/pipeline/character_file.h) with a BVH clip: the clip is
// retargeted to the character's template skeleton (core/retarget.h; MakeHuman-named files are
// applied directly), every sampled frame is skinned with the rig (runtime evaluator), checked
// (tools/pipeline/deformation_check.h: edge-length ratio to rest, flipped triangles) and written.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/io/bvh.h"
#include "core/progress.h"
#include "core/retarget.h"
#include "core/skeleton.h"
#include "tools/pipeline/character_file.h"
#include "tools/pipeline/deformation_check.h"

namespace bodymodel {

struct ClipPoses {
  std::vector<Pose> poses;        // every frame of the clip, for the skeleton
  double frame_time = 1.0 / 30;   // seconds
  std::string mapping;            // "MakeHuman names", "Poser/DAZ CMU map", "rig/cmu_mb.mhskel map"
  std::vector<std::string> ignored_joints;  // clip joints no bone takes its rotation from
};

// Throws InputError naming `what` and listing the clip joints that no map knows when the clip
// cannot be mapped onto the MakeHuman skeleton. `options` for clips that need a retarget map
// (its apply_root_translation is set from with_translation).
ClipPoses retarget_clip(const BvhMotion& clip, const Skeleton& skeleton, const std::filesystem::path& makehuman_dir,
                        bool with_translation, const std::string& what,
                        RetargetOptions options = RetargetOptions::for_animation());

struct AnimateOptions {
  double fps = 30;                // output frame rate (frames of the clip are sampled)
  int max_frames = 0;             // 0 = the whole clip
  std::string format = "ply";     // frame meshes: ply, obj, or none
  bool write_glb = true;          // animated.glb (SSD rig + the clip), when the writer exists
  int sheet_frames = 6;           // frames.png: this many frames side by side (0 = none)
  // details.csv: every flipped triangle (rig and its SSD) and every edge stretched beyond
  // details_edge_ratio, with its dominant bone and that bone's (and its parent's) joint angle.
  bool details = false;
  double details_edge_ratio = 2.5;
};

struct AnimateResult {
  int frames = 0;
  double frame_time = 0;               // seconds between output frames
  std::vector<int> source_frames;      // clip frame of each output frame
  std::vector<FrameCheck> rig, lbs, template_lbs;  // per output frame: the character's rig,
                                                   // its fitted SSD, the template weights
  double seconds = 0;                  // skinning + checks (excludes writing)
  bool wrote_glb = false;
  // Worst over frames.
  double max_edge_ratio(const std::vector<FrameCheck>& c) const;
  int max_flipped(const std::vector<FrameCheck>& c) const;
};

AnimateResult animate_character(const CharacterRigFile& character, const ClipPoses& clip,
                                const std::filesystem::path& dir, const AnimateOptions& options = {},
                                const ProgressCallback& progress = {});

// SSD weights of an LBS rig as a sparse #V by #B matrix.
SkinWeights skin_weights_of(const SkinningRig& lbs);

}  // namespace bodymodel
