#include "registration/segments.h"

#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/point_index.h"

namespace bodymodel {

BodySegments body_segments(const Skeleton& sk, const SkinWeights& W, const Eigen::MatrixX3i& F) {
  const int nb = sk.bone_count();
  if (W.cols() != nb)
    throw InputError("body segments: the skinning weights have " + std::to_string(W.cols()) +
                     " columns, the skeleton " + std::to_string(nb) + " bones");
  BodySegments s;
  s.names = {"torso"};
  std::vector<int> root_segment(nb, -1);
  for (const char* side : {".L", ".R"})
    for (const char* part : {"upperarm01", "lowerarm01", "upperleg01", "lowerleg01"}) {
      const int b = sk.find(std::string(part) + side);
      if (b < 0) continue;  // a skeleton without the limb: its vertices stay in the torso
      root_segment[b] = s.count();
      s.names.push_back(std::string(part).substr(0, std::string(part).size() - 2) + side);
    }
  // parents[b] < b: one pass down the tree.
  std::vector<int> bone_segment(nb, 0);
  for (int b = 0; b < nb; ++b)
    bone_segment[b] = root_segment[b] >= 0 ? root_segment[b] : sk.parents[b] >= 0 ? bone_segment[sk.parents[b]] : 0;
  const int n = int(W.rows());
  s.vertex_segment = Eigen::VectorXi::Zero(n);
  Eigen::VectorXd sum(s.count());
  for (int i = 0; i < n; ++i) {
    sum.setZero();
    for (SkinWeights::InnerIterator it(W, i); it; ++it) sum(bone_segment[it.col()]) += it.value();
    sum.maxCoeff(&s.vertex_segment(i));
  }
  s.adjacent = Eigen::MatrixXi::Identity(s.count(), s.count());
  if (F.size() > 0 && (F.minCoeff() < 0 || F.maxCoeff() >= n))
    throw InputError("body segments: a face index is outside the weights' " + std::to_string(n) + " rows");
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int e = 0; e < 3; ++e) {
      const int a = s.vertex_segment(F(f, e)), b = s.vertex_segment(F(f, (e + 1) % 3));
      s.adjacent(a, b) = s.adjacent(b, a) = 1;
    }
  return s;
}

Eigen::VectorXi point_segments(const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& N, const Eigen::MatrixX3d& V,
                               const Eigen::MatrixX3d& VN, const Eigen::VectorXi& vertex_segment,
                               const PointSegmentOptions& o) {
  if (vertex_segment.size() != V.rows() || VN.rows() != V.rows())
    throw InputError("point segments: " + std::to_string(V.rows()) + " vertices, " + std::to_string(VN.rows()) +
                     " normals and " + std::to_string(vertex_segment.size()) + " labels");
  const bool has_n = N.rows() == P.rows() && P.rows() > 0;
  Eigen::VectorXi out = Eigen::VectorXi::Constant(P.rows(), -1);
  if (V.rows() == 0) return out;
  const PointIndex index(V);
  const int k = std::max(1, std::min<int>(o.neighbours, int(V.rows())));
  tbb::parallel_for(Eigen::Index(0), P.rows(), [&](Eigen::Index j) {
    const std::vector<int> near = index.knn(P.row(j).transpose(), k);
    int pick = near.empty() ? -1 : near.front();
    if (has_n)
      for (int i : near) {
        const double c = N.row(j).dot(VN.row(i));
        if ((o.unsigned_normals ? std::abs(c) : c) > o.min_normal_cos) {
          pick = i;
          break;
        }
      }
    if (pick >= 0) out(j) = vertex_segment(pick);
  });
  return out;
}

}  // namespace bodymodel
