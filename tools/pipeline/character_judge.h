// Judging a character's rigs against real poses that are not the model's own (issue 26): the
// rigs of `bodymodel character` are trained on the model's pose morphs and, by default, judged
// against held-out pose morphs of the same model, whose heads and feet the skeleton cannot
// follow either — a comparison dominated by the reference. Here the reference is a real person:
//  1. the character's body is a registration of that person (template topology) in a near-rest
//     pose, UNPOSED into the model's standard pose (unpose_body: a skeleton pose fitted by least
//     squares, then linear blend skinning inverted per vertex, a few rounds so the skeleton is
//     placed in the unposed body);
//  2. the rigs are built from that body as usual (pose morphs of the model);
//  3. every rig is posed onto each of the person's other registered poses by the same fit
//     (fit_rig_pose: joint rotations of the driven bones and a rigid placement, Levenberg–
//     Marquardt on all vertices from the registration's own pose) and the residual vertex error
//     is the rig's error on that pose (docs/evaluation.md#character-rigs-on-real-poses).
// The registrations' own error (their distance to the scans) is a floor shared by every rig.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <limits>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/progress.h"
#include "core/skeleton.h"
#include "model/body_model.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

struct RigPoseFitOptions {
  int max_iterations = 60;          // Levenberg–Marquardt iterations
  double function_tolerance = 1e-6; // relative drop of the squared error below which it stops
  // The fit's residuals are every vertex_stride-th vertex (the reported errors are on all of
  // them): ≈ 40 000 residuals × ≈ 100 unknowns per Jacobian otherwise. 1 = every vertex.
  int vertex_stride = 3;
  // Prior pulling each fitted bone's rotation towards the start's: residual w·δ (δ the rotation
  // increment in radians, w in mm per radian). 0 (the judge) = none.
  double prior_mm_per_rad = 0;
};

// A rig posed onto a target mesh: the rig is evaluated with `transforms` (forward kinematics of
// `pose`, whose root rotation and translation are zero, so in the root's frame as the character's
// rigs are trained) and its output moved by `placement`.
struct RigPoseFit {
  Pose pose;                  // #B: the driven bones' rotations, the others and the root identity
  Eigen::Affine3d placement = Eigen::Affine3d::Identity();
  BoneTransforms transforms;  // #B, what the rig is evaluated with
  Eigen::MatrixX3d posed;     // #V by 3: placement applied to the rig's output
  int iterations = 0;
  double rms_mm = 0;          // root mean square vertex distance to the target
};

// Fits the rotations of the driven bones (#B flags, tools/pipeline/character.h driven_bones;
// roots excepted) and a rigid placement so that the rig's output matches `target` (#V by 3, the
// rig's topology, mm) in least squares over all vertices, starting from `start` (its undriven
// bones and root rotation are ignored; the placement starts at the best rigid fit of the rig's
// output in `start`). The same fit for every rig: no rig-specific terms. Levenberg–Marquardt with
// forward-difference derivatives, so any rig type works. Throws InputError when sizes disagree.
RigPoseFit fit_rig_pose(const SkinningRig& rig, const Skeleton& skeleton, const std::vector<char>& driven,
                        const Eigen::MatrixX3d& target, const Pose& start, const RigPoseFitOptions& options = {});

// Per vertex, the inverse of linear blend skinning: the rest point x with Σ_b w_vb M_b x = y_v
// (W #V by #B dense weights, M #B affine maps, Y #V by 3). Exact where the blended map is
// invertible (it is for rigid M unless bones nearly cancel); there the dominant bone's map is
// inverted instead.
Eigen::MatrixX3d inverse_linear_blend_skinning(const Eigen::MatrixX3d& Y, const Eigen::MatrixXd& W,
                                               const BoneTransforms& M);

struct UnposeOptions {
  int rounds = 4;             // inversions, each with the skeleton placed in the last body
  // false: the body is unposed with the given pose as it is (all bones, e.g. the pose
  // `register-mesh` fitted with its shape fit and priors; only a rigid placement is fitted);
  // true: the driven bones' rotations are fitted to the body in every round (fit_rig_pose,
  // starting from the given pose, with fit.prior_mm_per_rad pulling towards it).
  bool fit_pose = false;
  int max_influences = 8;     // of the template weights, for the fit and the inversion
  RigPoseFitOptions fit;
};
// The options `character --unpose` uses: the pose fitted to the body with a prior towards the
// registration's own pose. The registration's pose alone left the posed template far from a
// SCAPE registration (arms forward, fingers scattered after the inversion); the
// fit without a prior absorbed the template's different shape into rotations (knees out, a step
// at the waist); with 2000 mm/rad the SCAPE rest body kept neither (docs/skinning.md).
UnposeOptions unpose_with_prior();

struct UnposeResult {
  Eigen::MatrixX3d rest;   // #V by 3, mm, standard pose (the skeleton's rest)
  Pose pose;               // the fitted pose of the last round (root: identity, see RigPoseFit)
  Eigen::Affine3d placement = Eigen::Affine3d::Identity();
  // Per round: RMS distance (mm) of the posed template (fitted or placed) to the body before the
  // inversion — how far linear blend skinning of the round's rest body is from the posed body.
  std::vector<double> rms_mm;
};

// Unposes a body of the model's topology (#V by 3, mm, +y up) given in `pose`: the model's
// template body is posed with the template weights (with options.fit_pose, the pose is fitted
// first: fit_rig_pose from `pose`), placed rigidly onto the body, the body is carried back by
// inverse_linear_blend_skinning, and the skeleton is placed anew in the result
// (model.rig.skeleton_for) for the next round. Near the joints the result is only
// as good as linear blend skinning is for that pose: use the person's most rest-like pose.
// Throws InputError when the model has no rig or the body is not of its topology.
UnposeResult unpose_body(const BodyModel& model, const Eigen::MatrixX3d& posed, const Pose& pose,
                         const UnposeOptions& options = {}, const ProgressCallback& progress = {});

// One real pose to judge the rigs on.
struct JudgePose {
  std::string name;
  Eigen::MatrixX3d target;    // #V by 3, mm, the character's topology, +y up
  Pose start;                 // the fit's start (e.g. the registration's pose file), #B
  double registration_mm = std::numeric_limits<double>::quiet_NaN();  // its distance to the scan
  // The scan the pose was registered to (mm, +y up, any topology), optional: each posed rig is
  // then also compared with it by the two-sided surface distance of register-mesh
  // (registration/mesh_scan.h), which — unlike the vertex error against the registration — does
  // not reward keeping the registration's tangential layout of the vertices.
  Mesh scan;
};

// Error of one rig on one judged pose (pose "all": every vertex of every pose pooled).
struct JudgeRow {
  std::string method, pose;
  int poses = 1;
  double mean_mm = 0, max_mm = 0, rms_mm = 0, p95_mm = 0;
  int iterations = 0;   // of the pose fit (sum over poses for "all")
  // With a scan: two-sided surface distance of the posed rig to it (mean of the two directions'
  // means, mm; "all": the mean over poses); NaN without.
  double scan_two_sided_mm = std::numeric_limits<double>::quiet_NaN();
};

struct NamedRig {
  std::string name;
  const SkinningRig* rig = nullptr;
};

// Every rig fitted onto every pose (fit_rig_pose), rows per (rig, pose) then one "all" row per
// rig, in the order of `rigs`; the faces F (#F by 3) are the rigs' mesh (for the scan distance). All rigs must share the skeleton's rest (the character's body).
std::vector<JudgeRow> judge_rigs_on_poses(const std::vector<NamedRig>& rigs, const Skeleton& skeleton,
                                          const std::vector<char>& driven, const Eigen::MatrixX3i& F,
                                          const std::vector<JudgePose>& poses,
                                          const RigPoseFitOptions& options = {},
                                          const ProgressCallback& progress = {});

// judge.csv text: pose,method,poses,mean_mm,max_mm,rms_mm,p95_mm,fit_iterations,registration_mm,
// scan_two_sided_mm (the last two empty when unknown)
std::string judge_csv(const std::vector<JudgeRow>& rows, const std::vector<JudgePose>& poses);

}  // namespace bodymodel
