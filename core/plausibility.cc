#include "core/plausibility.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Box_intersection_d/Box_with_info_d.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>

#include <algorithm>
#include <array>
#include <limits>
#include <atomic>
#include <cmath>

#include "core/geometry.h"

namespace bodymodel {

namespace {

// vertex_roughness_deg with the one-ring neighbours given as the mesh's unique edges E.
Eigen::VectorXd roughness_over_edges(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const Eigen::MatrixX2i& E) {
  const Eigen::MatrixX3d N = vertex_normals(V, F);
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

}  // namespace

Eigen::VectorXd vertex_roughness_deg(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  return roughness_over_edges(V, F, unique_edges(F));  // one-ring neighbours through the edges
}

Roughness roughness(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const std::vector<char>& region) {
  return roughness(V, F, region, unique_edges(F));
}

Roughness roughness(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const std::vector<char>& region,
                    const Eigen::MatrixX2i& edges) {
  const Eigen::VectorXd a = roughness_over_edges(V, F, edges);
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

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;

// The narrow phase: triangles fa and fb (boxes overlapping) share no vertex, are not degenerate
// and intersect (CGAL's exact predicate).
bool triangles_cross(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, int fa, int fb) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (F(fa, i) == F(fb, j)) return false;  // neighbours: touching is not intersecting
  auto point = [&](int v) { return Kernel::Point_3(V(v, 0), V(v, 1), V(v, 2)); };
  const Kernel::Triangle_3 ta(point(F(fa, 0)), point(F(fa, 1)), point(F(fa, 2)));
  const Kernel::Triangle_3 tb(point(F(fb, 0)), point(F(fb, 1)), point(F(fb, 2)));
  if (ta.is_degenerate() || tb.is_degenerate()) return false;
  return CGAL::do_intersect(ta, tb);
}

}  // namespace

namespace {

template <class Found>
void for_each_box_d_pair(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, std::ptrdiff_t cutoff, Found&& found) {
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
  auto callback = [&](const Box& a, const Box& b) {
    if (triangles_cross(V, F, a.info(), b.info())) found(a.info(), b.info());
  };
  // cutoff: below this many boxes the segment tree stops recursing and scans. CGAL's default
  // (10) recurses far too deep for a body's ~27 000 small boxes; 2000 (the default here) is the
  // value of CGAL's own Polygon_mesh_processing::self_intersections.
  CGAL::box_self_intersection_d<CGAL::Sequential_tag>(boxes.begin(), boxes.end(), callback, cutoff);
}

}  // namespace

int self_intersecting_triangle_pairs_box_d(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, std::ptrdiff_t cutoff) {
  int count = 0;
  for_each_box_d_pair(V, F, cutoff, [&](int, int) { ++count; });
  return count;
}

namespace {

// Calls found(fa, fb) for every intersecting pair (fa < fb in grid order, each pair once); false
// when the grid is unsuitable (non-finite or degenerate extent, a triangle soup): the caller then
// uses the box intersection instead.
template <class Found>
bool grid_intersecting_pairs(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, Found&& found) {
  // Broad phase: a uniform grid of cells about twice a triangle's mean box extent; every pair of
  // triangles whose (closed) boxes overlap shares the cell of its overlap's lowest corner and is
  // tested there, once. The same pairs as CGAL's box_self_intersection_d (the narrow phase is
  // the same), in less CPU on population bodies (bench/plausibility_bench.cc; docs/population.md).
  const int nf = static_cast<int>(F.rows());
  if (nf < 2) return true;
  if (!V.allFinite()) return false;
  std::vector<std::array<double, 6>> box(nf);
  double extent = 0;
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      box[f][k] = std::min({V(F(f, 0), k), V(F(f, 1), k), V(F(f, 2), k)});
      box[f][3 + k] = std::max({V(F(f, 0), k), V(F(f, 1), k), V(F(f, 2), k)});
      extent += box[f][3 + k] - box[f][k];
    }
  Eigen::RowVector3d lo = Eigen::RowVector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::RowVector3d hi = -lo;
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) lo(k) = std::min(lo(k), box[f][k]), hi(k) = std::max(hi(k), box[f][3 + k]);
  double h = 2.0 * extent / (3.0 * nf);
  // At most 256 cells a side and 2²² cells (also when the triangles are degenerate: h = 0).
  const Eigen::RowVector3d size = hi - lo;
  h = std::max({h, size.maxCoeff() / 256.0, std::cbrt(size.prod() / (1 << 22))});
  if (!(h > 0)) return false;
  int dim[3];
  for (int k = 0; k < 3; ++k) dim[k] = std::max(1, std::min(256, static_cast<int>((hi(k) - lo(k)) / h) + 1));
  auto cell = [&](double x, int k) { return std::clamp(static_cast<int>((x - lo(k)) / h), 0, dim[k] - 1); };
  const long long cells = static_cast<long long>(dim[0]) * dim[1] * dim[2];
  auto for_each_cell = [&](int f, auto&& fn) {
    int a[3], b[3];
    for (int k = 0; k < 3; ++k) a[k] = cell(box[f][k], k), b[k] = cell(box[f][3 + k], k);
    for (int x = a[0]; x <= b[0]; ++x)
      for (int y = a[1]; y <= b[1]; ++y)
        for (int z = a[2]; z <= b[2]; ++z) fn((static_cast<long long>(x) * dim[1] + y) * dim[2] + z);
  };
  // Triangles per cell (counting sort).
  std::vector<long long> first(cells + 1, 0);
  for (int f = 0; f < nf; ++f) for_each_cell(f, [&](long long c) { ++first[c + 1]; });
  for (long long c = 0; c < cells; ++c) first[c + 1] += first[c];
  // Triangles far larger than the cells (a soup, not a surface): the box intersection instead.
  if (first[cells] > 64LL * nf) return false;
  std::vector<int> items(first[cells]);
  {
    std::vector<long long> fill(first.begin(), first.end() - 1);
    for (int f = 0; f < nf; ++f) for_each_cell(f, [&](long long c) { items[fill[c]++] = f; });
  }
  for (int x = 0; x < dim[0]; ++x)
    for (int y = 0; y < dim[1]; ++y)
      for (int z = 0; z < dim[2]; ++z) {
        const long long c = (static_cast<long long>(x) * dim[1] + y) * dim[2] + z;
        for (long long i = first[c]; i < first[c + 1]; ++i)
          for (long long j = i + 1; j < first[c + 1]; ++j) {
            const auto& A = box[items[i]];
            const auto& B = box[items[j]];
            bool overlap = true;
            for (int k = 0; k < 3 && overlap; ++k) overlap = A[k] <= B[3 + k] && B[k] <= A[3 + k];
            if (!overlap || cell(std::max(A[0], B[0]), 0) != x || cell(std::max(A[1], B[1]), 1) != y ||
                cell(std::max(A[2], B[2]), 2) != z)
              continue;
            if (triangles_cross(V, F, items[i], items[j])) found(items[i], items[j]);
          }
      }
  return true;
}

}  // namespace

int self_intersecting_triangle_pairs(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  int count = 0;
  if (!grid_intersecting_pairs(V, F, [&](int, int) { ++count; })) return self_intersecting_triangle_pairs_box_d(V, F);
  return count;
}

std::vector<std::pair<int, int>> self_intersecting_triangle_pair_list(const Eigen::MatrixX3d& V,
                                                                      const Eigen::MatrixX3i& F) {
  std::vector<std::pair<int, int>> pairs;
  if (!grid_intersecting_pairs(V, F, [&](int a, int b) { pairs.emplace_back(std::min(a, b), std::max(a, b)); })) {
    pairs.clear();
    for_each_box_d_pair(V, F, 2000, [&](int a, int b) { pairs.emplace_back(std::min(a, b), std::max(a, b)); });
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

}  // namespace bodymodel
