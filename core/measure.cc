#include "core/measure.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/convex_hull_2.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <vector>

#include "core/error.h"
#include "core/geometry.h"

namespace bodymodel {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point2 = Kernel::Point_2;

inline uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<uint64_t>(static_cast<uint32_t>(a)) << 32) | static_cast<uint32_t>(b);
}

// Closed loops of the section of the mesh with the plane x[up] = h, as 2-D polygons in the two
// remaining coordinates. Open chains (non-closed meshes) are returned too.
std::vector<std::vector<Eigen::Vector2d>> section_loops(const Eigen::MatrixX3d& V,
                                                        const Eigen::MatrixX3i& F, double h,
                                                        int up) {
  const int a0 = (up + 1) % 3, a1 = (up + 2) % 3;
  // Each crossing triangle gives a segment between two edge points; link segments by edge.
  std::unordered_map<uint64_t, Eigen::Vector2d> point_of_edge;
  std::unordered_map<uint64_t, std::vector<uint64_t>> links;
  auto side = [&](int v) { return V(v, up) >= h; };
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    uint64_t ends[2];
    int n = 0;
    for (int k = 0; k < 3; ++k) {
      int i = F(f, k), j = F(f, (k + 1) % 3);
      if (side(i) == side(j)) continue;
      double t = (h - V(i, up)) / (V(j, up) - V(i, up));
      uint64_t key = edge_key(i, j);
      point_of_edge.emplace(key, Eigen::Vector2d(V(i, a0) + t * (V(j, a0) - V(i, a0)),
                                                 V(i, a1) + t * (V(j, a1) - V(i, a1))));
      if (n < 2) ends[n++] = key;
    }
    if (n == 2) {
      links[ends[0]].push_back(ends[1]);
      links[ends[1]].push_back(ends[0]);
    }
  }
  std::vector<std::vector<Eigen::Vector2d>> loops;
  std::unordered_map<uint64_t, bool> used;
  for (auto& [start, _] : links) {
    if (used[start]) continue;
    std::vector<Eigen::Vector2d> loop;
    uint64_t prev = ~0ull, cur = start;
    while (!used[cur]) {
      used[cur] = true;
      loop.push_back(point_of_edge[cur]);
      uint64_t next = ~0ull;
      for (uint64_t nb : links[cur])
        if (nb != prev && !used[nb]) { next = nb; break; }
      if (next == ~0ull) break;
      prev = cur;
      cur = next;
    }
    if (loop.size() >= 3) loops.push_back(std::move(loop));
  }
  return loops;
}

double polygon_area(const std::vector<Eigen::Vector2d>& p) {
  double a = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    const auto& u = p[i];
    const auto& w = p[(i + 1) % p.size()];
    a += u.x() * w.y() - w.x() * u.y();
  }
  return std::abs(a) / 2;
}

double hull_perimeter(const std::vector<Eigen::Vector2d>& loop) {
  std::vector<Point2> pts, hull;
  pts.reserve(loop.size());
  for (auto& p : loop) pts.emplace_back(p.x(), p.y());
  CGAL::convex_hull_2(pts.begin(), pts.end(), std::back_inserter(hull));
  double per = 0;
  for (size_t i = 0; i < hull.size(); ++i)
    per += std::sqrt(CGAL::squared_distance(hull[i], hull[(i + 1) % hull.size()]));
  return per;
}

}  // namespace

double girth_at_height(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, double h,
                       int up_axis) {
  auto loops = section_loops(V, F, h, up_axis);
  const std::vector<Eigen::Vector2d>* best = nullptr;
  double best_area = -1;
  for (auto& l : loops) {
    double a = polygon_area(l);
    if (a > best_area) { best_area = a; best = &l; }
  }
  return best ? hull_perimeter(*best) : 0.0;
}

double navy_body_fat_pct(Sex sex, double height_cm, double neck_cm, double waist_cm,
                         double hips_cm) {
  constexpr double in = 1 / 2.54;
  if (sex == Sex::male && waist_cm > neck_cm)
    return 86.010 * std::log10((waist_cm - neck_cm) * in) - 70.041 * std::log10(height_cm * in) +
           36.76;
  if (sex == Sex::female && waist_cm + hips_cm > neck_cm)
    return 163.205 * std::log10((waist_cm + hips_cm - neck_cm) * in) -
           97.684 * std::log10(height_cm * in) - 78.387;
  return std::numeric_limits<double>::quiet_NaN();
}

BodyMeasurements measure_body(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, Sex sex,
                              const MeasureOptions& o) {
  if (V.rows() == 0 || F.rows() == 0) throw InputError("measure: the mesh is empty");
  if (o.up_axis < 0 || o.up_axis > 2) throw InputError("measure: up axis must be 0, 1 or 2");
  const double to_cm = o.mm_per_unit / 10.0;
  BodyMeasurements m;
  const double lo = V.col(o.up_axis).minCoeff(), hi = V.col(o.up_axis).maxCoeff();
  const double height = hi - lo;
  m.height_cm = height * to_cm;
  double vol = signed_volume(V, F);
  if (!(vol > 0))
    throw InputError("measure: the mesh encloses no positive volume (open, or faces point inward)");
  // An open surface encloses no definite volume: the divergence-theorem sum then depends on the
  // origin, moving by t·S/3 for a shift t, S = Σ of the triangles' area vectors (0 when closed).
  // A third of a body's faces removed still summed to 36.5 of its 54.9 L: refuse a surface whose
  // holes make the volume depend on the origin by more than 1 % over a shift of its own size.
  Eigen::RowVector3d area = Eigen::RowVector3d::Zero();
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    area += 0.5 * (V.row(F(f, 1)) - V.row(F(f, 0))).cross(V.row(F(f, 2)) - V.row(F(f, 0)));
  const double size = (V.colwise().maxCoeff() - V.colwise().minCoeff()).norm();
  if (area.norm() * size / 3 > 0.01 * vol)
    throw InputError("measure: the surface is not closed (its holes make the volume uncertain by up to " +
                     std::to_string(static_cast<int>(std::ceil(100 * area.norm() * size / 3 / vol))) +
                     " %): volume, weight and girths need a watertight body");
  m.volume_l = vol * std::pow(o.mm_per_unit, 3) * 1e-6;
  m.weight_kg = m.volume_l * o.density_kg_per_l;

  // Vertical extent of every triangle, for listing each cut's candidate triangles.
  const int up = o.up_axis, n = o.slices_per_band;
  Eigen::VectorXd fmin(F.rows()), fmax(F.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const double a = V(F(f, 0), up), b = V(F(f, 1), up), c = V(F(f, 2), up);
    fmin(f) = std::min({a, b, c});
    fmax(f) = std::max({a, b, c});
  }

  // Cuts from the bottom of the band upwards. With `stop_at_jump`, the scan ends at the first
  // cut whose girth exceeds the previous one by more than 12 %: the arms joining the torso
  // loop at the armpits (A-pose), which must not count as chest.
  auto band = [&](double f0, double f1, bool maximum, double& at, bool stop_at_jump = false) {
    std::vector<double> fraction(n), h(n);
    for (int s = 0; s < n; ++s) {
      fraction[s] = f0 + (f1 - f0) * (s + 0.5) / n;
      h[s] = lo + fraction[s] * height;
    }
    // A plane section at height h only involves triangles whose extent contains h.
    std::vector<std::vector<int>> cut_faces(o.cut_band_triangles_only ? n : 0);
    if (o.cut_band_triangles_only && n > 0)
      for (Eigen::Index f = 0; f < F.rows(); ++f) {
        if (fmax(f) < h.front() || fmin(f) > h.back()) continue;
        const auto first = std::lower_bound(h.begin(), h.end(), fmin(f));
        const auto last = std::upper_bound(first, h.end(), fmax(f));
        for (auto it = first; it != last; ++it) cut_faces[it - h.begin()].push_back(static_cast<int>(f));
      }
    double best = maximum ? -1 : std::numeric_limits<double>::infinity();
    double previous = 0;
    Eigen::MatrixX3i Fc;
    for (int s = 0; s < n; ++s) {
      double g;
      if (o.cut_band_triangles_only) {
        Fc.resize(static_cast<Eigen::Index>(cut_faces[s].size()), 3);
        for (size_t k = 0; k < cut_faces[s].size(); ++k) Fc.row(static_cast<Eigen::Index>(k)) = F.row(cut_faces[s][k]);
        g = girth_at_height(V, Fc, h[s], up);
      } else {
        g = girth_at_height(V, F, h[s], up);
      }
      if (g <= 0) continue;
      if (stop_at_jump && previous > 0 && g > 1.12 * previous) break;
      previous = g;
      if (maximum ? g > best : g < best) { best = g; at = fraction[s] * height * to_cm; }
    }
    return std::isfinite(best) && best > 0 ? best * to_cm : 0.0;
  };
  m.neck_cm = band(0.80, 0.88, false, m.neck_at_cm);
  m.chest_cm = band(0.68, 0.80, true, m.chest_at_cm, true);
  m.waist_cm = band(0.55, 0.67, false, m.waist_at_cm);
  m.hips_cm = band(0.45, 0.55, true, m.hips_at_cm);
  m.body_fat_pct = navy_body_fat_pct(sex, m.height_cm, m.neck_cm, m.waist_cm, m.hips_cm);
  return m;
}

}  // namespace bodymodel
