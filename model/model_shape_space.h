// A built model's SHAPE space as the registration's shape space (`register --model`): Hasler et
// al. register scans with their own model once it exists. The model decodes an encoding by two
// sparse solves, too slow for the shape fit's finite-difference Jacobian (one body per coefficient
// and step), so the space is APPROXIMATED around the mean body: the mean decoded once and each
// component k decoded at mean ± step·sd_k, the central differences giving a vertex offset per sd
// and the second derivative along the component (core/shape_space.h VertexShapeSpace; the cross
// terms between components are left out). Away from the mean the approximate body differs from
// the exact decode; ModelShapeSpaceSummary measures by how much at ±2 sd (figures in
// docs/real-registration.md).
#pragma once

#include <Eigen/Core>

#include "core/shape_space.h"
#include "model/body_model.h"

namespace bodymodel {

struct ModelShapeSpaceOptions {
  int components = -1;       // leading shape components kept (-1: all)
  double step_sd = 1.0;      // central-difference step, sd
  // The mean body is rigidly placed (Kabsch, all vertices) onto `frame` when given (13380 by 3,
  // e.g. MakeHuman's default body), the offsets rotated with it: a model's decodes sit where its
  // first training mesh was, the registration expects MakeHuman's frame (+y up, facing +z).
  Eigen::MatrixX3d frame;
  bool second_order = true;  // false: linear only (no curvature)
  // Measure the approximation: every kept component decoded exactly at ±error_at_sd.
  bool measure_error = false;
  double error_at_sd = 2.0;
};

struct ModelShapeSpaceSummary {
  int components = 0;
  int decodes = 0;
  // With measure_error: over the kept components and both signs, the mean and the largest vertex
  // distance (mm) between the linear body and the exact decode (rigidly aligned, as the shape fit
  // only sees the body up to its placement), and the component of the largest.
  double mean_error_mm = 0, max_error_mm = 0;
  int worst_component = -1;
  double mean_error_linear_mm = 0, max_error_linear_mm = 0;  // the same for the first order alone
  double max_displacement_mm = 0;  // the largest vertex move from the mean at ±error_at_sd (for scale)
  double seconds = 0;
};

// InputError when the model's topology is not MakeHuman's body (13380 vertices) or it has no
// shape components.
VertexShapeSpace model_shape_space(const BodyModel& model, const ModelShapeSpaceOptions& options = {},
                                   ModelShapeSpaceSummary* summary = nullptr);

}  // namespace bodymodel
