// Data sets whose bodies stand along another axis than +y (SCAPE: +x): the rotation that turns
// a named axis onto +y, so the tools can bring such meshes into the project's frame
// (millimetres, +y up) and evaluation can bring the truths into the same frame.
#pragma once

#include <Eigen/Core>
#include <string>

#include "core/error.h"

namespace bodymodel {

// The rotation R with R · axis = +y for axis "y", "+y", "-y", "x", "+x", "-x", "z", "+z", "-z":
// a quarter turn about z for ±x (x → y keeps z), about x for ±z (z → y keeps x), a half turn
// about z for −y, the identity for +y. Throws InputError naming `what` for anything else.
inline Eigen::Matrix3d up_axis_rotation(std::string axis, const std::string& what = "--up") {
  if (!axis.empty() && axis[0] == '+') axis.erase(0, 1);
  Eigen::Matrix3d R;
  if (axis == "y")
    R.setIdentity();
  else if (axis == "-y")
    R << -1, 0, 0, 0, -1, 0, 0, 0, 1;
  else if (axis == "x")
    R << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  else if (axis == "-x")
    R << 0, 1, 0, -1, 0, 0, 0, 0, 1;
  else if (axis == "z")
    R << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  else if (axis == "-z")
    R << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  else
    throw InputError(what + " must be one of x, y, z, -x, -y, -z (the axis the body stands "
                     "along), got '" + axis + "'");
  return R;
}

// V (#V by 3) in the data set's unit and axes → millimetres, +y up: scale · V · Rᵀ.
inline Eigen::MatrixX3d to_project_frame(const Eigen::MatrixX3d& V, double mm_per_unit,
                                         const Eigen::Matrix3d& up_rotation) {
  return mm_per_unit * V * up_rotation.transpose();
}

}  // namespace bodymodel
