// Animating a character rig (tools/pipeline/character_file.h) with a BVH clip: the clip is
// retargeted to the character's template skeleton (core/retarget.h; MakeHuman-named files are
// applied directly), every sampled frame is skinned with the rig (runtime evaluator), checked
// (tools/pipeline/deformation_check.h: edge-length ratio to rest, flipped triangles) and written.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/fold_repair.h"
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
  // Leading frames dropped (lead_in_frames): 1 when the file starts with its rest pose one frame
  // before the motion, as cgspeed's CMU conversions (12_03) do. lead_in_jump_deg: that jump.
  int lead_in = 0;
  double lead_in_jump_deg = 0;
};

// 1 when the clip's first frame is a lead-in, not motion: some bone turns more than 30° from it
// to the second frame, and more than 10 times the median largest turn between the frames after
// it (a player would show it as a snap); else 0. `jump_deg` gets frame 0's largest turn.
int lead_in_frames(const std::vector<Pose>& poses, double* jump_deg = nullptr);

// Throws InputError naming `what` and listing the clip joints that no map knows when the clip
// cannot be mapped onto the MakeHuman skeleton. A lead-in first frame (lead_in_frames) is dropped.
// `options` for clips that need a retarget map (its apply_root_translation is set from
// with_translation).
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
  // Fold repair of every frame with flipped triangles (core/fold_repair.h,
  // repair_folds_against_normals): each flipped area of the skinned frame, grown by a few rings,
  // is re-solved from the rest mesh's local shape rotated and scaled onto the area's border; the
  // flip test is the check's (rest normal turned by the triangle's dominant bone), and a solve is
  // kept only where it leaves fewer flips, so the count never grows. A post-process of the
  // frames (.ply/.obj, frames.png, animation.csv): the glb's LBS rig is not repaired. What it
  // repairs are LBS creases at the armpit (upperarm01/02) and groin (spine05) at ordinary angles
  // of a walk (upper arm 29-49 deg from hm08's A-pose, thighs 20-37 deg forward), inside the range
  // of motion the character was trained on (its training poses include frames of the same CMU
  // clips), in every frame; the rig's SSD base folds more (demo character at 5a4a148, 02_02: 277
  // flipped triangles over all frames with MWE, 448 with its SSD).
  bool repair = true;
  // The rest shape's Laplacian coordinates turned per vertex by its blended bone rotation (SSD
  // weights) instead of one Procrustes fit per region's border. Off: the blended rotations
  // rebuild the LBS crease they are meant to repair (demo character 02_02: worst frame 10 -> 7
  // flipped with them, 10 -> 0 with the region fit).
  bool repair_vertex_rotations = false;
  FoldRepairOptions repair_options = default_animation_repair();
  // Frames with flips left after the repair are repaired again from the skinned frame with these
  // first-ring widths (in turn, until none are left; the attempt with the fewest is kept): with
  // rings 2 alone a small crowd character kept an armpit triangle in some frames of each clip.
  std::vector<int> repair_retry_rings = {4, 1, 3, 6};
  static FoldRepairOptions default_animation_repair();
};

struct AnimateResult {
  int frames = 0;
  double frame_time = 0;               // seconds between output frames
  std::vector<int> source_frames;      // clip frame of each output frame
  std::vector<FrameCheck> rig, lbs, template_lbs;  // per output frame: the character's rig
                                                   // (after the fold repair, if on), its fitted
                                                   // SSD, the template weights
  std::vector<FrameCheck> rig_before_repair;       // the character's rig as skinned
  int repaired_frames = 0;             // frames the repair changed
  double seconds = 0;                  // skinning + checks + repair (excludes writing)
  double skin_seconds = 0;             // the rig's skinning alone (runtime evaluator)
  double repair_seconds = 0;           // the fold repair alone (flip references + solves)
  bool wrote_glb = false;
  // Worst over frames.
  double max_edge_ratio(const std::vector<FrameCheck>& c) const;
  int max_flipped(const std::vector<FrameCheck>& c) const;
};

AnimateResult animate_character(const CharacterRigFile& character, const ClipPoses& clip,
                                const std::filesystem::path& dir, const AnimateOptions& options = {},
                                const ProgressCallback& progress = {});

// Rotation of each vertex in a frame: the normalised weighted sum of its bones' rotation
// quaternions (SSD weights of `lbs`), #V. Used by the fold repair.
std::vector<Eigen::Matrix3d> blended_vertex_rotations(const SkinningRig& lbs, const BoneTransforms& M);

// SSD weights of an LBS rig as a sparse #V by #B matrix.
SkinWeights skin_weights_of(const SkinningRig& lbs);

}  // namespace bodymodel
