#include "skinning/skinning_rig.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <tbb/parallel_for.h>

#include "core/error.h"
#include "skinning/dual_quaternion_skinning.h"

namespace bodymodel {

SkinningMethod parse_skinning_method(const std::string& name) {
  if (name == "ssd" || name == "lbs") return SkinningMethod::lbs;
  if (name == "as" || name == "animation_space") return SkinningMethod::animation_space;
  if (name == "mwe") return SkinningMethod::mwe;
  if (name == "dqs") return SkinningMethod::dqs;
  throw InputError("unknown skinning method '" + name + "' (expected ssd, dqs, as or mwe)");
}

std::string skinning_method_name(SkinningMethod m) {
  switch (m) {
    case SkinningMethod::lbs: return "ssd";
    case SkinningMethod::animation_space: return "as";
    case SkinningMethod::mwe: return "mwe";
    case SkinningMethod::dqs: return "dqs";
  }
  return "?";
}

int coefficients_per_influence(SkinningMethod m) {
  switch (m) {
    case SkinningMethod::lbs: return 1;
    case SkinningMethod::animation_space: return 4;
    case SkinningMethod::mwe: return 12;
    case SkinningMethod::dqs: return 1;
  }
  return 1;
}

void SkinningRig::validate(const std::string& what) const {
  const Eigen::Index n = rest.rows(), K = influences.cols();
  const int c = coefficients_per_influence(method);
  if (bone_count <= 0) throw InputError(what + ": bone count must be positive, found " +
                                        std::to_string(bone_count));
  if (influences.rows() != n)
    throw InputError(what + ": influences have " + std::to_string(influences.rows()) +
                     " rows, expected one per vertex (" + std::to_string(n) + ")");
  if (coefficients.rows() != n || coefficients.cols() != K * c)
    throw InputError(what + ": coefficients are " + std::to_string(coefficients.rows()) + " by " +
                     std::to_string(coefficients.cols()) + ", expected " + std::to_string(n) +
                     " by " + std::to_string(K * c) + " (" + std::to_string(K) + " slots × " +
                     std::to_string(c) + ")");
  if (!rest.allFinite()) throw InputError(what + ": rest positions contain NaN or infinity");
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index k = 0; k < K; ++k) {
      const int b = influences(i, k);
      if (b < -1 || b >= bone_count)
        throw InputError(what + ": vertex " + std::to_string(i) + " slot " + std::to_string(k) +
                         " names bone " + std::to_string(b) + ", expected -1 or 0.." +
                         std::to_string(bone_count - 1));
    }
    if (!coefficients.row(i).allFinite())
      throw InputError(what + ": coefficients of vertex " + std::to_string(i) +
                       " contain NaN or infinity");
  }
}

Eigen::MatrixX3d evaluate_rig(const SkinningRig& rig, const BoneTransforms& M) {
  if (static_cast<int>(M.size()) != rig.bone_count)
    throw InputError("evaluate_rig: rig has " + std::to_string(rig.bone_count) +
                     " bones, the pose has " + std::to_string(M.size()) + " transforms");
  if (rig.method == SkinningMethod::dqs)
    return dual_quaternion_skinning(rig.rest, rig.influences, rig.coefficients, M);
  const Eigen::Index n = rig.rest.rows(), K = rig.influences.cols();
  Eigen::MatrixX3d out(n, 3);
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, n, 1024), [&](const auto& r) {
    for (Eigen::Index i = r.begin(); i < r.end(); ++i) {
      const Eigen::Vector4d v(rig.rest(i, 0), rig.rest(i, 1), rig.rest(i, 2), 1.0);
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      for (Eigen::Index k = 0; k < K; ++k) {
        const int b = rig.influences(i, k);
        if (b < 0) continue;
        const auto A = M[static_cast<size_t>(b)].affine();   // 3 by 4
        switch (rig.method) {
          case SkinningMethod::lbs: p += rig.coefficients(i, k) * (A * v); break;
          case SkinningMethod::animation_space:
            p += A * rig.coefficients.row(i).segment<4>(4 * k).transpose();
            break;
          case SkinningMethod::mwe:
            for (int j = 0; j < 3; ++j)
              for (int c = 0; c < 4; ++c)
                p(j) += rig.coefficients(i, 12 * k + 4 * j + c) * A(j, c) * v(c);
            break;
          case SkinningMethod::dqs: break;   // handled above
        }
      }
      out.row(i) = p.transpose();
    }
  });
  return out;
}

Eigen::MatrixXd dense_weights(const SkinningRig& rig) {
  if (rig.method != SkinningMethod::lbs && rig.method != SkinningMethod::dqs)
    throw InputError("dense_weights: the rig is " + skinning_method_name(rig.method) +
                     ", expected an ssd (LBS) or dqs rig");
  Eigen::MatrixXd W = Eigen::MatrixXd::Zero(rig.rest.rows(), rig.bone_count);
  for (Eigen::Index i = 0; i < rig.rest.rows(); ++i)
    for (Eigen::Index k = 0; k < rig.influences.cols(); ++k)
      if (rig.influences(i, k) >= 0) W(i, rig.influences(i, k)) += rig.coefficients(i, k);
  return W;
}

SkinningRig lbs_rig_from_weights(const Eigen::MatrixX3d& rest, const Eigen::MatrixXd& W,
                                 int max_influences, double threshold) {
  if (W.rows() != rest.rows())
    throw InputError("weights have " + std::to_string(W.rows()) + " rows, the rest mesh has " +
                     std::to_string(rest.rows()) + " vertices");
  if (max_influences < 1) throw InputError("max_influences must be at least 1");
  SkinningRig rig;
  rig.method = SkinningMethod::lbs;
  rig.bone_count = static_cast<int>(W.cols());
  rig.rest = rest;
  const int K = std::min<int>(max_influences, static_cast<int>(W.cols()));
  rig.influences = Eigen::MatrixXi::Constant(rest.rows(), K, -1);
  rig.coefficients = Eigen::MatrixXd::Zero(rest.rows(), K);
  std::vector<int> order(static_cast<size_t>(W.cols()));
  for (Eigen::Index i = 0; i < W.rows(); ++i) {
    if (!W.row(i).allFinite())
      throw InputError("weights of vertex " + std::to_string(i) + " contain NaN or infinity");
    std::iota(order.begin(), order.end(), 0);
    std::partial_sort(order.begin(), order.begin() + K, order.end(),
                      [&](int a, int b) { return W(i, a) > W(i, b); });
    double sum = 0;
    int used = 0;
    for (int k = 0; k < K; ++k) {
      if (W(i, order[static_cast<size_t>(k)]) <= threshold && used > 0) break;
      rig.influences(i, used) = order[static_cast<size_t>(k)];
      rig.coefficients(i, used) = std::max(0.0, W(i, order[static_cast<size_t>(k)]));
      sum += rig.coefficients(i, used);
      ++used;
    }
    if (sum <= 0) {
      rig.coefficients(i, 0) = 1.0;
      sum = 1.0;
    }
    rig.coefficients.row(i) /= sum;
  }
  return rig;
}

SkinningRig lbs_as_mwe(const SkinningRig& lbs) {
  if (lbs.method != SkinningMethod::lbs) throw InputError("lbs_as_mwe: expected an ssd rig");
  SkinningRig m = lbs;
  m.method = SkinningMethod::mwe;
  const Eigen::Index K = lbs.influences.cols();
  m.coefficients.resize(lbs.rest.rows(), 12 * K);
  for (Eigen::Index k = 0; k < K; ++k)
    for (int c = 0; c < 12; ++c) m.coefficients.col(12 * k + c) = lbs.coefficients.col(k);
  return m;
}

}  // namespace bodymodel
