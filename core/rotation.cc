#include "core/rotation.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace bodymodel {

Eigen::Vector3d rotation_vector_of(const Eigen::Matrix3d& R) {
  Eigen::AngleAxisd a(R);
  return a.angle() * a.axis();
}

Eigen::Matrix3d rotation_from_vector(const Eigen::Vector3d& v) {
  const double a = v.norm();
  if (a < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(a, v / a).toRotationMatrix();
}

double rotation_angle_deg(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  const Eigen::Matrix3d D = A * B.transpose();
  return std::acos(std::clamp((D.trace() - 1.0) / 2.0, -1.0, 1.0)) * 180.0 / M_PI;
}

}  // namespace bodymodel
