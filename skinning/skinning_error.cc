#include "skinning/skinning_error.h"

#include <algorithm>
#include <cmath>
#include <list>
#include <vector>

#include <Eigen/Geometry>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/geometry.h"

namespace bodymodel {
namespace {
using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using Triangle = Kernel::Triangle_3;
using Iterator = std::vector<Triangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<Kernel, Iterator>;
using Traits = CGAL::AABB_traits<Kernel, Primitive>;
using Tree = CGAL::AABB_tree<Traits>;
}  // namespace

struct ReferenceSurface::Impl {
  std::vector<Triangle> triangles;
  Tree tree;
};

ReferenceSurface::ReferenceSurface(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F)
    : impl_(std::make_unique<Impl>()) {
  if (F.rows() == 0 || V.rows() == 0)
    throw InputError("reference surface: the mesh has no triangles");
  if (F.minCoeff() < 0 || F.maxCoeff() >= V.rows())
    throw InputError("reference surface: a face index is outside 0.." + std::to_string(V.rows() - 1));
  if (!V.allFinite()) throw InputError("reference surface: the mesh contains NaN positions");
  impl_->triangles.reserve(static_cast<size_t>(F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    auto p = [&](int c) { return Point(V(F(f, c), 0), V(F(f, c), 1), V(F(f, c), 2)); };
    impl_->triangles.emplace_back(p(0), p(1), p(2));
  }
  impl_->tree.insert(impl_->triangles.cbegin(), impl_->triangles.cend());
  impl_->tree.build();
  impl_->tree.accelerate_distance_queries();
}

ReferenceSurface::~ReferenceSurface() = default;
ReferenceSurface::ReferenceSurface(ReferenceSurface&&) noexcept = default;
ReferenceSurface& ReferenceSurface::operator=(ReferenceSurface&&) noexcept = default;

Eigen::VectorXd ReferenceSurface::distances(const Eigen::MatrixX3d& X) const {
  Eigen::VectorXd d(X.rows());
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, X.rows(), 256), [&](const auto& r) {
    for (Eigen::Index i = r.begin(); i < r.end(); ++i) {
      if (!X.row(i).allFinite()) {
        d(i) = std::numeric_limits<double>::infinity();
        continue;
      }
      d(i) = std::sqrt(impl_->tree.squared_distance(Point(X(i, 0), X(i, 1), X(i, 2))));
    }
  });
  return d;
}

MeshDeviation mesh_deviation(const Eigen::MatrixX3d& X, const Eigen::MatrixX3d& Y,
                             const Eigen::MatrixX3i& F, const ReferenceSurface* surface) {
  if (X.rows() != Y.rows())
    throw InputError("mesh deviation: the result has " + std::to_string(X.rows()) +
                     " vertices, the reference " + std::to_string(Y.rows()));
  std::unique_ptr<ReferenceSurface> own;
  if (!surface) {
    own = std::make_unique<ReferenceSurface>(Y, F);
    surface = own.get();
  }
  MeshDeviation d;
  d.geometric = surface->distances(X);
  d.vertex = (X - Y).rowwise().norm();
  const Eigen::MatrixX3d NX = vertex_normals(X, F), NY = vertex_normals(Y, F);
  d.normal_deg.resize(X.rows());
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    // atan2 of |a×b| and a·b: accurate at small and large angles; zero normals give 0.
    const Eigen::Vector3d a = NX.row(i), b = NY.row(i);
    d.normal_deg(i) = std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
  }
  return d;
}

void DeviationStats::merge(const DeviationStats& b) {
  count += b.count;
  frames += b.frames;
  sum_geometric += b.sum_geometric;
  max_geometric = std::max(max_geometric, b.max_geometric);
  sum_normal += b.sum_normal;
  max_normal = std::max(max_normal, b.max_normal);
  sum_vertex += b.sum_vertex;
  sum_vertex_sq += b.sum_vertex_sq;
  max_vertex = std::max(max_vertex, b.max_vertex);
}

void DeviationStats::add(const MeshDeviation& d) {
  count += d.geometric.size();
  ++frames;
  sum_geometric += d.geometric.sum();
  max_geometric = std::max(max_geometric, d.geometric.maxCoeff());
  sum_normal += d.normal_deg.sum();
  max_normal = std::max(max_normal, d.normal_deg.maxCoeff());
  sum_vertex += d.vertex.sum();
  sum_vertex_sq += d.vertex.squaredNorm();
  max_vertex = std::max(max_vertex, d.vertex.maxCoeff());
}

double DeviationStats::rms_vertex() const { return count ? std::sqrt(sum_vertex_sq / count) : 0; }

double DeviationStats::e_rms(double diagonal) const {
  // ‖X − Y‖_F over all frames = √(Σ e_i²); n·f = count.
  return count ? 1000.0 * std::sqrt(sum_vertex_sq) / (std::sqrt(3.0 * count) * diagonal) : 0;
}

}  // namespace bodymodel
