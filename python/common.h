// Helpers shared by the binding files: numpy ↔ Eigen with explicit shape/finiteness checks (a bad
// array raises bodymodel.InputError naming the argument, never a crash or a silent copy error),
// and progress callbacks that may be called from worker threads while the GIL is released.
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Core>
#include <memory>
#include <string>

#include "core/progress.h"
#include "core/skeleton.h"

namespace bodymodel::py {

namespace pyb = pybind11;
using DoubleArray = pyb::array_t<double, pyb::array::c_style | pyb::array::forcecast>;

// (n, 3) float64 array (any real dtype converts; NaN/inf, other shapes and non-numbers raise).
Eigen::MatrixX3d vertices(const pyb::handle& a, const std::string& what, bool allow_empty = false);
// (m, 3) triangle indices; integer dtypes only (a float array raises: indices must not be
// rounded silently), each in [0, vertex_count) when vertex_count >= 0.
Eigen::MatrixX3i faces(const pyb::handle& a, const std::string& what, long vertex_count = -1);
// Any 2-D / 1-D finite float64 array.
Eigen::MatrixXd matrix(const pyb::handle& a, const std::string& what, bool allow_nan = false);
Eigen::VectorXd vector(const pyb::handle& a, const std::string& what, bool allow_nan = false);
// Bone maps: (B, 3, 4) or (B, 4, 4) (last row 0 0 0 1) → B affine maps.
BoneTransforms bone_transforms(const pyb::handle& a, const std::string& what);
pyb::array_t<double> bone_transforms_array(const BoneTransforms& M);  // (B, 3, 4)

// numpy outputs (copies: the result owns its memory).
pyb::array_t<double> to_array(const Eigen::MatrixXd& M);
pyb::array_t<double> to_array(const Eigen::VectorXd& v);
pyb::array_t<int32_t> to_array(const Eigen::MatrixXi& M);

// A Python callable progress(fraction, what) -> None/bool as a ProgressCallback: it takes the GIL
// for each call (so it works from TBB workers while the calling thread has released the GIL),
// checks for Ctrl-C, and a False return stops the work (bodymodel.Cancelled).
ProgressCallback progress_callback(const pyb::object& cb);

void bind_model(pyb::module_& m);
void bind_skinning(pyb::module_& m);
void bind_regression(pyb::module_& m);
void bind_registration(pyb::module_& m);
void bind_markers(pyb::module_& m);

}  // namespace bodymodel::py
