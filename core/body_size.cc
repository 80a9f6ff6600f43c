#include "core/body_size.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.h"

namespace bodymodel {
namespace {

std::string number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

// The unit the mesh's own numbers look like, as the --scale that makes them a body's height.
double plausible_scale(double height_in_mesh_units) {
  for (double s : {1.0, 10.0, 1000.0}) {
    const double h = height_in_mesh_units * s;
    if (h >= kMinBodyHeightMm && h <= kMaxBodyHeightMm) return s;
  }
  return 0;
}

const char* unit_name(double scale) { return scale == 1 ? "millimetres" : scale == 10 ? "centimetres" : "metres"; }

}  // namespace

Eigen::Vector3d bounding_box_sides(const Eigen::MatrixX3d& V) {
  if (V.rows() == 0) return Eigen::Vector3d::Zero();
  Eigen::Vector3d s = (V.colwise().maxCoeff() - V.colwise().minCoeff()).transpose();
  std::sort(s.data(), s.data() + 3, [](double a, double b) { return a > b; });
  return s;
}

void check_body_size(const Eigen::MatrixX3d& V, const std::string& what, const std::string& scale_option,
                     double mm_per_unit, bool scale_from_model) {
  if (!V.allFinite()) throw InputError(what + ": a vertex has a NaN or infinite coordinate");
  const Eigen::Vector3d s = bounding_box_sides(V);
  const std::string after =
      scale_option.empty() ? ""
                           : " after " + std::string(scale_from_model ? "the model's " : "") + scale_option + " " +
                                 number(mm_per_unit);
  if (!(s(0) > 0) || s(2) < kMinBodyThicknessFraction * s(0))
    throw InputError(what + ": its vertices lie on " + (s(0) > 0 ? s(1) > 0 ? "a plane" : "a line" : "one point") +
                     " (bounding box " + number(s(0)) + " × " + number(s(1)) + " × " + number(s(2)) +
                     " mm" + after + "): not a body");
  if (s(0) >= kMinBodyHeightMm && s(0) <= kMaxBodyHeightMm) return;
  std::string msg = what + ": the body is " + number(s(0)) + " mm tall (its largest extent)" + after + "; a body is " +
                    number(kMinBodyHeightMm) + " … " + number(kMaxBodyHeightMm) + " mm";
  const double scale = mm_per_unit > 0 ? plausible_scale(s(0) / mm_per_unit) : 0;
  if (scale_option.empty())
    msg += ": the mesh must be in millimetres" +
           (scale > 0 && scale != 1 ? std::string(" (it looks like ") + unit_name(scale) + ")" : std::string());
  else if (scale > 0 && scale != mm_per_unit)
    msg += ": wrong " + scale_option + "? the mesh looks like it is in " + unit_name(scale) + ": use " + scale_option +
           " " + number(scale) + " (millimetres per mesh unit)";
  else
    msg += ": wrong " + scale_option + "? (millimetres per mesh unit: 1000 for metres, 1 for millimetres)";
  throw InputError(msg);
}

}  // namespace bodymodel
