// Local folds left in a registration of a real body: triangles facing against their own 2-ring
// neighbourhood where the template at rest does not (registration/metrics.h
// locally_folded_triangles). The registration's own fold repair (register_scan's
// repair_flipped_triangles, register-mesh's unfold_triangles) compares with the pose-fitted
// template, which is posed by linear blend skinning and so carries its creases (armpits, groin,
// finger joints): a fold the posed template already has is not "flipped" against it and stays.
// Here "folded" needs no reference pose: each locally folded triangle is compared with its
// 2-ring's normal, and its region is re-solved with the REST template's local shape, rotated and
// scaled onto the region's border (core/fold_repair.h, Laplacian editing with a Procrustes fit).
#pragma once

#include <Eigen/Core>

#include "core/fold_repair.h"

namespace bodymodel {

struct LocalFoldRepairOptions {
  int rings = 2;         // neighbourhood of the fold test (vertex rings)
  int repair_rings = 2;  // rings grown around the folds for the first repair pass
  int passes = 6;        // repair passes (pass p grows the region by p more rings)
  int rounds = 3;        // fold tests and repairs repeated while folds remain
  // A region's solve that moves a vertex farther is refused (mm): a fold is not worth dragging
  // the surface away from the scan.
  double max_displacement = 30.0;
};

struct LocalFoldRepairSummary {
  int folded_before = 0;
  int folded_after = 0;
};

// Repairs V in place. V #V by 3 (registration), rest_V #V by 3 (the template at rest, its
// shaped body if the shape was fitted), F #F by 3.
LocalFoldRepairSummary repair_local_folds(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& rest_V,
                                          const Eigen::MatrixX3i& F,
                                          const LocalFoldRepairOptions& options = {});

}  // namespace bodymodel
