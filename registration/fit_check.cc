#include "registration/fit_check.h"

#include <cstdio>

#include "core/error.h"
#include "core/geometry.h"
#include "registration/metrics.h"

namespace bodymodel {

namespace {
template <typename... A>
std::string format(const char* f, A... a) {
  char buf[400];
  std::snprintf(buf, sizeof buf, f, a...);
  return buf;
}
}  // namespace

FitCheck check_registration_fit(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& posed_V,
                                const Eigen::MatrixX3d& rest_V, const Eigen::MatrixX3i& F,
                                const PointCloud& scan, const FitCheckOptions& o) {
  if (V.rows() != posed_V.rows() || V.rows() != rest_V.rows())
    throw InputError("fit check: the registration, its start and the rest template differ in "
                     "vertex count");
  FitCheck c;
  if (!V.allFinite()) {
    c.plausible = false;
    c.reason = "the registration has non-finite vertices";
    return c;
  }
  // Scan → registered surface, on an even stride of the scan.
  const Eigen::Index stride = std::max<Eigen::Index>(1, scan.P.rows() / std::max(1, o.scan_samples));
  Eigen::MatrixX3d P((scan.P.rows() + stride - 1) / stride, 3);
  for (Eigen::Index i = 0, k = 0; i < scan.P.rows(); i += stride) P.row(k++) = scan.P.row(i);
  c.scan_to_registered_mm = P.rows() > 0 ? point_to_mesh_distance(P, V, F).mean() : 0.0;
  c.mean_displacement_mm = (V - posed_V).rowwise().norm().mean();
  const Eigen::MatrixX2i E = unique_edges(F);
  int collapsed = 0;
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    const double rest = (rest_V.row(E(e, 0)) - rest_V.row(E(e, 1))).norm();
    const double now = (V.row(E(e, 0)) - V.row(E(e, 1))).norm();
    if (rest > 0 && now < o.collapsed_edge_ratio * rest) ++collapsed;
  }
  c.collapsed_edge_fraction = E.rows() > 0 ? double(collapsed) / double(E.rows()) : 0.0;
  if (c.scan_to_registered_mm > o.max_scan_to_registered_mm)
    c.reason = format("the registration leaves the scan %.1f mm away on average (more than "
                      "%.0f mm): is the scan a body, and are the landmarks its own?",
                           c.scan_to_registered_mm, o.max_scan_to_registered_mm);
  else if (c.mean_displacement_mm > o.max_mean_displacement_mm)
    c.reason = format("the non-rigid fit moved the posed template %.1f mm on average (more "
                      "than %.0f mm): the pose stage found no body in the scan",
                           c.mean_displacement_mm, o.max_mean_displacement_mm);
  else if (c.collapsed_edge_fraction > o.max_collapsed_edge_fraction)
    c.reason = format("%.1f %% of the template's edges collapsed below %.0f %% of their "
                      "rest length",
                           100 * c.collapsed_edge_fraction, 100 * o.collapsed_edge_ratio);
  c.plausible = c.reason.empty();
  return c;
}

}  // namespace bodymodel
