// A cheap first-order preview of morphed bodies, for interactive use (`bodymodel serve` draws
// it while a slider is dragged and decodes exactly when the slider is released).
//
// APPROXIMATION: decoding is nonlinear in the encoding (rotations), so the preview replaces it
// by its secant expansion around the start x0:
//     V(x0 + basis·z) ≈ V(x0) + Σ_k J_k z_k,   J_k = (V(x0 + σ_k b_k) − V(x0 − σ_k b_k)) / 2σ_k
// with σ_k the component's standard deviation (a secant over ±1σ fits the typical request
// better than the tangent). Building it costs 2·K decodes once; a preview then costs one
// 3#V by K product (milliseconds, far below a decode: docs/viewer.md#measured). How far it lies from the exact
// decode is measured by bench/serve_roundtrip.py and bounded in the serve test (docs/viewer.md).
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <vector>

#include "model/morph.h"

namespace bodymodel {

class ShapePreview {
 public:
  // Decodes 2·K bodies through `morpher`; gives up (returns with ready() false) as soon as
  // *stop becomes true, checked between decodes.
  ShapePreview(const ShapeMorpher& morpher, const Eigen::VectorXd& x0, const std::atomic<bool>* stop = nullptr);

  bool ready() const { return ready_; }
  // ≈ morpher.decode(x0 + basis·z) (z: K coefficients).
  Eigen::MatrixX3d operator()(const Eigen::VectorXd& z) const;
  // The coefficient change morph_encoding makes on its first iteration (the regression's
  // prediction of the start's values, eq. 11 towards the targets; no decode) for exact
  // conditions with default MorphOptions; c0 = the start's coefficients. Throws InputError for
  // range or keep conditions (they need a measured start) and unknown labels.
  static Eigen::VectorXd first_change(const SubModel& shape, const std::vector<LabelCondition>& conditions,
                                      const Eigen::VectorXd& c0);

 private:
  Eigen::MatrixX3d V0_;
  Eigen::MatrixXf J_;  // 3#V by K (x, y, z of vertex 0, then vertex 1, ...); float halves the memory
  bool ready_ = false;
};

}  // namespace bodymodel
