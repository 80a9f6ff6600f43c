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
  // Turn the body into the skeleton's rest frame before skinning it for the positional
  // constraints (canonical_rotation): joint rotations are about world axes of that frame, so a
  // body standing turned about the vertical (a scan on a turntable) would otherwise be posed
  // about the wrong axes.
  bool canonical_frame = true;
};

struct PoseMorphSummary {
  int pose_labels = 0, kept_labels = 0, tip_vertices = 0;
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

// A pose file as the synthetic database writes it (DB/truth/<scan>.pose.csv: a header, then
// bone,rx,ry,rz rotation vectors in radians; rows starting with '_' are global and skipped) as
// a Pose of the skeleton with bone names `bones` (bones not in the file keep the rest rotation).
// InputError naming the file and line for a malformed number.
Pose read_pose_csv(const std::string& path, const std::vector<std::string>& bones);

// Mean vertex distance (mm) between A and B after the best rigid fit of A onto B.
double mean_vertex_error_after_rigid_fit(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B);

}  // namespace bodymodel
