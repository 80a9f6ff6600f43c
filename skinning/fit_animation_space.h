// Fitting Animation Space (Merry et al. 2006; Jacka et al. 2007 §2.2): v' = Σ_k M_k p_k with a
// free 4-vector p_k per influence, per vertex by ridge regression over all example poses:
//   min Σ_p ω_p² ‖Σ_k M_k(p) p_k − q_p‖² + λ' Σ_k ‖p_k − p_k⁰‖²,
// where p_k⁰ = w_k ṽ is the SSD solution (the prior; zero when prior_from_lbs is off) and
// λ' = λ · tr(AᵀA) / (4n) makes λ independent of the data's scale and pose count.
#pragma once

#include <Eigen/Core>
#include <string>

#include "core/progress.h"
#include "skinning/skinning_examples.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

struct AnimationSpaceFitOptions {
  // Ridge λ (relative, see above). Jacka et al. Fig. 3(b): a flat minimum around 0.015 on the
  // horse for their parametrisation; ours: a flat minimum around 1e-4 on the horse (README).
  double ridge = 1e-4;
  // Shrink towards the SSD solution (true) or towards zero (plain ridge).
  bool prior_from_lbs = true;
  // Influences when no base rig is given: SSD fitted with this many slots.
  int max_influences = 4;
};

struct AnimationSpaceFitSummary {
  int vertices = 0, poses = 0, max_influences = 0;
  double rms_residual = 0, max_residual = 0, seconds = 0;
  std::string brief() const;
};

// base_lbs: an SSD rig fitted to the same examples (its influence sets and weights are used as
// influences and prior); nullptr = fit one here.
SkinningRig fit_animation_space(const SkinningExamples& ex, const SkinningRig* base_lbs = nullptr,
                                const AnimationSpaceFitOptions& options = {},
                                AnimationSpaceFitSummary* summary = nullptr,
                                const ProgressCallback& progress = {});

}  // namespace bodymodel
