#include "registration/scan.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/geometry.h"
#include "core/point_index.h"

namespace bodymodel {

Eigen::MatrixX3d estimate_normals(const Eigen::MatrixX3d& P, int k) {
  Eigen::MatrixX3d N = Eigen::MatrixX3d::Zero(P.rows(), 3);
  if (P.rows() < 3) return N;
  PointIndex index(P);
  tbb::parallel_for(Eigen::Index(0), P.rows(), [&](Eigen::Index i) {
    std::vector<int> nb = index.knn(P.row(i).transpose(), k);
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int j : nb) c += P.row(j).transpose();
    c /= double(nb.size());
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    for (int j : nb) {
      Eigen::Vector3d d = P.row(j).transpose() - c;
      C += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
    N.row(i) = es.eigenvectors().col(0).transpose();
  });
  return N;
}

ScanCheckReport prepare_scan(PointCloud& scan, const Eigen::MatrixX3d& template_V,
                             const std::string& what, const ScanCheckOptions& options) {
  ScanCheckReport report;
  if (scan.P.rows() == 0)
    throw InputError(what + ": expected a point cloud, found no points");
  if (scan.P.rows() < 100)
    throw InputError(what + ": expected a scan of at least 100 points, found " +
                     std::to_string(scan.P.rows()));
  for (Eigen::Index i = 0; i < scan.P.rows(); ++i)
    if (!scan.P.row(i).allFinite())
      throw InputError(what + ": point " + std::to_string(i) +
                       " has a non-finite coordinate (NaN or infinity); remove it from the scan");
  if (scan.N.rows() != 0 && scan.N.rows() != scan.P.rows())
    throw InputError(what + ": " + std::to_string(scan.P.rows()) + " points but " +
                     std::to_string(scan.N.rows()) + " normals");
  if (!scan.has_normals()) {
    scan.N = estimate_normals(scan.P, options.normal_neighbours);
    report.normals_estimated = true;
  } else {
    for (Eigen::Index i = 0; i < scan.N.rows(); ++i) {
      if (!scan.N.row(i).allFinite())
        throw InputError(what + ": normal " + std::to_string(i) + " is not finite");
    }
    Eigen::VectorXd len = scan.N.rowwise().norm();
    bool any_zero = (len.array() < 1e-12).any();
    if (any_zero) {
      Eigen::MatrixX3d est = estimate_normals(scan.P, options.normal_neighbours);
      for (Eigen::Index i = 0; i < len.size(); ++i)
        if (len(i) < 1e-12) scan.N.row(i) = est.row(i), len(i) = 1.0;
    }
    for (Eigen::Index i = 0; i < len.size(); ++i) scan.N.row(i) /= len(i);
  }
  const double ds = bounding_box_diagonal(scan.P), dt = bounding_box_diagonal(template_V);
  report.size_ratio = dt > 0 ? ds / dt : 1.0;
  if (!(report.size_ratio <= options.max_size_ratio &&
        report.size_ratio >= 1.0 / options.max_size_ratio)) {
    throw InputError(what + ": the scan's size (bounding-box diagonal " + std::to_string(ds) +
                     ") is " + std::to_string(report.size_ratio) +
                     " times the template's (" + std::to_string(dt) +
                     "); the units probably differ — pass the scan unit (e.g. --scan-unit m "
                     "for metres) so both are in millimetres");
  }
  return report;
}

}  // namespace bodymodel
