#include "skinning/dual_quaternion_skinning.h"

#include <Eigen/Geometry>
#include <string>

#include "core/error.h"
#include "skinning/skinning_examples.h"

namespace bodymodel {

Eigen::MatrixX3d dual_quaternion_skinning(const Eigen::MatrixX3d& V, const Eigen::MatrixXd& W,
                                          const BoneTransforms& M) {
  if (W.rows() != V.rows() || W.cols() != static_cast<Eigen::Index>(M.size()))
    throw InputError("dual quaternion skinning: weights are " + std::to_string(W.rows()) + " by " +
                     std::to_string(W.cols()) + ", expected " + std::to_string(V.rows()) + " by " +
                     std::to_string(M.size()));
  std::string problem;
  if (!transforms_are_rigid({M}, 1e-6, &problem))
    throw InputError("dual quaternion skinning: rigid transforms are required but " + problem);
  const size_t B = M.size();
  std::vector<Eigen::Quaterniond> real(B), dual(B);
  for (size_t b = 0; b < B; ++b) {
    real[b] = Eigen::Quaterniond(M[b].linear()).normalized();
    const Eigen::Vector3d t = M[b].translation();
    const Eigen::Quaterniond tq(0, t.x(), t.y(), t.z());
    const Eigen::Quaterniond d = tq * real[b];
    dual[b] = Eigen::Quaterniond(0.5 * d.w(), 0.5 * d.x(), 0.5 * d.y(), 0.5 * d.z());
  }
  Eigen::MatrixX3d out(V.rows(), 3);
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    Eigen::Vector4d r = Eigen::Vector4d::Zero(), e = Eigen::Vector4d::Zero();
    Eigen::Index first = 0;
    W.row(i).maxCoeff(&first);
    const Eigen::Vector4d pivot = real[static_cast<size_t>(first)].coeffs();
    for (size_t b = 0; b < B; ++b) {
      double w = W(i, static_cast<Eigen::Index>(b));
      if (w == 0) continue;
      if (real[b].coeffs().dot(pivot) < 0) w = -w;
      r += w * real[b].coeffs();
      e += w * dual[b].coeffs();
    }
    const double len = r.norm();
    r /= len;
    e /= len;
    const Eigen::Quaterniond c0(r(3), r(0), r(1), r(2)), ce(e(3), e(0), e(1), e(2));
    const Eigen::Vector3d v = V.row(i).transpose();
    const Eigen::Vector3d t =
        2.0 * (c0.w() * ce.vec() - ce.w() * c0.vec() + c0.vec().cross(ce.vec()));
    out.row(i) = (c0.toRotationMatrix() * v + t).transpose();
  }
  return out;
}

}  // namespace bodymodel
