#include "skinning/skinning_examples.h"

#include <algorithm>
#include <numeric>

#include <tbb/parallel_for.h>

#include "core/error.h"

namespace bodymodel {

bool transforms_are_rigid(const std::vector<BoneTransforms>& T, double tolerance,
                          std::string* problem) {
  for (size_t p = 0; p < T.size(); ++p)
    for (size_t b = 0; b < T[p].size(); ++b) {
      const Eigen::Matrix3d R = T[p][b].linear();
      const double orth = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm();
      const double det = R.determinant();
      if (orth > tolerance || det <= 0) {
        if (problem)
          *problem = "pose " + std::to_string(p) + " bone " + std::to_string(b) +
                     " is not rigid (‖RᵀR − I‖ = " + std::to_string(orth) +
                     ", det R = " + std::to_string(det) + ")";
        return false;
      }
    }
  return true;
}

void validate_examples(const SkinningExamples& ex, bool require_rigid, double rigid_tolerance) {
  const Eigen::Index n = ex.rest.rows();
  if (n == 0) throw InputError("skinning examples: the rest mesh has no vertices");
  if (!ex.rest.allFinite()) throw InputError("skinning examples: rest positions contain NaN");
  if (ex.poses.empty()) throw InputError("skinning examples: no example poses");
  if (ex.transforms.size() != ex.poses.size())
    throw InputError("skinning examples: " + std::to_string(ex.poses.size()) + " pose meshes but " +
                     std::to_string(ex.transforms.size()) + " sets of bone transforms");
  const size_t B = ex.transforms[0].size();
  if (B == 0) throw InputError("skinning examples: pose 0 has no bone transforms");
  for (size_t p = 0; p < ex.poses.size(); ++p) {
    if (ex.poses[p].rows() != n)
      throw InputError("skinning examples: pose " + std::to_string(p) + " has " +
                       std::to_string(ex.poses[p].rows()) + " vertices, the rest mesh has " +
                       std::to_string(n));
    if (!ex.poses[p].allFinite())
      throw InputError("skinning examples: pose " + std::to_string(p) +
                       " contains NaN or infinite positions");
    if (ex.transforms[p].size() != B)
      throw InputError("skinning examples: pose " + std::to_string(p) + " has " +
                       std::to_string(ex.transforms[p].size()) + " bone transforms, pose 0 has " +
                       std::to_string(B));
    for (size_t b = 0; b < B; ++b)
      if (!ex.transforms[p][b].matrix().allFinite())
        throw InputError("skinning examples: pose " + std::to_string(p) + " bone " +
                         std::to_string(b) + " transform contains NaN");
  }
  if (ex.pose_weights.size() != 0) {
    if (ex.pose_weights.size() != static_cast<Eigen::Index>(ex.poses.size()))
      throw InputError("skinning examples: " + std::to_string(ex.pose_weights.size()) +
                       " pose weights for " + std::to_string(ex.poses.size()) + " poses");
    for (Eigen::Index p = 0; p < ex.pose_weights.size(); ++p)
      if (!(ex.pose_weights(p) >= 0) || !std::isfinite(ex.pose_weights(p)))
        throw InputError("skinning examples: pose weight " + std::to_string(p) +
                         " must be finite and non-negative, found " +
                         std::to_string(ex.pose_weights(p)));
  }
  std::string problem;
  if (require_rigid && !transforms_are_rigid(ex.transforms, rigid_tolerance, &problem))
    throw InputError("skinning examples: rigid bone transforms are required but " + problem);
}

Eigen::MatrixXi choose_influences(const SkinningExamples& ex, int max_influences) {
  validate_examples(ex, false);
  const int B = ex.bone_count();
  const int K = std::clamp(max_influences, 1, B);
  const Eigen::Index n = ex.rest.rows();
  Eigen::MatrixXi I(n, K);
  // Blocked over vertices: per pose and bone one vectorised residual of a 256-vertex block
  // (R V_blockᵀ + t − Q_blockᵀ), instead of one 3-vector at a time.
  constexpr Eigen::Index kBlock = 256;
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, (n + kBlock - 1) / kBlock, 1), [&](const auto& r) {
    std::vector<int> order(static_cast<size_t>(B));
    Eigen::Matrix<double, 3, Eigen::Dynamic> Vt, Qt, D;
    Eigen::MatrixXd err;   // B by block
    for (Eigen::Index blk = r.begin(); blk < r.end(); ++blk) {
      const Eigen::Index i0 = blk * kBlock, m = std::min(kBlock, n - i0);
      Vt = ex.rest.middleRows(i0, m).transpose();
      err.setZero(B, m);
      for (int p = 0; p < ex.pose_count(); ++p) {
        Qt = ex.poses[static_cast<size_t>(p)].middleRows(i0, m).transpose();
        const double w = ex.pose_weight(p);
        for (int b = 0; b < B; ++b) {
          const Eigen::Affine3d& M = ex.transforms[static_cast<size_t>(p)][static_cast<size_t>(b)];
          D.noalias() = M.linear() * Vt;
          D.colwise() += M.translation();
          D -= Qt;
          err.row(b).noalias() += w * D.colwise().squaredNorm();
        }
      }
      for (Eigen::Index j = 0; j < m; ++j) {
        std::iota(order.begin(), order.end(), 0);
        std::partial_sort(order.begin(), order.begin() + K, order.end(),
                          [&](int a, int c) { return err(a, j) < err(c, j); });
        for (int k = 0; k < K; ++k) I(i0 + j, k) = order[static_cast<size_t>(k)];
      }
    }
  });
  return I;
}

}  // namespace bodymodel
