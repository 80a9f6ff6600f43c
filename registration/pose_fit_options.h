// Options and summary of the pose fitter (registration/pose_fit.h). Each option: its default and
// why; what the defaults were measured against is in docs/pose_fit.md#options.
#pragma once

#include <string>
#include <vector>

#include "registration/pose_parameters.h"

namespace bodymodel {

struct PoseFitOptions {
  // ---- unknowns (docs/pose_fit.md#parameters) ----
  // Names of the bones whose rotation is fitted, each a free ball joint (besides the root,
  // always free). Takes precedence over `parameters`. Default empty: use `parameters`.
  std::vector<std::string> free_bones;
  // Fitted rotations; empty (and free_bones empty): default_pose_parameters(), keeping the
  // bones that exist in the skeleton. Named bones must exist.
  std::vector<PoseParameter> parameters;
  bool fit_scale = true;        // subjects differ in size from the template
  // Starting global scale; ≤ 0: from the landmarks' similarity transform (or the bounding boxes).
  double initial_scale = 0.0;

  // ---- correspondences (docs/pose_fit.md#correspondences) ----
  // §2.2 rejection: pairs farther apart are dropped (mm). The threshold starts at
  // initial_max_distance and halves every ICP iteration down to max_distance, since a coarse
  // start is too far for 50 mm.
  double max_distance = 50.0;
  double initial_max_distance = 200.0;
  double max_normal_angle_deg = 30.0;   // §2.2: pairs whose normals differ more are dropped
  bool unsigned_normals = false;        // for scans with estimated (unoriented) normals
  int sample_vertices = 1500;           // template vertices used as ICP samples (evenly strided)
  double robust_scale = 10.0;           // Huber loss scale (mm): outliers pull linearly
  // Each sample gives a point-to-plane residual (scan normal) plus this much point-to-point,
  // which keeps samples from sliding along flat surface.
  double point_to_point_weight = 0.3;
  // Symmetric ICP: scan→template pairs (every scan_samples-th scan point to its closest template
  // sample) with this total weight relative to the template→scan pairs; they pull limbs towards
  // scan surface they do not face yet. 0: template→scan only (§2.2).
  double symmetric_weight = 1.0;
  int scan_samples = 3000;
  // From the second ICP iteration on, the worst trim_fraction of each direction's pairs is
  // dropped (trimmed ICP), in [0, 1). 0: off (it did not help, docs/pose_fit.md#options).
  double trim_fraction = 0.0;

  // ---- landmarks (docs/pose_fit.md#landmarks) ----
  // Landmarks are used when at least half of their vertex's weight is on bones at most this
  // many fixed bones below a fitted one: toes below the foot and the jaw below the head follow
  // their joint, a fingertip of held fingers does not.
  int landmark_rigid_depth = 3;
  double landmark_weight = 3.0;         // residual weight of a landmark relative to a sample
  // Solves with the landmarks alone (and the prior) before the ICP iterations (needs ≥ 3):
  // landmarks are reliable and far-reaching, a wrongly posed template's correspondences are not.
  int landmark_iterations = 1;

  // ---- priors (docs/pose_fit.md#priors) ----
  // Prior towards the rest pose: residual = sqrt(prior)·angle (rad) per bone, in mm²-equivalents
  // against ~sample_vertices data residuals. It picks the smallest split between MakeHuman's
  // redundant consecutive bones, and is weak against real data.
  double pose_prior = 1e4;
  // The prior starts this many times stronger and halves every ICP iteration down to pose_prior
  // (coarse to fine). 1: off (no gain measured).
  double initial_prior_factor = 1.0;
  // The landmark-only solves use a pose prior this many times stronger (relaxed geometrically to
  // 1× over landmark_iterations solves): two dozen landmarks leave limb twists undetermined and a
  // weak prior lets the solver wander into twisted poses the ICP cannot undo.
  double landmark_prior_factor = 100.0;
  // Prior towards the landmark-only solve's pose (same form as pose_prior): keeps joints the
  // surface barely constrains (twists) where the landmarks put them, instead of bending them to
  // absorb the template's wrong shape. 0: off.
  double anchor_prior = 1e5;

  // ---- solver (docs/pose_fit.md#stages) ----
  int max_icp_iterations = 25;
  int solver_iterations = 8;            // Levenberg–Marquardt iterations per ICP step
  // Converged when no joint angle changes by more than convergence_deg and the translation by
  // less than convergence_mm between ICP iterations (scale changes count as 1000 mm per unit).
  double convergence_deg = 0.1;
  double convergence_mm = 0.2;
  int threads = 1;                      // Ceres threads per solve; register parallelises over scans

  // ---- hand stage (docs/pose_fit.md#hand-stage) ----
  // After the body ICP, at most hand_iterations solves of the `late` parameters with the body
  // fixed, on hand-local pairs both ways (a straight template finger is not pulled to the thigh
  // it touches). Samples: up to hand_sample_vertices template vertices weighted on a late bone.
  int hand_iterations = 10;
  int hand_sample_vertices = 1000;
  // The rejection distance halves from hand_initial_max_distance to hand_max_distance (mm): a
  // fist's fingertips are ~100 mm from an open hand's.
  double hand_initial_max_distance = 80.0;
  double hand_max_distance = 20.0;
  // Refit the wrists in the hand stage: the body stage places a hand by few, mostly forearm,
  // correspondences.
  bool hand_wrists = true;
  // With hand_wrists, also refit each forearm's twist (the twist parameter above the wrist): a
  // hand turned palm up turns the forearm, which the body stage leaves untwisted.
  bool hand_forearm_twist = true;
  // With hand_wrists, a prior on each refitted wrist's twist about its bone (per rad², units of
  // pose_prior, on top of it), so that the twist goes to the forearm. 0: none.
  double wrist_twist_prior = 3e4;
  // Range of a finger's curl per phalanx (degrees; positive closes the finger towards the palm):
  // a fist's inside is not scanned, and unbounded fingers were fitted bent backwards.
  // max ≤ min: unbounded.
  double curl_min_deg = -15.0;
  double curl_max_deg = 100.0;
  // The curls of one hand's fingers are pulled towards their mean with this weight (per finger,
  // units of pose_prior): fingers the scan shows poorly close with the others. 0: independent.
  double finger_coupling = 3e3;
  // Before the per-finger solves, a phase with each hand's curls tied (one grasp per hand),
  // robust where single fingers are poorly scanned; the per-finger phase starts from it.
  bool tied_hand_phase = true;
  // Per-finger acceptance: after the hand stage each hand parameter in turn goes back to its
  // start if that lowers the hand's two-sided distance to the scan, each distance capped at this
  // (mm): scan holes and touching fingers give pairs that curl a straight finger. ≤ 0: off.
  double hand_accept_cap = 30.0;

  // ---- hand-stage starts (docs/pose_fit.md#hand-starts) ----
  // Every finger's curl per phalanx (degrees) at each start of the hand stage; each hand keeps
  // the result closest to the scan. A start with the same curl as an earlier one is that start's
  // variant (other thumb tuck or forearm twist), run only for a hand that keeps the earlier
  // start. Empty: one start from the body stage's (open) fingers. Default: open, fist, fist with
  // tucked thumbs, open with the forearm turned +90° and −90°.
  std::vector<double> hand_start_curls_deg = {0.0, 80.0, 80.0, 0.0, 0.0};
  // Per start, the thumbs' tuck per bone (degrees; PoseParameter::tuck; missing entries: 0): a
  // fist's thumb lies tucked inside it, where the scanner does not see it.
  std::vector<double> hand_start_tucks_deg = {0.0, 0.0, 40.0, 0.0, 0.0};
  // Per start, the forearms' twist added to the body stage's (degrees; needs
  // hand_forearm_twist, else such a start is skipped; missing entries: 0): on a near-cylindrical
  // forearm the body stage cannot see the twist, and the hand stage alone ends in a local minimum.
  std::vector<double> hand_start_twists_deg = {0.0, 0.0, 0.0, 90.0, -90.0};
  // A start after the first is kept only if its distance is below (1 − margin) times the first
  // start's, in [0, 1): leaving the open hand needs clear evidence.
  double hand_start_margin = 0.2;
  // The starts are compared after aligning each hand to the scan by a translation, found in this
  // many alternating closest-point steps (0: as posed): the stage cannot move the wrist.
  int hand_start_align_steps = 5;
  // With several starts, each hand's chosen result is last compared (margin 0) with the body
  // stage's hand and kept only if closer to the scan: the hand stage's own pairs can lead it away
  // from a hand the body stage had right.
  bool hand_compare_body_stage = true;

  // Throws InputError naming the first option out of its range (a negative distance, a fraction
  // outside [0, 1), a tuck parameter that is not late, …). fit_pose calls it first.
  void validate() const;
};

struct PoseFitSummary {
  int icp_iterations = 0;       // landmark-only solves and ICP iterations run
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

}  // namespace bodymodel
