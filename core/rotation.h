// Rotation vectors (axis · angle, radians): the one conversion between 3×3 rotation matrices and
// the three numbers that pose files, pose labels and the pose fitter's unknowns store.
#pragma once

#include <Eigen/Core>

namespace bodymodel {

// Rotation vector of a rotation matrix R (3×3, orthonormal, det +1): axis · angle, angle in
// [0, π] radians; the zero vector for the identity.
Eigen::Vector3d rotation_vector_of(const Eigen::Matrix3d& R);

// Rotation matrix (3×3) of a rotation vector v (axis · angle, radians). Vectors shorter than
// 1e-15 rad give exactly the identity.
Eigen::Matrix3d rotation_from_vector(const Eigen::Vector3d& v);

// Angle of the rotation A·Bᵀ (A, B 3×3 rotations), in degrees, in [0, 180].
double rotation_angle_deg(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B);

}  // namespace bodymodel
