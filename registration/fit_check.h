// Is a registration a body fitted to a body? A plausibility check run after register_scan, so a
// scan of something that is not a body (a sphere, a chair), or landmarks that do not belong to
// the scan, gives a registration flagged as failed instead of a silently collapsed or inflated
// template. No ground truth: only the scan, the result and the template it started from.
#pragma once

#include <Eigen/Core>
#include <string>

#include "core/mesh.h"

namespace bodymodel {

struct FitCheckOptions {
  // The scan is not covered: mean distance from scan points to the registered surface (mm).
  // FAUST meshes and their scans: 1–4 mm (docs/real-registration.md); a sphere: tens of mm.
  double max_scan_to_registered_mm = 15.0;
  // The non-rigid fit had to move the posed template this far on average (mm): the pose stage
  // found no body in the scan.
  double max_mean_displacement_mm = 40.0;
  // Edges shrunk below `collapsed_edge_ratio` × their rest length (a collapsed mesh); more than
  // this fraction of all edges fails the check.
  double collapsed_edge_ratio = 0.1;
  double max_collapsed_edge_fraction = 0.01;
  int scan_samples = 20000;  // scan points measured (evenly strided)
};

struct FitCheck {
  bool plausible = true;
  std::string reason;  // why not (empty when plausible)
  double scan_to_registered_mm = 0;
  double mean_displacement_mm = 0;
  double collapsed_edge_fraction = 0;
};

// V: the registration, posed_V: the pose-fitted template it started from, rest_V: the rest
// template (edge lengths), all #V by 3 on faces F (mm); scan: the scan registered to.
FitCheck check_registration_fit(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& posed_V,
                                const Eigen::MatrixX3d& rest_V, const Eigen::MatrixX3i& F,
                                const PointCloud& scan, const FitCheckOptions& options = {});

}  // namespace bodymodel
