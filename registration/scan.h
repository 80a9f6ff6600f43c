// Scan preparation for registration: validation, normal estimation, unit check.
#pragma once

#include <Eigen/Core>
#include <string>

#include "core/mesh.h"

namespace bodymodel {

struct ScanCheckOptions {
  int normal_neighbours = 12;     // k for PCA normal estimation when the scan has none
  // A scan whose bounding-box diagonal differs from the template's by more than this factor
  // (either way) is taken for a unit mismatch (e.g. metres vs millimetres).
  double max_size_ratio = 3.0;
};

struct ScanCheckReport {
  bool normals_estimated = false;  // the scan had no normals; they were estimated (unoriented)
  double size_ratio = 1.0;         // scan / template bounding-box diagonal
};

// Validates `scan` in place against a template `template_V` (#V by 3, same unit expected):
// throws InputError naming `what` if the scan has no points, non-finite coordinates or
// normals, or a size that suggests a unit mismatch (the message names the factor and suggests
// the unit flag). Normals of zero length are re-estimated; a scan without normals gets PCA
// normals (orientation unknown, so `normals_estimated` is set and the registration should
// compare normals without sign). Unit normals on return.
ScanCheckReport prepare_scan(PointCloud& scan, const Eigen::MatrixX3d& template_V,
                             const std::string& what, const ScanCheckOptions& options = {});

// PCA normals from the k nearest neighbours (unit, unoriented: sign arbitrary).   #P by 3
Eigen::MatrixX3d estimate_normals(const Eigen::MatrixX3d& P, int k);

}  // namespace bodymodel
