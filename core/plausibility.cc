#include "core/plausibility.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Box_intersection_d/Box_with_info_d.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>

#include <algorithm>
#include <atomic>
#include <cmath>

#include "core/geometry.h"

namespace bodymodel {

Eigen::VectorXd vertex_roughness_deg(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  const Eigen::MatrixX3d N = vertex_normals(V, F);
  // One-ring neighbours through the edges.
  const Eigen::MatrixX2i E = unique_edges(F);
  Eigen::MatrixX3d sum = Eigen::MatrixX3d::Zero(V.rows(), 3);
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    sum.row(E(e, 0)) += N.row(E(e, 1));
    sum.row(E(e, 1)) += N.row(E(e, 0));
  }
  Eigen::VectorXd angle = Eigen::VectorXd::Zero(V.rows());
  for (Eigen::Index v = 0; v < V.rows(); ++v) {
    const double len = sum.row(v).norm(), n = N.row(v).norm();
    if (len <= 0 || n <= 0) continue;
    const double c = std::clamp(sum.row(v).dot(N.row(v)) / (len * n), -1.0, 1.0);
    angle(v) = std::acos(c) * 180.0 / M_PI;
  }
  return angle;
}

Roughness roughness(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const std::vector<char>& region) {
  const Eigen::VectorXd a = vertex_roughness_deg(V, F);
  std::vector<double> values;
  values.reserve(a.size());
  for (Eigen::Index v = 0; v < a.size(); ++v)
    if (region.empty() || (static_cast<size_t>(v) < region.size() && region[v])) values.push_back(a(v));
  Roughness r;
  r.vertices = static_cast<int>(values.size());
  if (values.empty()) return r;
  const size_t k = static_cast<size_t>(std::ceil(0.95 * values.size())) - 1;
  std::nth_element(values.begin(), values.begin() + k, values.end());
  r.p95_deg = values[k];
  r.max_deg = *std::max_element(values.begin(), values.end());
  return r;
}

std::vector<char> trunk_and_limbs_region(const std::vector<std::string>& names, const std::vector<int>& parents,
                                         const SkinWeights& W) {
  const int nb = static_cast<int>(names.size());
  std::vector<char> excluded(nb, 0);
  for (int b = 0; b < nb; ++b) {  // parents come first
    const std::string& n = names[b];
    excluded[b] = n == "head" || n == "wrist.L" || n == "wrist.R" || n == "foot.L" || n == "foot.R" ||
                  (parents[b] >= 0 && parents[b] < b && excluded[parents[b]]);
  }
  std::vector<char> region(W.rows(), 0);
  for (int v = 0; v < W.rows(); ++v) {
    int best = -1;
    double weight = -1;
    for (SkinWeights::InnerIterator it(W, v); it; ++it)
      if (it.value() > weight) weight = it.value(), best = static_cast<int>(it.col());
    region[v] = best >= 0 && best < nb && !excluded[best];
  }
  return region;
}

int self_intersecting_triangle_pairs(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
  // One box per triangle; its info is the face index.
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int, CGAL::Box_intersection_d::ID_EXPLICIT>;
  std::vector<Box> boxes;
  boxes.reserve(F.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    double lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min({V(F(f, 0), k), V(F(f, 1), k), V(F(f, 2), k)});
      hi[k] = std::max({V(F(f, 0), k), V(F(f, 1), k), V(F(f, 2), k)});
    }
    boxes.emplace_back(lo, hi, static_cast<int>(f));
  }
  auto point = [&](int v) { return Kernel::Point_3(V(v, 0), V(v, 1), V(v, 2)); };
  int count = 0;
  auto callback = [&](const Box& a, const Box& b) {
    const int fa = a.info(), fb = b.info();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        if (F(fa, i) == F(fb, j)) return;  // neighbours: touching is not intersecting
    const Kernel::Triangle_3 ta(point(F(fa, 0)), point(F(fa, 1)), point(F(fa, 2)));
    const Kernel::Triangle_3 tb(point(F(fb, 0)), point(F(fb, 1)), point(F(fb, 2)));
    if (ta.is_degenerate() || tb.is_degenerate()) return;
    if (CGAL::do_intersect(ta, tb)) ++count;
  };
  CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), callback);
  return count;
}

}  // namespace bodymodel
