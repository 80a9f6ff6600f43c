// Skeleton-based pose estimation (Hasler et al. 2009 §2.2): the template, with its skeleton and
// linear-blend-skinning weights, is posed onto a scan by non-linear least squares (Ceres, robust
// loss). Unknowns: a global scale (about the root joint), the global rigid motion and one
// rotation per body segment (registration/pose_parameters.h). Stages (docs/pose_fit.md#stages):
// set-up (registration/pose_problem.h), landmark-only solves, ICP iterations with the paper's
// rejection (registration/pose_residuals.h for the residuals), then the hand stage
// (registration/hand_stage.h). Options and summary: registration/pose_fit_options.h.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/mesh.h"
#include "core/progress.h"
#include "core/skeleton.h"
#include "registration/landmarks.h"
#include "registration/pose_fit_options.h"
#include "registration/pose_parameters.h"

namespace bodymodel {

struct PoseFitResult {
  double scale = 1.0;           // global scale of template and skeleton about the root head
  Pose pose;                    // per-bone rotations (fitted for free bones, identity else)
  Eigen::MatrixX3d V;           // #V by 3 posed (and scaled) template
  std::vector<int> free_bones;  // indices of the fitted bones (root first)
};

// Scales template and skeleton by `scale` about the root head, then poses them with LBS.
//   V_rest #V by 3; returns #V by 3.
Eigen::MatrixX3d pose_template(const Eigen::MatrixX3d& V_rest, const Skeleton& skeleton,
                               const SkinWeights& weights, double scale, const Pose& pose);

// Fits pose and scale of the template (V_rest/F_rest with skeleton and weights) to `scan`
// (unit normals; see prepare_scan). Landmarks whose vertex is mostly bound to bones kept at
// rest (fingers, toes, face) are ignored here. With ≥ 3 landmarks a similarity transform from them
// initialises the global motion; otherwise centroids and bounding-box sizes do. Throws
// InputError for options out of range (PoseFitOptions::validate) or inputs that do not fit.
PoseFitResult fit_pose(const Mesh& template_rest, const Skeleton& skeleton,
                       const SkinWeights& weights, const PointCloud& scan,
                       const std::vector<Landmark>& landmarks, const PoseFitOptions& options = {},
                       PoseFitSummary* summary = nullptr, const ProgressCallback& progress = {});

}  // namespace bodymodel
