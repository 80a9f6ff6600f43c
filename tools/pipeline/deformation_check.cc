#include "tools/pipeline/deformation_check.h"

#include <algorithm>
#include <map>
#include <vector>

#include "core/error.h"
#include "core/geometry.h"

namespace bodymodel {

DeformationChecker::DeformationChecker(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3i& F,
                                       const SkinningRig& lbs)
    : F_(F), E_(unique_edges(F)) {
  if (lbs.method != SkinningMethod::lbs || lbs.vertex_count() != rest.rows())
    throw InputError("deformation check: needs an SSD rig of the mesh's " + std::to_string(rest.rows()) +
                     " vertices");
  rest_length_.resize(E_.rows());
  for (Eigen::Index e = 0; e < E_.rows(); ++e)
    rest_length_(e) = std::max((rest.row(E_(e, 0)) - rest.row(E_(e, 1))).norm(), 1e-12);
  rest_normals_ = face_normals(rest, F);
  vertex_bone_.resize(rest.rows());
  for (Eigen::Index v = 0; v < rest.rows(); ++v) {
    int best = 0;
    double bw = -1;
    for (int k = 0; k < lbs.max_influences(); ++k)
      if (lbs.influences(v, k) >= 0 && lbs.coefficients(v, k) > bw) bw = lbs.coefficients(v, k), best = lbs.influences(v, k);
    vertex_bone_(v) = best;
  }
  dominant_bone_.resize(F.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    std::map<int, double> w;
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < lbs.max_influences(); ++k) {
        int b = lbs.influences(F(f, c), k);
        if (b >= 0) w[b] += lbs.coefficients(F(f, c), k);
      }
    int best = 0;
    double bw = -1;
    for (auto [b, x] : w)
      if (x > bw) bw = x, best = b;
    dominant_bone_(f) = best;
  }
}

FrameCheck DeformationChecker::check(const Eigen::MatrixX3d& X, const BoneTransforms& M) const {
  FrameCheck c;
  c.max_edge_ratio = 0;
  c.min_edge_ratio = std::numeric_limits<double>::infinity();
  std::vector<double> ratios(E_.rows());
  for (Eigen::Index e = 0; e < E_.rows(); ++e) {
    const double r = (X.row(E_(e, 0)) - X.row(E_(e, 1))).norm() / rest_length_(e);
    ratios[e] = r;
    if (!(r <= c.max_edge_ratio)) c.max_edge_ratio = r, c.worst_edge = static_cast<int>(e);
    c.min_edge_ratio = std::min(c.min_edge_ratio, r);
  }
  if (!ratios.empty()) {
    const size_t k = static_cast<size_t>(0.99 * (ratios.size() - 1));
    std::nth_element(ratios.begin(), ratios.begin() + static_cast<long>(k), ratios.end());
    c.p99_edge_ratio = ratios[k];
  }
  c.flipped = static_cast<int>(flipped_faces(X, M).size());
  return c;
}

Eigen::MatrixX3d DeformationChecker::reference_normals(const BoneTransforms& M) const {
  Eigen::MatrixX3d R(F_.rows(), 3);
  for (Eigen::Index f = 0; f < F_.rows(); ++f)
    R.row(f) = (M[dominant_bone_(f)].linear() * rest_normals_.row(f).transpose()).transpose();
  return R;
}

std::vector<int> DeformationChecker::flipped_faces(const Eigen::MatrixX3d& X, const BoneTransforms& M) const {
  std::vector<int> out;
  const Eigen::MatrixX3d N = face_normals(X, F_);
  const Eigen::MatrixX3d R = reference_normals(M);
  for (Eigen::Index f = 0; f < F_.rows(); ++f)
    if (N.row(f).dot(R.row(f)) < 0) out.push_back(static_cast<int>(f));
  return out;
}

}  // namespace bodymodel
