// Skeleton-based pose estimation (Hasler et al. 2009 §2.2): the template, with its skeleton and
// linear-blend-skinning weights, is posed onto a scan by non-linear least squares (Ceres, robust
// loss). Unknowns: a global scale (about the root joint), the global rigid motion (root
// rotation + translation) and one rotation per body segment (default_pose_parameters: spine,
// neck, head, shoulders, upper/lower arms and legs with their twist bones, wrists, feet;
// fingers, toes, face, spine05 and the pelvis bones stay at rest). ICP loop: closest-point correspondences template→scan with the paper's
// rejection (normals > 30°, distance > 50 mm), plus landmarks for global stability; solve;
// repeat until the pose stops changing.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/progress.h"
#include "core/skeleton.h"
#include "registration/landmarks.h"

namespace bodymodel {

// One fitted rotation shared by a group of bones (each bone of the group gets the same
// rotation relative to its parent), or, with `twist`, an angle about each bone's own rest axis.
struct PoseParameter {
  std::vector<std::string> bones;
  bool twist = false;
  double prior = 1.0;  // multiplies PoseFitOptions::pose_prior for each bone of the group
  // Fitted only in the hand stage (after the body has converged, with the rest of the pose held
  // fixed and hand-local correspondences); kept at rest before. Not anchored.
  bool late = false;
  // A finger's curl: one angle about each bone's curl axis (bone direction × palm normal, the
  // palm normal from the rest bones of the hand the bone belongs to). Shared over the phalanges
  // of a group, so the finger closes as a whole.
  bool curl = false;
  // Pulled towards the landmark-only solve's value (PoseFitOptions::anchor_prior) in the ICP.
  bool anchored = true;
  // A thumb's tuck: one angle per bone about the palm normal of its hand (the `curl` palm
  // normal, signed so that a positive angle sweeps the thumb tip across the palm, towards the
  // little finger). Never fitted: set by the hand stage's start
  // (PoseFitOptions::hand_start_tucks_deg) and held there. Needs `late`.
  bool tuck = false;
};

struct PoseFitOptions {
  // Names of the bones whose rotation is fitted, each a free ball joint (besides the root,
  // always free). Takes precedence over `parameters`.
  std::vector<std::string> free_bones;
  // Fitted rotations; empty (and free_bones empty): default_pose_parameters(), keeping the
  // bones that exist in the skeleton. Named bones must exist.
  std::vector<PoseParameter> parameters;
  bool fit_scale = true;
  // Starting global scale; ≤ 0: from the landmarks' similarity transform (or the bounding boxes).
  double initial_scale = 0.0;
  // §2.2 rejection thresholds. The distance threshold starts at initial_max_distance and halves
  // every ICP iteration down to max_distance (a coarse start is too far for 50 mm).
  double max_distance = 50.0;           // mm
  double initial_max_distance = 200.0;  // mm
  double max_normal_angle_deg = 30.0;
  bool unsigned_normals = false;        // for scans with estimated (unoriented) normals
  int sample_vertices = 1500;           // template vertices used as ICP samples (evenly strided)
  double robust_scale = 10.0;           // Huber loss scale, mm
  // Each sample gives a point-to-plane residual (scan normal) plus this much point-to-point.
  double point_to_point_weight = 0.3;
  // Landmarks are used when at least half of their vertex's weight is on bones at most this
  // many fixed bones below a fitted one (toes below the foot, the jaw below the head).
  int landmark_rigid_depth = 3;
  double landmark_weight = 3.0;         // residual weight of a landmark relative to a sample
  // Prior towards the rest pose on free joints: residual = sqrt(prior)·angle (rad) per joint
  // (cost in mm²-equivalents, against ~sample_vertices data residuals). MakeHuman's skeleton is
  // redundant (two bones per limb segment, clavicle + shoulder, five spine bones): without it
  // consecutive bones counter-rotate by tens of degrees at no data cost. Strong enough to pick
  // the smallest split, weak against real data (a 10 mm landmark miss outweighs 50° of prior).
  double pose_prior = 1e4;
  // The prior starts this many times stronger and halves every ICP iteration down to
  // pose_prior (coarse to fine: joints move first where the data insists most). 100 gave
  // 21.0 vs 22.1 mm posed-template error on six scans, joint error unchanged: off by default.
  double initial_prior_factor = 1.0;
  // Symmetric ICP: scan→template pairs (every scan_samples-th scan point to its closest
  // template sample, same rejection) with this total weight relative to the template→scan
  // pairs. 0: template→scan only (§2.2).
  // 1 (with the two options below): on 15 scans of the synthetic database, pose-only joint
  // error median 6.8 → 6.5°, posed-template correspondence 15.1 → 14.7 mm, p95 41 → 39 mm.
  double symmetric_weight = 1.0;
  int scan_samples = 3000;
  // From the second ICP iteration on, the worst trim_fraction of each direction's pairs is
  // dropped (trimmed ICP). 0: off.
  double trim_fraction = 0.0;
  // Prior towards the pose of the landmark-only solve (same form as pose_prior, centred there
  // instead of at rest): keeps joints the surface barely constrains (twists) where the
  // landmarks put them. Without it the ICP bends joints to absorb the template's wrong shape
  // (a thin template in a heavy subject): on a known pose, joint error median 4.0° after the
  // landmark solve became 11.0° after the ICP; with 1e5 it ends at 5.8°. 0: off.
  double anchor_prior = 1e5;
  int max_icp_iterations = 25;
  // Solves with the landmarks alone (and the prior) before the ICP iterations (needs ≥ 3).
  int landmark_iterations = 1;
  // The landmark-only solves use a pose prior this many times stronger, relaxed geometrically to
  // 1× over landmark_iterations solves (with one solve: this factor). Two dozen landmarks leave
  // limb twists and the split between consecutive bones undetermined; a weak prior lets the
  // solver wander into twisted poses (a thigh twisted 60° and the knee bent sideways to
  // compensate) that the ICP, on near-cylindrical limbs, cannot undo.
  // 100: joint error median 13.2 → 4.0° after the landmark solve on a known pose (with the
  // anchor below, 15 database scans: 10.8 → 6.8°). Relaxing it over several landmark solves
  // undid the gain (9.2°).
  double landmark_prior_factor = 100.0;
  int solver_iterations = 8;            // Levenberg–Marquardt iterations per ICP step
  // Stop when no joint angle changes by more than this (degrees) and the translation by less
  // than convergence_mm between ICP iterations.
  double convergence_deg = 0.1;
  double convergence_mm = 0.2;
  int threads = 1;
  // Hand stage (parameters marked `late`: the finger curls): after the body ICP, at most
  // hand_iterations solves with the body fixed. Samples: every template vertex weighted on a
  // late bone (up to hand_sample_vertices); pairs both ways with the scan points whose closest
  // posed template vertex is on the hand (hand-local, so a straight template finger is not
  // pulled to the thigh it touches). The rejection distance halves from
  // hand_initial_max_distance to hand_max_distance (a fist's fingertips are ~100 mm from an
  // open hand's).
  int hand_iterations = 10;
  int hand_sample_vertices = 1000;
  // Refit the wrists in the hand stage (the body stage places a hand by few, mostly forearm,
  // correspondences). 15 database scans, pose only, before the shape fit, hand stage on: distal
  // phalanx error median 33.1 → 15.6°, correspondence median 19.6 → 14.5 mm.
  bool hand_wrists = true;
  // With hand_wrists, the hand stage also refits the forearms' twist (the twist parameter right
  // above each wrist): a hand turned palm up turns the forearm (pronation), not the wrist. The
  // body stage, anchored to the landmark-only pose, leaves the forearms untwisted (registered
  // lowerarm02 twist within ±4° over 100 database scans, truth up to ±56°) and the refitted
  // wrists took the twist instead (±50°, truth mostly within ±20°).
  bool hand_forearm_twist = true;
  // In the hand stage (with hand_wrists), a prior on each refitted wrist's twist about its bone (per rad², same
  // units as pose_prior, on top of it): the twist goes to the forearm. 0: none.
  // 100 database scans, pose stage, with the forearm twist and the twist starts: 0 / 3e4 / 1e5
  // give flipped triangles 2 912 / 1 616 / 1 680, joint median 5.02 / 5.05 / 5.08°.
  double wrist_twist_prior = 3e4;
  // Range of a finger's curl per phalanx (degrees; positive closes the finger towards the palm,
  // the side of the thumb). Without it fists were fitted with fingers bent backwards (a fist's
  // inside is not scanned). max ≤ min: unbounded.
  double curl_min_deg = -15.0;
  double curl_max_deg = 100.0;
  double hand_initial_max_distance = 80.0;  // mm
  double hand_max_distance = 20.0;          // mm
  // The curls of the fingers of one hand (late `curl` groups under the same wrist) are pulled
  // towards their mean with this weight (per finger, same units as pose_prior): fingers the
  // scan shows poorly close with the others. 0: independent.
  double finger_coupling = 3e3;
  // Before the per-finger solves, a hand stage with the curls of each hand tied (one grasp per
  // hand), from which the per-finger solves start and to which the acceptance reverts.
  bool tied_hand_phase = true;
  // After the hand stage each hand parameter (finger, thumb, wrist with hand_wrists) in turn
  // goes back to its start if that lowers the hand's two-sided distance to the scan, each
  // distance capped at this (mm); ≤ 0: off.
  double hand_accept_cap = 30.0;
  // Starts of the hand stage: every finger's curl per phalanx (degrees) before the tied phase,
  // the wrists where the body stage put them. Each hand keeps the result of the start that
  // ends closest to the scan (two-sided distance of the hand, capped at hand_accept_cap).
  // Empty: one start from the body stage's (open) fingers. A start with the same curl as an
  // earlier one is that start's variant (differing in the thumbs' tuck or the forearms' twist):
  // it is run and compared only for a hand that keeps the earlier start, against it.
  std::vector<double> hand_start_curls_deg = {0.0, 80.0, 80.0, 0.0, 0.0};
  // Per start, the thumbs' tuck per bone (degrees; PoseParameter::tuck; missing entries: 0).
  // The third start is the fist with the thumb tucked across the palm (40° at each of its two
  // outer bones; fight03's fists: 18° and 65°), inside the fist, where the scanner does not see
  // it: a straight thumb sticks out of the fist, far from every scan point. 15 database scans,
  // full register: flipped triangles 390 -> 285 (s008_p3: 164 -> 59, the right thumb), every
  // other scan unchanged.
  std::vector<double> hand_start_tucks_deg = {0.0, 0.0, 40.0, 0.0, 0.0};
  // Per start, the forearms' twist added to the body stage's (degrees; with
  // hand_forearm_twist, else such a start is skipped; missing entries: 0). The fourth and
  // fifth starts are the open hand's variants with the forearm turned ±90°: on a
  // near-cylindrical forearm the body stage cannot
  // see the twist, and from the untwisted forearm the hand stage ended palm out in a local
  // minimum (s017_p4, fight02: the right forearm 90° off, 2 605 flipped triangles after the pose
  // stage; 28 with these starts). 100 database scans, pose stage, forearm twist refitted:
  // flipped triangles 4 944 -> 2 912 (hands 2 352), pose stage 543 -> 832 s (wall, 2 jobs).
  std::vector<double> hand_start_twists_deg = {0.0, 0.0, 0.0, 90.0, -90.0};
  // A start after the first is kept only if its distance is below (1 − margin) times the first
  // start's: leaving the open hand needs clear evidence. On the whole database (100 scans) with
  // 0.1, three open hands whose arm the body stage had misplaced (the hand's fit 10–12 mm off
  // either way) were taken for fists 12–16 % closer, e.g. s011_p1: 1 172 flipped triangles
  // instead of 11 after the full registration; fight03's fist, whose inside is not scanned, wins by 31 % (s008_p3).
  double hand_start_margin = 0.2;
  // The starts are compared after aligning each hand to the scan by a translation, found in
  // this many alternating closest-point steps (0: as posed).
  int hand_start_align_steps = 5;
  // With several starts, each hand's chosen result is last compared, the same way (margin 0),
  // with the body stage's hand (fingers at rest, wrist and forearm twist as the body stage left
  // them): the hand stage's result is kept only if it is closer to the scan. The hand stage's
  // own correspondences can lead it away from a hand the body stage had right: s019_p0 (the
  // standard pose, fingers straight), pose stage: the left forearm twisted 14.6°, wrist bent,
  // little finger curled 80°; hand two-sided distance 7.6 mm against 5.6 mm before the stage.
  bool hand_compare_body_stage = true;
};

struct PoseFitSummary {
  int icp_iterations = 0;
  double seconds = 0.0;
  double rms = 0.0;             // RMS sample→scan distance of accepted pairs, last iteration (mm)
  int matched_samples = 0;      // accepted pairs, last iteration
  double landmark_rms = 0.0;    // mm
  bool converged = false;
  int landmarks_used = 0;       // landmarks on the root or free bones (the others are ignored)
  // Mean of (scan points → posed template vertices) and (template vertices → scan points),
  // each distance capped at max_distance (mm): compares fits with different options.
  double two_sided_mm = 0.0;
  int hand_iterations = 0;      // solves of the hand stage
  double hand_rms = 0.0;        // RMS distance of the hand stage's accepted pairs, last solve (mm)
  // Per-finger acceptance (PoseFitOptions::hand_accept_cap): the hand's two-sided distance
  // with every hand parameter fitted, after the reverts, and how many went back (mm, count).
  double hand_accept_before = 0.0;
  double hand_accept_after = 0.0;
  int hand_reverted = 0;
  // Per hand (wrist order in the skeleton), the index of the start kept
  // (PoseFitOptions::hand_start_curls_deg), or the number of starts for the body stage's hand
  // (PoseFitOptions::hand_compare_body_stage); empty with a single start.
  std::vector<int> hand_start_choice;
  // Every comparison of the start choice: hand, incumbent start, challenger start and their
  // two-sided distances on the compared scan points (mm, after the translation alignment);
  // challenger = the number of starts: the body stage's hand.
  struct HandStartComparison {
    int hand = 0, incumbent = 0, challenger = 0;
    double incumbent_mm = 0, challenger_mm = 0;
  };
  std::vector<HandStartComparison> hand_start_comparisons;
};

struct PoseFitResult {
  double scale = 1.0;           // global scale of template and skeleton about the root head
  Pose pose;                    // per-bone rotations (fitted for free bones, identity else)
  Eigen::MatrixX3d V;           // #V by 3 posed (and scaled) template
  std::vector<int> free_bones;  // indices of the fitted bones (root first)
};

// Pose parameterisations of the MakeHuman default skeleton:
// 'segment': one rotation per body segment (tied spine and neck groups, clavicle + shoulder01,
// twist-only second bones of each limb segment) plus finger grasp groups;
const std::vector<PoseParameter>& segment_pose_parameters();
// 'bone': every spine, neck, arm and leg bone of the segment set a free ball joint (the
// pose prior picks the smallest split), finger grasp groups as in 'segment'.
const std::vector<PoseParameter>& bone_pose_parameters();
// 'segment' with the hands in a hand stage (PoseParameter::late) instead of the grasp groups:
// one curl per finger (PoseParameter::curl), the thumbs ball joints at their base. On the
// synthetic fists of MakeHuman's fight03 the finger vertices come from 52 to 7.8 mm (test). On
// the 15 database scans (register --shard 1/7, with the shape fit) it lowers the distal phalanx
// error median 27.0 → 14.9°, correspondence median 9.40 → 8.38 mm, p95 25.9 → 21.2 mm. With the
// fist start (PoseFitOptions::hand_start_curls_deg) one scan of fight03 fists (s008_p3), whose
// right wrist the open start alone refitted 58° off, flips 157 triangles instead of 744; the 15
// scans' pose stage flips 345 (hands 239) instead of 932 (826), and the full registration 390
// (hands 305) instead of 1087 (946). With the thumbs' tuck (a fist's variant start, tuck
// parameters on finger1-2/1-3, never fitted) the full registration flips 285 (hands 200). With
// the forearms' twist refitted in the hand stage, the wrists' twist restrained and the open
// hand's two twisted variant starts, all 100 database scans (full registration) flip 1 992
// triangles (hands 1 319) instead of 5 357 (4 687). register --hand-stage on selects it.
const std::vector<PoseParameter>& hand_stage_pose_parameters();
// `parameters` with the finger grasp groups (bones named "finger…") replaced by the hand stage's
// per-finger curls and thumbs (as in hand_stage_pose_parameters()): e.g. 'bone' with a hand
// stage. The other groups are kept as they are.
std::vector<PoseParameter> with_hand_stage(const std::vector<PoseParameter>& parameters);
// The default parameters: one of the two above (the better on the synthetic database).
const std::vector<PoseParameter>& default_pose_parameters();
// All bones named by default_pose_parameters().
const std::vector<std::string>& default_free_bones();

// Scales template and skeleton by `scale` about the root head, then poses them with LBS.
//   V_rest #V by 3; returns #V by 3.
Eigen::MatrixX3d pose_template(const Eigen::MatrixX3d& V_rest, const Skeleton& skeleton,
                               const SkinWeights& weights, double scale, const Pose& pose);

// Fits pose and scale of the template (V_rest/F_rest with skeleton and weights) to `scan`
// (unit normals; see prepare_scan). Landmarks whose vertex is mostly bound to bones kept at
// rest (fingers, toes, face) are ignored here. With ≥ 3 landmarks a similarity transform from them
// initialises the global motion; otherwise centroids and bounding-box sizes do.
PoseFitResult fit_pose(const Mesh& template_rest, const Skeleton& skeleton,
                       const SkinWeights& weights, const PointCloud& scan,
                       const std::vector<Landmark>& landmarks, const PoseFitOptions& options = {},
                       PoseFitSummary* summary = nullptr, const ProgressCallback& progress = {});

}  // namespace bodymodel
