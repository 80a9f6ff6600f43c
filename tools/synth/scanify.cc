#include "tools/synth/scanify.h"

#include <Eigen/Eigenvalues>
#include <random>
#include <tbb/parallel_for.h>

#include "core/body_size.h"
#include "core/error.h"
#include "core/geometry.h"
#include "core/point_index.h"

namespace bodymodel {

unsigned scan_seed(unsigned seed, const std::string& name) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : name) h = (h ^ c) * 1099511628211ull;
  h ^= uint64_t(seed) * 0x9E3779B97F4A7C15ull;
  return unsigned(h ^ (h >> 32));
}

PointCloud scanify_mesh(const Mesh& mesh, const ScanifyOptions& o, const std::string& what) {
  if (mesh.V.rows() < 3 || mesh.F.rows() < 1)
    throw InputError(what + ": expected a triangle mesh, found " + std::to_string(mesh.V.rows()) +
                     " vertices and " + std::to_string(mesh.F.rows()) + " triangles");
  if (!mesh.V.allFinite()) throw InputError(what + ": a vertex has a NaN or infinite coordinate");
  if (mesh.F.minCoeff() < 0 || mesh.F.maxCoeff() >= mesh.V.rows())
    throw InputError(what + ": a face index is outside 0.." + std::to_string(mesh.V.rows() - 1));
  check_body_size(mesh.V, what, "--scale", o.mm_per_unit);
  if (!(o.scanner.noise_sigma_mm >= 0) || o.scanner.min_points < 100)
    throw InputError("scanify: the noise must be ≥ 0 mm and at least 100 points requested");
  std::mt19937_64 rng(o.seed);
  if (o.holes) return simulate_scan(mesh.V, mesh.F, o.scanner, rng);

  // No holes: the whole surface, uniform by area, with the scanner's noise and normal estimate.
  const SurfaceSamples s = sample_surface(mesh.V, mesh.F, o.scanner.min_points, unsigned(rng()));
  const Eigen::MatrixX3d FN = face_normals(mesh.V, mesh.F);
  const double outward = signed_volume(mesh.V, mesh.F) < 0 ? -1.0 : 1.0;
  std::normal_distribution<double> noise(0.0, o.scanner.noise_sigma_mm);
  PointCloud cloud;
  cloud.P = s.P;
  for (Eigen::Index i = 0; i < cloud.P.rows(); ++i)
    for (int k = 0; k < 3; ++k) cloud.P(i, k) += noise(rng);
  const PointIndex index(cloud.P);
  cloud.N.resize(cloud.P.rows(), 3);
  tbb::parallel_for(Eigen::Index(0), cloud.P.rows(), [&](Eigen::Index i) {
    const Eigen::Vector3d p = cloud.P.row(i).transpose();
    const auto nb = index.knn(p, o.scanner.normal_neighbours);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int j : nb) mean += cloud.P.row(j).transpose();
    mean /= double(nb.size());
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    for (int j : nb) {
      const Eigen::Vector3d d = cloud.P.row(j).transpose() - mean;
      C += d * d.transpose();
    }
    Eigen::Vector3d n = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(C).eigenvectors().col(0);
    if (n.dot(outward * FN.row(s.face(i)).transpose()) < 0) n = -n;
    cloud.N.row(i) = n.transpose();
  });
  return cloud;
}

}  // namespace bodymodel
