#include "registration/correspondence.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <mutex>

#include "core/error.h"
#include "core/geometry.h"
#include "core/point_index.h"
#include "core/statistics.h"
#include "registration/metrics.h"

namespace bodymodel {

namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using Triangle = Kernel::Triangle_3;
using Iterator = std::vector<Triangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<Kernel, Iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;

// Barycentric coordinates of the point of triangle (a, b, c) closest to p (Ericson, Real-Time
// Collision Detection §5.1.5, returning the weights instead of the point).
Eigen::Vector3d closest_barycentric(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {1 - v - w, v, w};
}


// Pooled statistics of many errors: exact count, sum and max; median and p95 from a histogram.
struct Pool {
  explicit Pool(const CorrespondenceOptions& o)
      : bin(o.histogram_bin), bins(size_t(std::ceil(o.histogram_max / o.histogram_bin)) + 1, 0) {}
  void add(const Eigen::VectorXd& e) {
    for (Eigen::Index i = 0; i < e.size(); ++i) {
      sum += e(i);
      max = std::max(max, e(i));
      bins[std::min(bins.size() - 1, size_t(e(i) / bin))]++;
    }
    count += e.size();
    ++pairs;
  }
  // The value of rank r (0-based) in sorted order, as the centre of its bin.
  double rank_value(double r) const {
    long long seen = 0;
    for (size_t k = 0; k < bins.size(); ++k) {
      seen += bins[k];
      if (double(seen) > r) return (double(k) + 0.5) * bin;
    }
    return max;
  }
  ErrorStats stats() const {
    ErrorStats s;
    s.count = count;
    s.pairs = pairs;
    if (count == 0) return s;
    s.mean = sum / double(count);
    s.max = max;
    // numpy's linear interpolation between the order statistics at floor/ceil of q (n − 1).
    auto q = [&](double p) {
      const double pos = p / 100.0 * double(count - 1);
      const double lo = rank_value(std::floor(pos)), hi = rank_value(std::ceil(pos));
      return std::min(max, lo + (pos - std::floor(pos)) * (hi - lo));
    };
    s.median = q(50);
    s.p95 = q(95);
    return s;
  }
  double bin;
  std::vector<long long> bins;
  long long count = 0;
  int pairs = 0;
  double sum = 0, max = 0;
};

}  // namespace

ErrorStats error_stats(const Eigen::VectorXd& e) {
  ErrorStats s;
  s.count = e.size();
  s.pairs = 1;
  if (e.size() == 0) return s;
  std::vector<double> v(e.data(), e.data() + e.size());
  std::sort(v.begin(), v.end());
  s.mean = e.mean();
  s.median = percentile_sorted(v, 50);
  s.p95 = percentile_sorted(v, 95);
  s.max = v.back();
  return s;
}

std::vector<SurfaceLocation> locate_on_surface(const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& V,
                                               const Eigen::MatrixX3i& F) {
  if (V.rows() == 0 || F.rows() == 0)
    throw InputError("locate on surface: the mesh has no triangles");
  if (F.minCoeff() < 0 || F.maxCoeff() >= V.rows())
    throw InputError("locate on surface: a face index is outside 0.." + std::to_string(V.rows() - 1));
  if (!V.allFinite() || !P.allFinite())
    throw InputError("locate on surface: a NaN or infinite coordinate");
  std::vector<Triangle> triangles;
  triangles.reserve(size_t(F.rows()));
  auto pt = [&](Eigen::Index f, int c) { return Point(V(F(f, c), 0), V(F(f, c), 1), V(F(f, c), 2)); };
  for (Eigen::Index f = 0; f < F.rows(); ++f) triangles.emplace_back(pt(f, 0), pt(f, 1), pt(f, 2));
  Tree tree(triangles.cbegin(), triangles.cend());
  tree.accelerate_distance_queries();
  std::vector<SurfaceLocation> out(size_t(P.rows()));
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, P.rows(), 256), [&](const auto& r) {
    for (Eigen::Index i = r.begin(); i < r.end(); ++i) {
      const auto hit = tree.closest_point_and_primitive(Point(P(i, 0), P(i, 1), P(i, 2)));
      const int f = int(hit.second - triangles.cbegin());
      const Eigen::Vector3d p = P.row(i).transpose();
      SurfaceLocation& l = out[size_t(i)];
      l.face = f;
      l.bary = closest_barycentric(p, V.row(F(f, 0)).transpose(), V.row(F(f, 1)).transpose(),
                                   V.row(F(f, 2)).transpose());
      const Eigen::Vector3d q = l.bary(0) * V.row(F(f, 0)).transpose() +
                                l.bary(1) * V.row(F(f, 1)).transpose() +
                                l.bary(2) * V.row(F(f, 2)).transpose();
      l.distance = (p - q).norm();
    }
  });
  return out;
}

std::vector<SurfaceLocation> locate_on_surface_oriented(const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& PN,
                                                        const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                                                        int neighbours) {
  std::vector<SurfaceLocation> out = locate_on_surface(P, V, F);
  if (PN.rows() != P.rows())
    throw InputError("locate on surface: " + std::to_string(PN.rows()) + " normals for " + std::to_string(P.rows()) +
                     " points");
  const Eigen::MatrixX3d FN = face_normals(V, F);
  std::vector<std::vector<int>> vf(size_t(V.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) vf[size_t(F(f, k))].push_back(int(f));
  const PointIndex index(V);
  const int k = std::max(1, std::min(neighbours, int(V.rows())));
  auto corner = [&](int f, int c) -> Eigen::Vector3d { return V.row(F(f, c)).transpose(); };
  tbb::parallel_for(Eigen::Index(0), P.rows(), [&](Eigen::Index i) {
    SurfaceLocation& l = out[size_t(i)];
    const Eigen::Vector3d n = PN.row(i).transpose();
    if (FN.row(l.face).dot(n) >= 0) return;
    const Eigen::Vector3d p = P.row(i).transpose();
    double best = std::numeric_limits<double>::infinity();
    for (int v : index.knn(p, k))
      for (int f : vf[size_t(v)]) {
        if (FN.row(f).dot(n) < 0) continue;
        const double d = point_triangle_distance(p, corner(f, 0), corner(f, 1), corner(f, 2));
        if (d < best) {
          best = d;
          l.face = f;
        }
      }
    if (!std::isfinite(best)) return;
    l.bary = closest_barycentric(p, corner(l.face, 0), corner(l.face, 1), corner(l.face, 2));
    l.distance = best;
  });
  return out;
}

Eigen::MatrixX3d carry_locations(const std::vector<SurfaceLocation>& locations,
                                 const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  Eigen::MatrixX3d Q(Eigen::Index(locations.size()), 3);
  for (size_t i = 0; i < locations.size(); ++i) {
    const SurfaceLocation& l = locations[i];
    if (l.face < 0 || l.face >= F.rows())
      throw InputError("carry locations: triangle " + std::to_string(l.face) + " outside 0.." +
                       std::to_string(F.rows() - 1));
    Q.row(Eigen::Index(i)) = l.bary(0) * V.row(F(l.face, 0)) + l.bary(1) * V.row(F(l.face, 1)) +
                             l.bary(2) * V.row(F(l.face, 2));
  }
  return Q;
}

CorrespondenceReport evaluate_correspondence(const std::vector<CorrespondenceMesh>& meshes,
                                             const Eigen::MatrixX3i& registered_F,
                                             const CorrespondenceOptions& options,
                                             const ProgressCallback& progress) {
  if (meshes.size() < 2)
    throw InputError("correspondence: need at least two registered meshes, found " +
                     std::to_string(meshes.size()));
  if (!(options.histogram_bin > 0) || !(options.histogram_max > options.histogram_bin))
    throw InputError("correspondence: the histogram bin must be positive and below its maximum");
  const Eigen::Index nt = meshes[0].truth.rows(), nr = meshes[0].registered.rows();
  for (const auto& m : meshes) {
    if (m.truth.rows() != nt || m.registered.rows() != nr)
      throw InputError("correspondence: " + m.id + " has " + std::to_string(m.truth.rows()) +
                       " truth and " + std::to_string(m.registered.rows()) +
                       " registered vertices, " + meshes[0].id + " " + std::to_string(nt) +
                       " and " + std::to_string(nr) + " (every mesh must share both topologies)");
    if (!m.truth.allFinite() || !m.registered.allFinite())
      throw InputError("correspondence: " + m.id + " has a NaN or infinite vertex");
  }
  const size_t n = meshes.size();
  CorrespondenceReport report;
  std::vector<std::vector<SurfaceLocation>> located(n);
  report.location_distance_mean.resize(n);
  for (size_t a = 0; a < n; ++a) {
    report_progress(progress, 0.5 * double(a) / double(n), "locating " + meshes[a].id);
    if (options.oriented_location && meshes[a].truth_normals.rows() != nt)
      throw InputError("correspondence: oriented location needs the truth normals of " + meshes[a].id);
    located[a] = options.oriented_location
                     ? locate_on_surface_oriented(meshes[a].truth, meshes[a].truth_normals, meshes[a].registered,
                                                  registered_F)
                     : locate_on_surface(meshes[a].truth, meshes[a].registered, registered_F);
    double s = 0;
    for (const auto& l : located[a]) s += l.distance;
    report.location_distance_mean[a] = s / double(nt);
  }
  Pool inter(options), intra(options);
  std::mutex mutex;
  report.vertex_error_mean = Eigen::MatrixXd::Zero(nt, Eigen::Index(n));
  Eigen::VectorXi pairs_of(Eigen::VectorXi::Zero(Eigen::Index(n)));
  for (size_t a = 0; a < n; ++a) {
    report_progress(progress, 0.5 + 0.5 * double(a) / double(n), "pairs from " + meshes[a].id);
    std::vector<size_t> partners;
    for (size_t b = 0; b < n; ++b) {
      if (b == a) continue;
      const bool is_inter = meshes[a].subject != meshes[b].subject;
      if ((options.pairs == PairSelection::inter && !is_inter) ||
          (options.pairs == PairSelection::intra && is_inter))
        continue;
      partners.push_back(b);
    }
    std::vector<PairError> rows(partners.size());
    tbb::parallel_for(size_t(0), partners.size(), [&](size_t k) {
      const size_t b = partners[k];
      const Eigen::MatrixX3d Q = carry_locations(located[a], meshes[b].registered, registered_F);
      const Eigen::VectorXd e = (Q - meshes[b].truth).rowwise().norm();
      PairError& row = rows[k];
      row.a = int(a);
      row.b = int(b);
      row.inter = meshes[a].subject != meshes[b].subject;
      row.stats = error_stats(e);
      std::lock_guard<std::mutex> lock(mutex);
      (row.inter ? inter : intra).add(e);
      report.vertex_error_mean.col(Eigen::Index(a)) += e;
      report.vertex_error_mean.col(Eigen::Index(b)) += e;
      ++pairs_of(Eigen::Index(a)), ++pairs_of(Eigen::Index(b));
    });
    for (auto& r : rows) report.pairs.push_back(std::move(r));
  }
  for (size_t m = 0; m < n; ++m)
    if (pairs_of(Eigen::Index(m)) > 0) report.vertex_error_mean.col(Eigen::Index(m)) /= double(pairs_of(Eigen::Index(m)));
  report.inter = inter.stats();
  report.intra = intra.stats();
  report_progress(progress, 1.0, "done");
  return report;
}

}  // namespace bodymodel
