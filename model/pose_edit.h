// Handle-based editing (Hasler et al. 2009 §5.3) and pose morphing (§5.4).
//
// EDITING: the user drags handle vertices. Each iteration decodes the current encoding with
// the handles as positional constraints (plus soft anchors far from the handles, so the body
// cannot satisfy a handle by merely translating), encodes the result and projects it back
// into the shape model's space (keeping the body's own detail the model cannot represent).
// After the iterations the body is a model-space shape; the final decode with the
// constraints puts the handles on their targets.
//
// POSE MORPHING: the joint rotations of the target pose are the full model's pose labels;
// they are all set at once (eq. 11, damped because there are many), the subject's own labels
// (height, weight, ...) are held, and the limb tips (hands, feet, head) are positional
// constraints at the places linear blend skinning of the body with the model's skeleton puts
// them.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/skeleton.h"
#include "encoding/relative_rotation_decoder.h"
#include "model/body_model.h"

namespace bodymodel {

struct VertexHandle {
  int vertex = 0;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // mm
};

struct EditOptions {
  int iterations = 10;              // the paper's "about 10"
  double anchor_distance_mm = 300;  // anchors are at least this far from every handle
  int anchors = 32;                 // farthest-point sampled anchor vertices
  double anchor_weight = 10;        // soft (handles use the decoder's 1e4)
};

struct EditSummary {
  int iterations = 0;
  double max_handle_error_mm = 0, mean_handle_error_mm = 0;
  std::vector<double> handle_error_per_iteration_mm;  // of the projected (unconstrained) shape
};

// V #V by 3 (mm, the model's topology). Throws InputError for a vertex index out of range or
// no handles.
Eigen::MatrixX3d edit_with_handles(const BodyModel& model, RelativeRotationDecoder& decoder,
                                   const Eigen::MatrixX3d& V, const std::vector<VertexHandle>& handles,
                                   const EditOptions& options = {}, EditSummary* summary = nullptr);

struct PoseMorphOptions {
  // Limb tips of the MakeHuman skeleton (the paper constrains hands, feet and head).
  std::vector<std::string> tip_bones = {"wrist.L", "wrist.R", "foot.L", "foot.R", "head"};
  // Also constrain the vertices around elbows and knees (lowerarm01, lowerleg01): beyond the
  // paper, lowers the error where the linear pose regression bends limbs too little.
  bool constrain_elbows_and_knees = true;
  int vertices_per_tip = 40;
  // Beyond the paper: also constrain, on every bone, up to vertices_per_bone of the vertices it
  // carries nearly alone (skinning weight ≥ 0.9), placed by skinning the body like the tips.
  bool constrain_every_bone = false;
  int vertices_per_bone = 10;   // most strongly bound vertices of each tip bone (and children)
  bool use_tip_constraints = true;
  // Labels held at their current value besides the joint angles being set (empty = every
  // non-pose label of the full model).
  std::vector<std::string> keep_labels;
  // eq. 11 with many constraints: damping relative to the largest squared singular value
  // (1e-3 beat 1e-2, 1e-4 and 1e-5 on held-out scans).
  double damping = 1e-3;
  // Example-based pose transfer before the linear correction: the coefficient change from
  // standard pose to posed of the training scans whose joint angles are nearest the target
  // (Gaussian-weighted over this many), added to the body, then eq. 11 sets the joint angles
  // the examples missed. 0 = the paper's linear regression only.
  int transfer_neighbours = 8;
  // Torso placement (beyond the paper). With only the limb tips constrained, the decoder places
  // the torso wherever the tips pull it: on held-out posed scans far from where skinning the
  // body puts it, which was most of the error against the true posed mesh
  // (docs/results.md#pose-morphs). When set, the pose-changed body is first decoded without
  // constraints, fitted rigidly onto the torso (root, spine*, pelvis* bones, weight ≥ 0.9) of
  // the skinned body, and torso_anchors of its torso vertices (spread evenly) are kept at those
  // places as soft positional constraints with the tips: the torso keeps the model's shape
  // and is placed by the skeleton's root and spine.
  bool anchor_torso = true;
  int torso_anchors = 64;
  // As the tips: the lowest error of 1e2–1e4 (docs/benchmarks.md#figures-behind-code-comments).
  double torso_anchor_weight = 1e4;
  // Volume (beyond the paper). A pose change from the model changes the body's volume, more
  // than the training scans' own skinned pose changes do, and a generated character's CMU-frame
  // morphs lost several per cent (docs/results.md#pose-morphs;
  // docs/benchmarks.md#figures-behind-code-comments). When set, a result whose volume is more than volume_tolerance off the
  // input body's is offset along its vertex normals by the uniform distance that brings it to
  // the edge of that band (restore_volume; ≈ 0.5 mm per percent on an adult).
  bool preserve_volume = true;
  // Volumes within this fraction of the input body's are left alone; beyond it the body is
  // offset back to the edge of the band (0 = exactly the input's volume).
  double volume_tolerance = 0.01;
  // Turn the body into the skeleton's rest frame before skinning it for the positional
  // constraints (canonical_rotation): joint rotations are about world axes of that frame, so a
  // body standing turned about the vertical (a scan on a turntable) would otherwise be posed
  // about the wrong axes.
  bool canonical_frame = true;
};

struct PoseMorphSummary {
  int pose_labels = 0, kept_labels = 0, tip_vertices = 0, torso_anchors = 0;
  double volume_ratio_before = 1;   // the decoded body's volume / the input body's, before restore_volume
  double volume_ratio = 1;          // of the result
  double volume_offset_mm = 0;      // normal offset restore_volume applied
  double change_norm = 0;
  int transfer_examples = 0;           // training scans the pose change was taken from
  double transfer_pose_distance = 0;   // joint-angle distance of the nearest one (rad, 2-norm)
};

// Pose change from training examples (full model): samples are grouped into subjects by
// identical subject labels, each subject's standard-pose sample is the one with zero joint
// angles, and the change (posed − standard) of the `neighbours` posed samples nearest in
// joint angles to `target` (L full-model label values; only the pose labels are read) is
// averaged with Gaussian weights.
struct PoseTransfer {
  Eigen::VectorXd coefficient_change;  // K_f
  Eigen::VectorXd pose_labels;         // L, the weighted mean joint angles of the examples
  int examples = 0;
  double nearest_distance = 0;
};
PoseTransfer pose_transfer_from_examples(const SubModel& full, const Eigen::VectorXd& target, int neighbours);

// Rotation G (3×3) that turns body V (#V by 3, standing, +y up) into the rig's rest frame:
// the hip joints' left–right axis onto x, up kept as close to +y as possible. Rows of V·Gᵀ are
// the turned vertices. Identity when the rig has no hip bones.
Eigen::Matrix3d canonical_rotation(const ModelRig& rig, const Eigen::MatrixX3d& V);

// Morphs body V (#V by 3, mm, standard pose) into `pose` (for model.rig's skeleton).
// Throws InputError if the model has no rig.
Eigen::MatrixX3d pose_morph(const BodyModel& model, RelativeRotationDecoder& decoder,
                            const Eigen::MatrixX3d& V, const Pose& pose, const PoseMorphOptions& options = {},
                            PoseMorphSummary* summary = nullptr);

// The positional constraints pose_morph decodes with (limb tips, elbows and knees where skinning
// the body V with the model's rig puts them in `pose`, and the torso anchors when
// options.anchor_torso: `unconstrained` decoded and fitted rigidly onto the skinned torso).
// torso_anchors (optional): how many of them are torso anchors. Empty without tip constraints.
PositionConstraints pose_morph_constraints(const BodyModel& model, RelativeRotationDecoder& decoder,
                                           const Eigen::MatrixX3d& V, const Pose& pose, const Encoding& unconstrained,
                                           const PoseMorphOptions& options = {}, int* torso_anchors = nullptr);

// An in-between of two pose morphs A and B (#V by 3, mm) of body V: their encodings interpolated
// at t (relative rotations, encoding/), decoded with pose_morph's constraints for `pose` (the
// in-between pose, e.g. per-bone slerp) and its volume kept like pose_morph's. Without the
// constraints the limbs of an in-between of two distant poses end far from where the skeleton
// puts them (the hands and feet of a demo character's held-out in-betweens:
// docs/results.md#characters-and-animation).
Eigen::MatrixX3d blend_pose_morphs(const BodyModel& model, RelativeRotationDecoder& decoder,
                                   const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B,
                                   double t, const Pose& pose, const PoseMorphOptions& options = {});

// Mean vertex distance (mm) between A and B after the best rigid fit of A onto B.
double mean_vertex_error_after_rigid_fit(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B);

// Offsets V (#V by 3, mm, closed triangle mesh F) along its area-weighted vertex normals by the
// uniform distance h (mm) that gives it the volume target_volume (mm³): Newton steps on
// h (d volume / d h = surface area) until the relative volume error is below `tolerance`.
// Returns h (0 if V's volume is not positive or the target is not). Changes V in place.
double restore_volume(Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, double target_volume,
                      double tolerance = 1e-5, int max_steps = 6);

// Per-vertex skinning weight (#V, 0..1) of the rig's torso bones: root, spine*, pelvis*.
Eigen::VectorXd torso_weight(const ModelRig& rig);

// How a posed body A sits on a reference B of the same pose (e.g. the body skinned with the
// rig), both #V by 3 mm: A is first placed on B by the best rigid fit over all vertices (as the
// character pipeline places pose morphs), then the torso (torso_w ≥ 0.9) of the placed A is
// fitted rigidly onto B's torso. Reported: that motion's displacement of the torso centroid
// (mm) and its angle (degrees), and the torso's mean vertex distance before and after it.
struct TorsoOffset {
  double translation_mm = 0, rotation_deg = 0;
  double mean_distance_mm = 0, mean_distance_after_mm = 0;
};
TorsoOffset torso_offset(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B, const Eigen::VectorXd& torso_w);

}  // namespace bodymodel
