// Per-triangle deformation gradients and their polar decomposition (Hasler et al. 2009 §3,
// docs/method.md §3.1; the fourth-vertex construction of Sumner & Popović 2004 §3).
//
// A triangle (v1, v2, v3) gets the frame W = [v2 − v1, v3 − v1, n] with n = (v2 − v1) × (v3 − v1)
// / sqrt(‖(v2 − v1) × (v3 − v1)‖): the "fourth vertex" v1 + n lies off the plane at a distance
// that scales like the edges (length-consistent), so W is invertible for every non-degenerate
// triangle and det W > 0. The deformation gradient from a rest triangle to a deformed one is
// U = W_deformed · W_rest⁻¹: it maps rest edges onto deformed edges and the rest normal onto the
// deformed normal scaled by sqrt(area ratio).
#pragma once

#include <Eigen/Core>
#include <vector>

namespace bodymodel {

// Frame W of every triangle (see above); zero-area triangles get n = 0 (W is then singular).
//   V  #V by 3,  F  #F by 3.   returns #F matrices
std::vector<Eigen::Matrix3d> triangle_frames(const Eigen::MatrixX3d& V,
                                             const Eigen::MatrixX3i& F);

// Inverse rest frames W_rest⁻¹ of every triangle of a template.
// Throws InputError naming the first triangle whose area is zero (relative to the squared mean
// edge length, below 1e-12) or whose coordinates are not finite: its rest frame is undefined.
std::vector<Eigen::Matrix3d> inverse_rest_frames(const Eigen::MatrixX3d& V_rest,
                                                 const Eigen::MatrixX3i& F);

// Polar decomposition U = R · S with R a proper rotation (det R = +1) and S symmetric. Usual
// case (det U > 0, condition below 100): closed-form eigen-decomposition of UᵀU plus one Newton
// polar step. Otherwise by SVD
// U = P Σ Qᵀ: R = P Qᵀ, S = Q Σ Qᵀ. When det(P Qᵀ) < 0 (a reflection, only possible for
// degenerate or inverted input) the singular direction of the smallest singular value is
// flipped, so S gets one negative eigenvalue and R·S still equals U exactly. Rank-deficient U
// (zero-area triangles) is handled the same way: R is then one valid choice among several.
struct PolarDecomposition {
  Eigen::Matrix3d R;   // rotation
  Eigen::Matrix3d S;   // symmetric stretch
};
PolarDecomposition polar_decomposition(const Eigen::Matrix3d& U);

// Closest rotation to A (Frobenius norm), by SVD with the determinant fixed to +1.
Eigen::Matrix3d closest_rotation(const Eigen::Matrix3d& A);

// Rotation vector (axis · angle, radians, angle in [0, π]) of a rotation matrix, and back.
// Both are accurate near the identity (series expansions) and near π.
Eigen::Vector3d rotation_log(const Eigen::Matrix3d& R);
Eigen::Matrix3d rotation_exp(const Eigen::Vector3d& r);

}  // namespace bodymodel
