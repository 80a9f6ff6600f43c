// Retargeting motion clips whose skeleton differs from the MakeHuman default skeleton
// (data README §7.2): the CMU clips in motion/cmu/.
//
//   02_02, 03_03  Poser/DAZ-style names (hip, abdomen, chest, lShldr, lThigh, ...)  → built-in map
//   12_03         cgspeed/MotionBuilder CMU names (Hips, LeftUpLeg, ...)            → the
//                 `reference` lists of rig/cmu_mb.mhskel (LeftHandIndex1 = LeftHandFinger1)
//
// Three steps, as the README suggests:
//  1. Name map: each source joint drives a chain of default-skeleton bones (`RetargetMap`).
//  2. Rest-pose correction: the clips rest in a T-pose, hm08 in an A-pose. For each corrected
//     chain, A = the smallest rotation taking the hm08 rest chain direction (head of its first
//     bone → tail of its last) onto the source rest direction (joint → its mapped child or End
//     Site). The world rotation of every bone of the chain is Q_b = G_j · A, where G_j is the
//     source joint's accumulated world rotation (file axes converted to hm08). By default only
//     the limb chains (upper arm, forearm, hand; thigh, shin, foot) are corrected: the arms are
//     where the two rest poses differ, and the clips' leg directions follow their own hip
//     widths (12_03's thighs converge: uncorrected, its walk crossed the legs). A mocap
//     skeleton's spine, neck and collars are straight by construction, not by the actor's
//     posture; aligning hm08's S-curved spine, neck and clavicles onto them bent a standing
//     body by 17–39° per joint
//     (12_03's rest frame: neck01 39°, spine02 25°, clavicle.L 23° but clavicle.R 18°) and
//     stretched the neck, shoulders and crotch in every frame. Chains not corrected use their
//     source parent's A. Bones that no chain drives keep identity relative to their parent.
//     A spine or neck chain driven by one source joint (abdomen → spine04, spine03, chest →
//     spine02, spine01, neck → neck01..neck03) shares the joint's rotation relative to the
//     chain's parent equally among its bones (each takes the n-th root), so the hm08 spine bends
//     along its length like a back instead of folding at its lowest bone. spine05, the top of
//     the pelvis, moves with the hips (as in rig/cmu_mb.mhskel: Hips → root, spine05): 02_02's
//     abdomen bends up to 35° against the hips, and all of it at spine05 stretched the groin
//     far beyond its rest length (docs/benchmarks.md#figures-behind-code-comments).
//     The chain's last bone ends where it did.
//  3. Root translation: scaled by (hm08 thigh+shin length / source thigh+shin length), with
//     the horizontal travel measured from frame 0 and the height from the source's rest hip
//     height above its lowest rest joint, so a standing frame keeps the hm08 feet on the rest
//     floor.
// The result is a `Pose` per frame for the MakeHuman skeleton, ready for forward_kinematics.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/io/bvh.h"
#include "core/skeleton.h"

namespace bodymodel {

struct RetargetMap {
  struct Entry {
    std::string source;                // BVH joint name
    std::vector<std::string> targets;  // default-skeleton bones it drives, first → last of a chain
    bool correct_rest = true;          // false: no rest correction of its own (inherits parent's)
  };
  std::vector<Entry> entries;

  // The map for the Poser/DAZ-style CMU conversions (02_02, 03_03).
  static RetargetMap poser_cmu();
  // The map given by an .mhskel's `reference` lists (e.g. rig/cmu_mb.mhskel for 12_03).
  // Rig bone names the BVH spells differently (LeftHandFinger1 → LeftHandIndex1) are renamed.
  static RetargetMap from_mhskel(const std::filesystem::path& mhskel);
  // Picks the map whose source names best match `clip`'s joints: poser_cmu, or from_mhskel of
  // `makehuman_dir`/rig/cmu_mb.mhskel. Throws InputError when fewer than half the clip's
  // joints are known to either.
  static RetargetMap for_clip(const BvhMotion& clip, const std::filesystem::path& makehuman_dir);
};

struct RetargetOptions {
  std::optional<BvhUpAxis> up_axis;   // default: guess_bvh_up_axis (Y for the CMU clips)
  // Off by default, like BvhPoseOptions: the body stays at its rest position (a walk's root
  // travels metres, which would carry a scanned body out of a scanner). On: see step 3 above.
  bool apply_root_translation = false;
  bool start_at_origin = true;        // horizontal translation relative to frame 0
  // Which chains get a rest correction of their own (step 2). `limbs`: arm and leg chains
  // (default). `all_chains`: every chain except root, pelvis, fingers and toes (the behaviour
  // before 336b371, kept for comparison).
  enum class RestCorrection { limbs, all_chains };
  RestCorrection rest_correction = RestCorrection::limbs;
  // The two options below are off by default (the synthetic database, `skin apply` and the
  // encoding tests keep the poses they were measured with); for_animation() turns them on for
  // `bodymodel animate`, `character` and `crowd` (tools/pipeline/).
  //
  // Twist split of the limbs' two-bone chains (upperarm01/02, lowerarm01/02, upperleg01/02,
  // lowerleg01/02: MakeHuman's second bone is a twist bone). The chain's rotation relative to
  // its parent, R = S·T (T: twist about the first bone's rest axis, S: the swing), is shared as
  // first bone S·T^f, second bone T^(1−f); the chain ends as before. f = 1 puts all of the
  // twist at the shoulder/hip, where linear blend skinning collapses the armpit and groin: the
  // CMU walks hold the humerus 20–53° internally rotated against hm08's A-pose roll, and that
  // twist at upperarm01 flipped 5–7 armpit triangles per arm in every frame (0 in MakeHuman's
  // standing poses, twist −18..7°). 0.5 halves it (animated demo character, both CMU walks:
  // flipped triangles in all frames 911 → 540 and 2048 → 1995 with its SSD).
  double first_bone_twist = 1;
  // Fingers and thumbs (finger*, metacarpal*) follow the clip. CMU captures no finger
  // articulation: its thumb and finger joints are estimated from one or two hand markers, and
  // 12_03's thumb swings 54° (twist 37°), folding the thumb. Off: they keep their rest pose
  // relative to the hand.
  bool drive_fingers = true;

  // first_bone_twist 0.5, drive_fingers false.
  static RetargetOptions for_animation();
};

// Drives `target` (the MakeHuman default skeleton, any body shape) with `clip`. The constructor
// refuses (InputError naming clip.source) a clip with two joints of one name, or without a
// joint the map needs to drive a body or limb bone (a renamed joint: its chain would stay at
// rest); joints for fingers, toes and eyes may be missing.
class Retargeter {
 public:
  Retargeter(const BvhMotion& clip, const Skeleton& target, const RetargetMap& map,
             const RetargetOptions& options = {});

  int frame_count() const { return clip_.frame_count(); }
  double frame_time() const { return clip_.frame_time; }
  // Pose of the target skeleton for `frame` (InputError if out of range).
  Pose pose(int frame) const;
  std::vector<Pose> all_poses() const;

  // Source-unit → target-unit scale of the root translation.
  double translation_scale() const { return scale_; }
  // Map entries whose source joint is not in the clip (ignored).
  const std::vector<std::string>& unmatched_sources() const { return unmatched_; }
  // Number of target bones driven directly by a source joint.
  int driven_bone_count() const;

 private:
  BvhMotion clip_;
  Skeleton target_;
  RetargetOptions options_;
  Eigen::Matrix3d C_;                      // file axes → hm08 axes
  std::vector<int> driver_;                // #target bones: driving source joint or −1
  std::vector<int> spread_;                // #target bones: length of the spine/neck chain whose
                                           // bend this bone shares (0 = not shared)
  std::vector<int> twist_child_;            // #target bones: second bone of a twist-split limb chain or −1
  std::vector<Eigen::Matrix3d> correction_;  // #source joints: rest correction A
  double scale_ = 1;
  double rest_hip_height_ = 0;             // source units, above its lowest rest joint
  Eigen::Vector3d start_ = Eigen::Vector3d::Zero();  // root position of frame 0 (file)
  std::vector<std::string> unmatched_;
};

// Throws InputError (naming clip.source) when `clip`, applied to `skeleton` by bone name as
// bvh_frame_to_pose does, would lose or misplace motion: two joints share a name; a joint that
// names no bone rotates (more than 0.01 degrees in some frame: renamed or foreign joints, whose
// rotation would be dropped); or a joint hangs below a bone in the clip that is not its ancestor
// in the skeleton (a joint given the root's or another bone's name). Joints that name no bone
// and never rotate (tpose.bvh's metatarsals) and skeleton bones the clip lacks (identity) pass.
void check_clip_by_bone_name(const BvhMotion& clip, const Skeleton& skeleton);

// Poses for `skeleton` from any BVH: files whose joints carry the skeleton's bone names
// (motion/poses/*.bvh) are applied directly (bvh_frame_to_pose, rotations only unless
// `with_translation`; checked with check_clip_by_bone_name); other skeletons (the CMU clips) are
// retargeted with RetargetMap::for_clip.
std::vector<Pose> poses_from_bvh(const BvhMotion& clip, const Skeleton& skeleton,
                                 const std::filesystem::path& makehuman_dir,
                                 bool with_translation = false);

}  // namespace bodymodel
