// A rigged character from the statistical model (docs/method.md §6.6; Hasler
// et al. 2009 §5.4 for the poses, Wang & Phillips 2002 for the rig):
//  1. a range of motion: MakeHuman's static poses and frames of the CMU clips (the poses the
//     synthetic database draws from), each turned into a mesh by the model's POSE MORPHING
//     (model/pose_edit.h), plus in-between poses made by interpolating two morphs in encoding
//     space (relative rotations: limbs keep their length) — training examples; other CMU frames
//     and other in-betweens are held out;
//  2. bone transforms of every example from the template skeleton placed in the body
//     (model.rig.skeleton_for) by forward kinematics of the pose;
//  3. SSD weights fitted on the template's influence sets, Animation Space and MWE (delta space
//     over that SSD) fitted to the training examples (skinning/ fit_lbs, fit_animation_space,
//     fit_mwe);
//  4. errors of every rig against the model's own pose morphs, training and held out (mm).
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "core/fold_repair.h"
#include "core/progress.h"
#include "core/skeleton.h"
#include "model/body_model.h"
#include "model/pose_edit.h"
#include "skinning/fit_animation_space.h"
#include "skinning/fit_lbs.h"
#include "skinning/fit_mwe.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

struct RangeOfMotionOptions {
  // MakeHuman static poses left out (self-contact or lying/handstand: the synthetic database
  // leaves them out too, so the model has never seen them).
  std::vector<std::string> excluded_static = {"benchmark", "gym01", "sit01"};
  int training_frames_per_clip = 4;   // CMU frames (k + 0.5)·n / count: the database's frames
  int held_out_frames_per_clip = 2;   // CMU frames k·n / (count + 1), k ≥ 1, never a training frame
  int training_blends = 8;            // encoding-space in-betweens of two training morphs (t = 0.5)
  int held_out_blends = 4;            // in-betweens of other pairs at t = 0.3
  unsigned seed = 3;                  // which pairs are blended
};

// One example pose of the range of motion.
struct RangeOfMotionPose {
  std::string name;       // "fight01", "cmu02_02-f112", "blend:fight01+run01@0.50", "rest"
  Pose pose;              // for the character's skeleton (for blends: per-bone slerp)
  bool held_out = false;
  int blend_a = -1, blend_b = -1;  // blends: indices of the two morphs, earlier in the list
  double t = 0;
};

// The poses (morphs come first, then blends of earlier entries). Throws InputError naming the
// file when a pose file cannot be read.
std::vector<RangeOfMotionPose> range_of_motion(const Skeleton& skeleton,
                                               const std::filesystem::path& makehuman_dir,
                                               const RangeOfMotionOptions& options = {});

// Bones the model can pose: the full model has joint-angle labels for them ("pose:<bone>:r*"),
// plus the root (global orientation and travel). #B flags. A pose morph cannot move the others
// (fingers, toes, face, ...), so a rig must not learn weights for them: their rotations are
// set to identity (they follow their parent) in training and in animation.
std::vector<char> driven_bones(const BodyModel& model, const Skeleton& skeleton);
// `pose` with every undriven bone's rotation set to identity (root translation kept).
Pose restrict_pose(const Pose& pose, const std::vector<char>& driven);
// Dense weights W (#V by #B) with each undriven bone's weight moved to its nearest driven
// ancestor (same deformation for restricted poses, identifiable fits).
Eigen::MatrixXd merge_undriven_weights(const Eigen::MatrixXd& W, const Skeleton& skeleton,
                                       const std::vector<char>& driven);
// Bone maps relative to the root bone's: G⁻¹ M_b with G = M_root (the first root). Skinning in
// this frame and applying G afterwards makes MWE and Animation Space (not invariant to a
// global rigid motion, unlike SSD) independent of where the character walks.
BoneTransforms relative_to_root(const BoneTransforms& M, const Skeleton& skeleton, Eigen::Affine3d* root = nullptr);

// Skinning weights W (#V by #B, rows summing to one) smoothed over the mesh F (#F by 3):
// `steps` times W ← ½ W + ½ (mean of the 1-ring neighbours' rows). Rows still sum to one.
// MakeHuman's weights change abruptly across a few short edges in the armpit and crotch, which
// linear blend skinning stretches most (tools/pipeline/character.h, CharacterOptions).
Eigen::MatrixXd smooth_skin_weights(const Eigen::MatrixXd& W, const Eigen::MatrixX3i& F, int steps);

// An MWE rig fitted in delta space over `base` (same vertices and influences) keeps the base
// and smooths its refinement D = W_mwe − W_base over the mesh: `steps` times D_v ← ½ D_v +
// ½ (mean of the 1-ring's D for the same bone; 0 where a neighbour lacks the bone). MWE's
// per-vertex fits are independent, so D carries vertex-to-vertex noise that unseen poses
// amplify on short edges (fingers, toes, eyelids: stretched many times their rest length on
// CMU clips).
// `keep` (#V in [0, 1], optional) then scales each vertex's refinement (0 = the base alone).
// Throws InputError when the rigs do not match.
void smooth_mwe_refinement(SkinningRig& mwe, const SkinningRig& base, const Eigen::MatrixX3i& F, int steps,
                           const Eigen::VectorXd* keep = nullptr);

// Per vertex (#V in [0, 1]): 1 − the weight (W #V by #B, smoothed `steps` times) of the hands,
// feet and head (the bones `wrist.*`, `foot.*`, `head` and their descendants). These parts are
// small and stiff; pose morphs (model/pose_edit.h) leave them as decoding noise around the
// skinned tip constraints, which MWE fits and unseen poses amplify (toes, fingers: edges
// stretched many times their rest length on CMU clips; docs/results.md#characters-and-animation).
Eigen::VectorXd mwe_refinement_mask(const Eigen::MatrixXd& W, const Skeleton& skeleton, const Eigen::MatrixX3i& F,
                                    int steps);
// The same with the masked bones named by prefixes (each bone whose name or an ancestor's name
// starts with one of them).
Eigen::VectorXd mwe_refinement_mask(const Eigen::MatrixXd& W, const Skeleton& skeleton, const Eigen::MatrixX3i& F,
                                    int steps, const std::vector<std::string>& bone_prefixes);

struct CharacterOptions {
  RangeOfMotionOptions range_of_motion;
  // The model's pose morph with its defaults (model/pose_edit.h: torso anchored where skinning
  // places it, volume kept within 1 % of the body's): closer to true posed scans than the paper's
  // tips-only morph (docs/results.md#pose-morphs).
  PoseMorphOptions pose_morph;
  // Fold repair of every pose morph and in-between before any rig sees it (core/fold_repair.h,
  // repair_folds_against_normals): a triangle is flipped when its normal points against its
  // rest normal turned by the bone that mostly carries it (the flip test of `animate`,
  // tools/pipeline/deformation_check.h); each flipped area is re-solved from the rest body's
  // local shape. Without it the morphs fold the armpit and groin and the rigs learn the folds.
  bool repair_folds = true;
  FoldRepairOptions fold_repair = [] {
    FoldRepairOptions f;
    f.passes = 8;   // as generate (model/morph.h)
    f.max_displacement = 40;  // mm
    f.max_edge_ratio = 3;     // as animate
    return f;
  }();
  // Local shape of the repair: the body skinned into the pose (true) or the rest body (false).
  bool fold_reference_skinned = true;
  // In-betweens decoded with the pose morph's constraints (limb tips, torso) for the slerped pose
  // (model/pose_edit.h blend_pose_morphs); false = the interpolated encoding decoded freely and
  // placed rigidly, whose hands and feet end far from where the skeleton puts them (the demo
  // character's held-out maximum of every rig was such an in-between: docs/results.md).
  bool constrain_blends = true;
  int max_influences = 4;           // slots per vertex (the template weights' largest ones)
  // The SSD rig Animation Space and MWE build on (their prior / delta-space base): the template's
  // weights (smooth, painted by MakeHuman's artists) rather than SSD weights fitted to the pose
  // morphs, whose vertex-to-vertex noise stretches edges in unseen poses (max edge ratio 23 vs 4
  // on CMU 12_03 for one character).
  bool base_on_template_weights = true;
  // Smoothing steps of the template weights (smooth_skin_weights) for the SSD rig AS and MWE
  // build on and the glb exports. On CMU 12_03 / 02_02 with the default body: 0 steps max edge
  // ratio 4.8 / 4.9, 5 → 3.1 / 3.4, 10 → 2.7 / 3.2, 20 → 3.1 / 3.3, 40 → 2.9 / 3.7.
  int weight_smoothing_steps = 10;
  // Smoothing steps of MWE's refinement over that SSD (smooth_mwe_refinement).
  int mwe_smoothing_steps = 20;
  // The refinement is faded out on the hands, feet and head (mwe_refinement_mask) over this
  // many smoothing steps of the mask; < 0 = no mask.
  int mwe_mask_steps = 10;
  // Bones whose vertices the mask fades the refinement on (name prefixes, with descendants), read
  // on the template weights before undriven bones are merged.
  std::vector<std::string> mwe_mask_bones = {"wrist", "foot", "head"};
  LbsFitOptions lbs;
  AnimationSpaceFitOptions animation_space;
  // MWE ridge s = 2e-5 (relative), 10⁴ × the horse-tuned default: the range of motion is small
  // (≈ 32 poses) and animation clips go beyond it; on CMU 12_03 this about halves the largest
  // edge stretch of a character while the held-out error stays below SSD's (docs/benchmarks.md#figures-behind-code-comments).
  MweFitOptions mwe = [] {
    MweFitOptions m;
    m.ridge_scale = 2e-5;
    return m;
  }();
  int threads = 0;                  // pose morphs in parallel (one decoder each); 0 = all cores
};

// Throws InputError naming the option (`--mwe-s`, …) when a setting is out of range (negative or
// NaN ridge, components, smoothing steps or threads; non-positive fold-repair distance). Called
// before any work: `character --mwe-s -1` was refused only by the MWE fit, after all the pose morphs.
void validate_character_options(const CharacterOptions& options);

// The example meshes of a character.
struct CharacterExamples {
  Eigen::MatrixX3d rest;                  // #V by 3, mm (the body, standard pose)
  Eigen::MatrixX3i F;                     // #F by 3
  Skeleton skeleton;                      // template skeleton placed in the body
  SkinWeights template_weights;           // #V by #B, the model's (MakeHuman's) weights
  std::vector<char> driven;               // #B, see driven_bones
  std::vector<RangeOfMotionPose> poses;   // #P (the rest pose first)
  // Both in the root's frame (relative_to_root): the root bone's map is the identity.
  std::vector<BoneTransforms> transforms; // #P forward kinematics of each (restricted) pose
  std::vector<Eigen::MatrixX3d> meshes;   // #P pose morphs, #V by 3, mm
  // Flipped triangles of each pose (#P) before and after the fold repair (the flip test of
  // `animate`: normal against the rest normal turned by the triangle's dominant bone of the
  // smoothed template weights). Equal when the repair is off.
  std::vector<int> flipped_before, flipped_after;
  double seconds = 0;
};

// Pose-morphs the body V (#V by 3, mm, the model's topology, standard pose) into the range of
// motion. Throws InputError when the model has no rig or V is not of the model's topology.
CharacterExamples make_character_examples(const BodyModel& model, const Eigen::MatrixX3d& V,
                                          const std::filesystem::path& makehuman_dir,
                                          const CharacterOptions& options = {},
                                          const ProgressCallback& progress = {});

struct CharacterRigs {
  SkinningRig template_lbs;   // the model's weights as they are (largest max_influences kept)
  SkinningRig smooth_lbs;     // the same smoothed (weight_smoothing_steps): AS and MWE's base
  SkinningRig lbs, as, mwe;   // fitted to the training examples
  LbsFitSummary lbs_summary;
  AnimationSpaceFitSummary as_summary;
  MweFitSummary mwe_summary;
};

CharacterRigs fit_character_rigs(const CharacterExamples& ex, const CharacterOptions& options = {},
                                 const ProgressCallback& progress = {});

// Errors of one rig on one split: vertex error ‖x_i − y_i‖ against the pose morph (mm), over all
// vertices of all poses of the split (docs/evaluation.md#character-rig-errors).
struct RigErrorRow {
  std::string method;   // "template_lbs", "smooth_lbs", "lbs", "as", "mwe"
  std::string split;    // "train" or "held_out"
  int poses = 0;
  double mean_mm = 0, max_mm = 0, rms_mm = 0, p95_mm = 0;
};

std::vector<RigErrorRow> evaluate_character_rigs(const CharacterExamples& ex, const CharacterRigs& rigs);
// Per-vertex mean error (mm) of `rig` over the held-out poses: #V.
Eigen::VectorXd held_out_vertex_error(const CharacterExamples& ex, const SkinningRig& rig);

// Per pose (#P rows) and rig (columns template_lbs, smooth_lbs, lbs, as, mwe): mean and max vertex
// error (mm) against the pose's morph.
struct PoseErrors {
  Eigen::MatrixXd mean_mm, max_mm;   // #P by 5
  Eigen::MatrixXi max_vertex;        // #P by 5: the vertex of the max
};
PoseErrors per_pose_errors(const CharacterExamples& ex, const CharacterRigs& rigs);

// fit.csv text: method,split,poses,mean_mm,max_mm,rms_mm,p95_mm
std::string rig_errors_csv(const std::vector<RigErrorRow>& rows);

}  // namespace bodymodel
