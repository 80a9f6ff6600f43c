#include "registration/pose_residuals.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace bodymodel {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

void rotation_and_left_jacobian(const double* aa, Eigen::Matrix3d* R, Eigen::Matrix3d* J) {
  const Eigen::Vector3d phi(aa[0], aa[1], aa[2]);
  const double th = phi.norm();
  const Eigen::Matrix3d K = skew(phi);
  if (th < 1e-8) {
    *R = Eigen::Matrix3d::Identity() + K;
    *J = Eigen::Matrix3d::Identity() + 0.5 * K;
    return;
  }
  *R = Eigen::AngleAxisd(th, phi / th).toRotationMatrix();
  *J = Eigen::Matrix3d::Identity() + (1 - std::cos(th)) / (th * th) * K +
       (th - std::sin(th)) / (th * th * th) * K * K;
}

PointResidual::PointResidual(const Chain* chain, const Skeleton* skeleton, const Eigen::Vector3d& x,
                             const Eigen::Vector3d& target, const Eigen::Vector3d& normal,
                             double weight, double plane_weight, double point_weight,
                             const std::vector<int>& block_sizes)
    : chain_(chain), skeleton_(skeleton), x_(x), target_(target), normal_(normal),
      weight_(weight), plane_weight_(plane_weight), point_weight_(point_weight) {
  set_num_residuals(4);
  auto* sizes = mutable_parameter_block_sizes();
  sizes->push_back(1);
  sizes->push_back(3);
  sizes->push_back(3);
  for (int b : block_sizes) sizes->push_back(b);
}

bool PointResidual::Evaluate(double const* const* p, double* r, double** jac) const {
  const Chain& ch = *chain_;
  const Skeleton& sk = *skeleton_;
  const int m = int(ch.bones.size());
  const double s = p[0][0];
  std::vector<Eigen::Matrix3d> Q(m), J(m);
  std::vector<Eigen::Vector3d> h(m);
  for (int c = 0; c < m; ++c) {
    const int b = ch.bones[c], pc = ch.parent[c];
    Eigen::Matrix3d R;
    if (pc < 0) {
      rotation_and_left_jacobian(p[1], &R, &J[c]);
      Q[c] = R;
      h[c] = sk.heads.row(b).transpose() + Eigen::Map<const Eigen::Vector3d>(p[2]);
      continue;
    }
    h[c] = h[pc] + Q[pc] * (s * (sk.heads.row(b) - sk.heads.row(ch.bones[pc])).transpose());
    if (ch.slot[c] >= 0) {
      const Eigen::Vector3d aa = ch.twist_axis[c].squaredNorm() > 0
                                     ? Eigen::Vector3d(p[ch.slot[c]][0] * ch.twist_axis[c])
                                     : Eigen::Vector3d(Eigen::Map<const Eigen::Vector3d>(p[ch.slot[c]]));
      rotation_and_left_jacobian(aa.data(), &R, &J[c]);
      Q[c] = Q[pc] * R;
    } else {
      Q[c] = Q[pc];
    }
  }
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> vc(ch.blend.size());
  for (size_t e = 0; e < ch.blend.size(); ++e) {
    const auto& [c, w] = ch.blend[e];
    vc[e] = Q[c] * (s * (x_ - sk.heads.row(ch.bones[c]).transpose())) + h[c];
    v += w * vc[e];
  }
  const Eigen::Vector3d d = v - target_;
  r[0] = weight_ * plane_weight_ * normal_.dot(d);
  for (int k = 0; k < 3; ++k) r[1 + k] = weight_ * point_weight_ * d[k];
  if (!jac) return true;
  // Residual rows as a 4×3 map of dv.
  Eigen::Matrix<double, 4, 3> P;
  P.row(0) = weight_ * plane_weight_ * normal_.transpose();
  P.bottomRows<3>() = weight_ * point_weight_ * Eigen::Matrix3d::Identity();
  const auto& sizes = parameter_block_sizes();
  for (size_t k = 3; k < sizes.size(); ++k)
    if (jac[k]) std::fill(jac[k], jac[k] + 4 * sizes[k], 0.0);
  auto put = [&](int block, const Eigen::MatrixXd& dv, bool add) {
    if (!jac[block]) return;
    Eigen::Map<Eigen::Matrix<double, 4, Eigen::Dynamic, Eigen::RowMajor>> Jm(jac[block], 4,
                                                                              dv.cols());
    if (add) Jm += P * dv;
    else Jm = P * dv;
  };
  const Eigen::Vector3d root_h = h[0];
  put(0, (v - root_h) / s, false);
  put(2, Eigen::Matrix3d::Identity(), false);
  // A rotation at chain bone a moves the points of the bones below it about its posed head:
  // dv = −Σ_e w_e [v_e − h_a]× ω_a,  ω_a = Q_parent(a) J_l(φ_a) dφ_a  (dφ_a = axis·dθ for a
  // 1-DOF bone; tied bones add their columns into the shared block).
  for (int a = 0; a < m; ++a) {
    const int block = a == 0 ? 1 : ch.slot[a];
    if (block < 0) continue;
    Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
    for (size_t e = 0; e < ch.blend.size(); ++e)
      if (ch.below[e][a]) M -= ch.blend[e].second * skew(vc[e] - h[a]);
    const Eigen::Matrix3d Qp = a == 0 ? Eigen::Matrix3d::Identity() : Q[ch.parent[a]];
    const Eigen::Matrix3d D = M * Qp * J[a];
    if (a > 0 && ch.twist_axis[a].squaredNorm() > 0)
      put(block, D * ch.twist_axis[a], true);
    else
      put(block, D, a > 0);
  }
  return true;
}

}  // namespace bodymodel
