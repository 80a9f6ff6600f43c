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
  // On by default: held-out mean error 21.4 mm with, 24.2 mm without (at damping 1e-4);
  // 19.5 mm with at the default damping 1e-3 (10 held-out scans, 30-subject model).
  bool constrain_elbows_and_knees = true;
  int vertices_per_tip = 40;   // most strongly bound vertices of each tip bone (and children)
  bool use_tip_constraints = true;
  // Labels held at their current value besides the joint angles being set (empty = every
  // non-pose label of the full model).
  std::vector<std::string> keep_labels;
  // eq. 11 with many constraints: damping relative to the largest squared singular value
  // (1e-3 beat 1e-2, 1e-4 and 1e-5 on held-out scans).
  double damping = 1e-3;
};

struct PoseMorphSummary {
  int pose_labels = 0, kept_labels = 0, tip_vertices = 0;
  double change_norm = 0;
};

// Morphs body V (#V by 3, mm, standard pose) into `pose` (for model.rig's skeleton).
// Throws InputError if the model has no rig.
Eigen::MatrixX3d pose_morph(const BodyModel& model, RelativeRotationDecoder& decoder,
                            const Eigen::MatrixX3d& V, const Pose& pose, const PoseMorphOptions& options = {},
                            PoseMorphSummary* summary = nullptr);

// Mean vertex distance (mm) between A and B after the best rigid fit of A onto B.
double mean_vertex_error_after_rigid_fit(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B);

}  // namespace bodymodel
