#include "skinning/dual_quaternion_skinning.h"

#include <Eigen/Geometry>
#include <string>

#include <tbb/parallel_for.h>

#include "core/error.h"
#include "skinning/skinning_examples.h"

namespace bodymodel {
namespace {

// Unit dual quaternions (real, dual) of rigid maps, coefficients (x, y, z, w).
struct DualQuaternions {
  std::vector<Eigen::Vector4d> real, dual;
};

DualQuaternions to_dual_quaternions(const BoneTransforms& M) {
  std::string problem;
  if (!transforms_are_rigid({M}, 1e-6, &problem))
    throw InputError("dual quaternion skinning: rigid transforms are required but " + problem);
  DualQuaternions q;
  q.real.resize(M.size());
  q.dual.resize(M.size());
  for (size_t b = 0; b < M.size(); ++b) {
    const Eigen::Quaterniond r = Eigen::Quaterniond(M[b].linear()).normalized();
    const Eigen::Vector3d t = M[b].translation();
    const Eigen::Quaterniond d = Eigen::Quaterniond(0, t.x(), t.y(), t.z()) * r;
    q.real[b] = r.coeffs();
    q.dual[b] = 0.5 * d.coeffs();
  }
  return q;
}

// Blend (r, e) accumulated with the weights, normalise, apply to v.
Eigen::Vector3d apply_blend(Eigen::Vector4d r, Eigen::Vector4d e, const Eigen::Vector3d& v) {
  const double len = r.norm();
  r /= len;
  e /= len;
  const Eigen::Quaterniond c0(r(3), r(0), r(1), r(2)), ce(e(3), e(0), e(1), e(2));
  const Eigen::Vector3d t = 2.0 * (c0.w() * ce.vec() - ce.w() * c0.vec() + c0.vec().cross(ce.vec()));
  return c0.toRotationMatrix() * v + t;
}

}  // namespace

Eigen::MatrixX3d dual_quaternion_skinning(const Eigen::MatrixX3d& V, const Eigen::MatrixXd& W,
                                          const BoneTransforms& M) {
  if (W.rows() != V.rows() || W.cols() != static_cast<Eigen::Index>(M.size()))
    throw InputError("dual quaternion skinning: weights are " + std::to_string(W.rows()) + " by " +
                     std::to_string(W.cols()) + ", expected " + std::to_string(V.rows()) + " by " +
                     std::to_string(M.size()));
  const DualQuaternions q = to_dual_quaternions(M);
  const size_t B = M.size();
  Eigen::MatrixX3d out(V.rows(), 3);
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    Eigen::Vector4d r = Eigen::Vector4d::Zero(), e = Eigen::Vector4d::Zero();
    Eigen::Index first = 0;
    W.row(i).maxCoeff(&first);
    const Eigen::Vector4d pivot = q.real[static_cast<size_t>(first)];
    for (size_t b = 0; b < B; ++b) {
      double w = W(i, static_cast<Eigen::Index>(b));
      if (w == 0) continue;
      if (q.real[b].dot(pivot) < 0) w = -w;
      r += w * q.real[b];
      e += w * q.dual[b];
    }
    out.row(i) = apply_blend(r, e, V.row(i).transpose()).transpose();
  }
  return out;
}

Eigen::MatrixX3d dual_quaternion_skinning(const Eigen::MatrixX3d& V, const Eigen::MatrixXi& I,
                                          const Eigen::MatrixXd& W, const BoneTransforms& M) {
  if (I.rows() != V.rows() || W.rows() != V.rows() || W.cols() != I.cols())
    throw InputError("dual quaternion skinning: influences are " + std::to_string(I.rows()) + " by " +
                     std::to_string(I.cols()) + " and weights " + std::to_string(W.rows()) + " by " +
                     std::to_string(W.cols()) + ", expected " + std::to_string(V.rows()) + " rows each, same columns");
  if (I.size() && I.maxCoeff() >= static_cast<int>(M.size()))
    throw InputError("dual quaternion skinning: an influence names bone " + std::to_string(I.maxCoeff()) +
                     ", the pose has " + std::to_string(M.size()) + " transforms");
  const DualQuaternions q = to_dual_quaternions(M);
  Eigen::MatrixX3d out(V.rows(), 3);
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, V.rows(), 1024), [&](const auto& rg) {
    for (Eigen::Index i = rg.begin(); i < rg.end(); ++i) {
      Eigen::Vector4d r = Eigen::Vector4d::Zero(), e = Eigen::Vector4d::Zero();
      Eigen::Index first = -1;   // the slot of the largest weight: its quaternion sets the hemisphere
      for (Eigen::Index k = 0; k < I.cols(); ++k)
        if (I(i, k) >= 0 && (first < 0 || W(i, k) > W(i, first))) first = k;
      if (first < 0) {
        out.row(i) = V.row(i);
        continue;
      }
      const Eigen::Vector4d pivot = q.real[static_cast<size_t>(I(i, first))];
      for (Eigen::Index k = 0; k < I.cols(); ++k) {
        const int b = I(i, k);
        double w = W(i, k);
        if (b < 0 || w == 0) continue;
        if (q.real[static_cast<size_t>(b)].dot(pivot) < 0) w = -w;
        r += w * q.real[static_cast<size_t>(b)];
        e += w * q.dual[static_cast<size_t>(b)];
      }
      out.row(i) = apply_blend(r, e, V.row(i).transpose()).transpose();
    }
  });
  return out;
}

}  // namespace bodymodel
