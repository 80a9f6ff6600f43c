// Error metrics of a skinned result against a reference mesh (Jacka et al. 2007 §3.2 after
// PolyMeCo; definitions in docs/evaluation.md#meshes-against-a-reference):
//   geometric deviation g_i  distance from result vertex x_i to the closest point of the reference
//                            *surface* (triangles; CGAL AABB tree), ≤ the vertex error
//   normal deviation         angle (degrees) between the area-weighted vertex normals of X and Y
//   vertex error e_i         ‖x_i − y_i‖ (same vertex index)
//   E_RMS (Kavan et al. 2010) 1000 · ‖X − Y‖_F / (√(3·n·f) · d), d = reference bbox diagonal
#pragma once

#include <Eigen/Core>
#include <memory>

namespace bodymodel {

// Closest-point queries on a fixed triangle mesh. Thread-safe queries; the queries run in parallel.
class ReferenceSurface {
 public:
  // V #V by 3, F #F by 3 (0-based). Throws InputError for an empty mesh or bad indices.
  ReferenceSurface(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F);
  ~ReferenceSurface();
  ReferenceSurface(ReferenceSurface&&) noexcept;
  ReferenceSurface& operator=(ReferenceSurface&&) noexcept;
  // Unsigned distance from each row of X (#X by 3) to the surface.         returns #X
  Eigen::VectorXd distances(const Eigen::MatrixX3d& X) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Per-vertex errors of a result X against a reference Y (same vertex order and faces F).
struct MeshDeviation {
  Eigen::VectorXd geometric;    // #V distance to the reference surface (data units)
  Eigen::VectorXd normal_deg;   // #V degrees in [0, 180]
  Eigen::VectorXd vertex;       // #V ‖x_i − y_i‖ (data units)
};

// `surface` may be passed to reuse the reference's tree; nullptr builds one.
MeshDeviation mesh_deviation(const Eigen::MatrixX3d& X, const Eigen::MatrixX3d& Y,
                             const Eigen::MatrixX3i& F, const ReferenceSurface* surface = nullptr);

// Accumulates MeshDeviations over frames: means are over all vertices of all frames.
struct DeviationStats {
  long long count = 0;          // vertices × frames accumulated
  long long frames = 0;
  double sum_geometric = 0, max_geometric = 0;
  double sum_normal = 0, max_normal = 0;
  double sum_vertex = 0, sum_vertex_sq = 0, max_vertex = 0;

  void add(const MeshDeviation& d);
  void merge(const DeviationStats& other);  // as if other's frames had been added here
  double mean_geometric() const { return count ? sum_geometric / count : 0; }
  double mean_normal_deg() const { return count ? sum_normal / count : 0; }
  double mean_vertex() const { return count ? sum_vertex / count : 0; }
  double rms_vertex() const;                            // √(mean e_i²)
  double e_rms(double diagonal) const;                  // Kavan et al. E_RMS with diagonal d
};

}  // namespace bodymodel
