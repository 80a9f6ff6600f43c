// The unit check of a body mesh. A mesh in metres read as millimetres (or millimetres scaled by
// 1000) is a body a thousand times too small or too large; every later figure (a fit's error, a
// generalisation, a measurement) is then meaningless, yet nothing else fails. One check, applied
// wherever a body mesh meets a model or the scanner: fit, eval-model, morph, pose, edit,
// sweep, character (--in, --judge-poses, --judge-scans), scanify, eval-correspondence and the
// Python module's Model.fit / Model.morph.
#pragma once

#include <Eigen/Core>
#include <string>

namespace bodymodel {

// A body's height (its largest bounding-box side, whichever axis it stands along), in mm.
inline constexpr double kMinBodyHeightMm = 300;   // a newborn is about 500 mm
inline constexpr double kMaxBodyHeightMm = 3000;  // the tallest people are under 2 750 mm
// The smallest bounding-box side below this fraction of the largest: flat, a line or a point.
inline constexpr double kMinBodyThicknessFraction = 0.01;

// Sides of the axis-aligned bounding box of V (#V by 3), largest first.
Eigen::Vector3d bounding_box_sides(const Eigen::MatrixX3d& V);

// Throws InputError naming `what` (e.g. "'scan.off'") when V (#V by 3, mm: after the caller's
// unit conversion) is not the size of a body: a NaN or infinite coordinate; all vertices on a
// point, a line or a plane; or a height (largest bounding-box side) outside
// kMinBodyHeightMm … kMaxBodyHeightMm. `scale_option` names the option that converted the mesh
// to mm ("--scale"; "" when the mesh must already be in mm) and `mm_per_unit` its value; the
// message then suggests the value that makes the mesh a body's size (1, 10 or 1000), if any.
// `scale_from_model`: the value was not given but taken from the model (its build --scale).
void check_body_size(const Eigen::MatrixX3d& V, const std::string& what, const std::string& scale_option = "",
                     double mm_per_unit = 1, bool scale_from_model = false);

}  // namespace bodymodel
