#include "encoding/deformation_gradient.h"

#include <Eigen/Geometry>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <cmath>
#include <string>

#include "core/error.h"

namespace bodymodel {

namespace {

Eigen::Matrix3d frame_of(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                         const Eigen::Vector3d& c) {
  Eigen::Matrix3d W;
  const Eigen::Vector3d e1 = b - a, e2 = c - a;
  const Eigen::Vector3d n = e1.cross(e2);
  const double len = n.norm();
  W.col(0) = e1;
  W.col(1) = e2;
  W.col(2) = len > 0 ? Eigen::Vector3d(n / std::sqrt(len)) : Eigen::Vector3d::Zero();
  return W;
}

}  // namespace

std::vector<Eigen::Matrix3d> triangle_frames(const Eigen::MatrixX3d& V,
                                             const Eigen::MatrixX3i& F) {
  std::vector<Eigen::Matrix3d> W(F.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    W[f] = frame_of(V.row(F(f, 0)).transpose(), V.row(F(f, 1)).transpose(),
                    V.row(F(f, 2)).transpose());
  return W;
}

std::vector<Eigen::Matrix3d> inverse_rest_frames(const Eigen::MatrixX3d& V_rest,
                                                 const Eigen::MatrixX3i& F) {
  double mean_sq_edge = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      mean_sq_edge += (V_rest.row(F(f, k)) - V_rest.row(F(f, (k + 1) % 3))).squaredNorm();
  mean_sq_edge /= std::max<Eigen::Index>(1, 3 * F.rows());
  std::vector<Eigen::Matrix3d> W = triangle_frames(V_rest, F);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const double dbl_area = (W[f].col(0).cross(W[f].col(1))).norm();
    if (!W[f].allFinite())
      throw InputError("template triangle " + std::to_string(f) +
                       ": expected finite vertex coordinates, found NaN or infinity");
    if (!(dbl_area > 1e-12 * mean_sq_edge))
      throw InputError("template triangle " + std::to_string(f) + " (vertices " +
                       std::to_string(F(f, 0)) + ", " + std::to_string(F(f, 1)) + ", " +
                       std::to_string(F(f, 2)) +
                       "): expected a triangle with non-zero area, found area " +
                       std::to_string(dbl_area / 2) + " (its rest frame is undefined)");
    W[f] = W[f].inverse().eval();
  }
  return W;
}

PolarDecomposition polar_decomposition(const Eigen::Matrix3d& U) {
  // Fast path (the usual case: det U > 0, singular values within a factor 100): eigen-
  // decomposition of UᵀU in closed form, S = Q Σ Qᵀ, R = U S⁻¹, then one Newton step of the
  // polar iteration, which makes R orthonormal to rounding; S = Rᵀ U symmetrised. Several times faster
  // than the SVD below, which handles everything else (reflections, rank deficiency).
  const double det = U.determinant();
  if (det > 0 && U.allFinite()) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(U.transpose() * U);
    const Eigen::Vector3d lambda = es.eigenvalues();  // increasing
    if (es.info() == Eigen::Success && lambda(0) > 1e-4 * lambda(2)) {
      const Eigen::Matrix3d& Q = es.eigenvectors();
      const Eigen::Vector3d inv_sigma = lambda.cwiseSqrt().cwiseInverse();
      Eigen::Matrix3d R = U * (Q * inv_sigma.asDiagonal() * Q.transpose());
      R = 0.5 * (R + R.inverse().transpose());
      if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-13) {
        PolarDecomposition out;
        out.R = R;
        const Eigen::Matrix3d S = R.transpose() * U;
        out.S = 0.5 * (S + S.transpose());
        return out;
      }
    }
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(U, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d P = svd.matrixU();
  const Eigen::Matrix3d& Q = svd.matrixV();
  Eigen::Vector3d sigma = svd.singularValues();
  if ((P * Q.transpose()).determinant() < 0) {
    P.col(2) = -P.col(2);   // smallest singular value is last
    sigma(2) = -sigma(2);
  }
  PolarDecomposition out;
  out.R = P * Q.transpose();
  out.S = Q * sigma.asDiagonal() * Q.transpose();
  out.S = (0.5 * (out.S + out.S.transpose())).eval();
  return out;
}

Eigen::Matrix3d closest_rotation(const Eigen::Matrix3d& A) {
  // The rotation factor of the polar decomposition (the same SVD with the same sign fix, and
  // its closed-form fast path for well-conditioned A with det A > 0).
  return polar_decomposition(A).R;
}

Eigen::Vector3d rotation_log(const Eigen::Matrix3d& R) {
  Eigen::Quaterniond q(R);  // Shepperd's method: robust at every angle
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  const Eigen::Vector3d v = q.vec();
  const double s = v.norm();
  if (s < 1e-12) return (2.0 / q.w()) * v;  // first order: angle ≈ 2 s / w
  return (2.0 * std::atan2(s, q.w()) / s) * v;
}

Eigen::Matrix3d rotation_exp(const Eigen::Vector3d& r) {
  const double theta2 = r.squaredNorm();
  Eigen::Matrix3d K;
  K << 0, -r.z(), r.y(), r.z(), 0, -r.x(), -r.y(), r.x(), 0;
  double a, b;  // sin θ / θ, (1 − cos θ) / θ²
  if (theta2 < 1e-12) {
    a = 1 - theta2 / 6;
    b = 0.5 - theta2 / 24;
  } else {
    const double theta = std::sqrt(theta2);
    a = std::sin(theta) / theta;
    const double h = std::sin(0.5 * theta);
    b = 2 * h * h / theta2;
  }
  return Eigen::Matrix3d::Identity() + a * K + b * K * K;
}

}  // namespace bodymodel
