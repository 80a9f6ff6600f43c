#include "core/skeleton.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <string>

#include "core/error.h"

namespace bodymodel {

int Skeleton::find(std::string_view name) const {
  for (int b = 0; b < bone_count(); ++b)
    if (names[b] == name) return b;
  return -1;
}

int Skeleton::index(std::string_view name) const {
  const int b = find(name);
  if (b < 0)
    throw InputError("skeleton has no bone called '" + std::string(name) + "' (" +
                     std::to_string(bone_count()) + " bones)");
  return b;
}

void Skeleton::validate() const {
  const int n = bone_count();
  if (static_cast<int>(parents.size()) != n || heads.rows() != n || tails.rows() != n)
    throw InputError("skeleton sizes disagree: " + std::to_string(n) + " names, " +
                     std::to_string(parents.size()) + " parents, " +
                     std::to_string(heads.rows()) + " heads, " + std::to_string(tails.rows()) +
                     " tails");
  for (int b = 0; b < n; ++b) {
    if (parents[b] < -1 || parents[b] >= b)
      throw InputError("skeleton bone '" + names[b] + "' (index " + std::to_string(b) +
                       ") has parent index " + std::to_string(parents[b]) +
                       "; expected -1 or an index below " + std::to_string(b));
    if (!heads.row(b).allFinite() || !tails.row(b).allFinite())
      throw InputError("skeleton bone '" + names[b] + "' has a non-finite head or tail");
  }
}

Pose Pose::rest(int bone_count) {
  Pose p;
  p.rotations.assign(bone_count, Eigen::Matrix3d::Identity());
  return p;
}

namespace {
void check_pose(const Skeleton& skeleton, const Pose& pose) {
  if (static_cast<int>(pose.rotations.size()) != skeleton.bone_count())
    throw InputError("pose has " + std::to_string(pose.rotations.size()) +
                     " rotations but the skeleton has " + std::to_string(skeleton.bone_count()) +
                     " bones");
}
}  // namespace

std::vector<Eigen::Matrix3d> world_rotations(const Skeleton& skeleton, const Pose& pose) {
  check_pose(skeleton, pose);
  const int n = skeleton.bone_count();
  std::vector<Eigen::Matrix3d> Q(n);
  for (int b = 0; b < n; ++b) {
    const int p = skeleton.parents[b];
    Q[b] = p < 0 ? pose.rotations[b] : Eigen::Matrix3d(Q[p] * pose.rotations[b]);
  }
  return Q;
}

BoneTransforms forward_kinematics(const Skeleton& skeleton, const Pose& pose) {
  const std::vector<Eigen::Matrix3d> Q = world_rotations(skeleton, pose);
  const int n = skeleton.bone_count();
  std::vector<Eigen::Vector3d> posed_heads(n);
  BoneTransforms M(n);
  for (int b = 0; b < n; ++b) {
    const int p = skeleton.parents[b];
    const Eigen::Vector3d h = skeleton.heads.row(b).transpose();
    if (p < 0) {
      posed_heads[b] = h + pose.root_translation;
    } else {
      const Eigen::Vector3d hp = skeleton.heads.row(p).transpose();
      posed_heads[b] = posed_heads[p] + Q[p] * (h - hp);
    }
    // M_b(x) = Q_b (x - h_b) + h'_b
    M[b].linear() = Q[b];
    M[b].translation() = posed_heads[b] - Q[b] * h;
    M[b].makeAffine();
  }
  return M;
}

Eigen::MatrixX3d linear_blend_skinning(const Eigen::MatrixX3d& V, const SkinWeights& W,
                                       const BoneTransforms& M) {
  if (W.rows() != V.rows())
    throw InputError("skinning weights have " + std::to_string(W.rows()) +
                     " rows but the mesh has " + std::to_string(V.rows()) + " vertices");
  if (W.cols() != static_cast<Eigen::Index>(M.size()))
    throw InputError("skinning weights have " + std::to_string(W.cols()) +
                     " columns but there are " + std::to_string(M.size()) + " bone transforms");
  // Each bone's 3x4 matrix, packed contiguously for the inner loop.
  const Eigen::Index nb = W.cols();
  std::vector<double> A(static_cast<size_t>(nb) * 12);
  for (Eigen::Index b = 0; b < nb; ++b) {
    const Eigen::Matrix<double, 3, 4> m = M[b].affine();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) A[b * 12 + r * 4 + c] = m(r, c);
  }
  Eigen::MatrixX3d out(V.rows(), 3);
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, V.rows(), 2048),
                    [&](const tbb::blocked_range<Eigen::Index>& range) {
    for (Eigen::Index i = range.begin(); i != range.end(); ++i) {
      double m[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
      for (SkinWeights::InnerIterator it(W, i); it; ++it) {
        const double w = it.value();
        const double* a = &A[static_cast<size_t>(it.col()) * 12];
        for (int k = 0; k < 12; ++k) m[k] += w * a[k];
      }
      const double x = V(i, 0), y = V(i, 1), z = V(i, 2);
      out(i, 0) = m[0] * x + m[1] * y + m[2] * z + m[3];
      out(i, 1) = m[4] * x + m[5] * y + m[6] * z + m[7];
      out(i, 2) = m[8] * x + m[9] * y + m[10] * z + m[11];
    }
  });
  return out;
}

}  // namespace bodymodel
