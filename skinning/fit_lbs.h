// Fitting linear blend skinning (SSD) weights to example poses (Jacka et al. 2007 §2.4.1,
// Sloan et al.; docs/method.md §6.2): per vertex, min Σ_p ω_p² ‖Σ_k w_k M_k(p) ṽ − q_p‖² subject to
// w ≥ 0 and Σ w = 1, solved exactly per vertex by an active-set (Lawson–Hanson) non-negative
// least-squares solve with the sum-to-one row appended with a large weight, then renormalised.
#pragma once

#include <Eigen/Core>
#include <string>

#include "core/progress.h"
#include "skinning/skinning_examples.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

struct LbsFitOptions {
  // Influence slots per vertex when no influence sets are given (chosen by choose_influences).
  int max_influences = 4;
  // Automatic influence sets: fit SSD over this many candidate bones per vertex (the best by
  // rigid residual, see choose_influences), then keep the max_influences largest weights and
  // refit. ≤ max_influences = use the rigid-residual ranking alone.
  int influence_candidates = 12;
  // Weight of the appended Σw = 1 row, relative to the RMS column norm of the vertex's system.
  // Large enough that Σw = 1 holds to ~1e-6 before renormalisation.
  double sum_to_one_weight = 1e3;
  // SSD models bones as rigid (Jacka §2): refuse non-rigid transforms unless disabled.
  bool require_rigid = true;
  double rigid_tolerance = 1e-4;
  // Normal equations from per-bone-pair pose moments (ṽᵀ G_kl ṽ); false = summed pose by pose per
  // vertex, the implementation before them (equal up to rounding), kept as the benchmark's baseline.
  bool pairwise_moments = true;
};

struct LbsFitSummary {
  int vertices = 0, poses = 0, bones = 0, max_influences = 0;
  double rms_residual = 0;   // RMS over vertices and poses of ‖fitted − example‖ (data units)
  double max_residual = 0;
  double seconds = 0;
  std::string brief() const;
};

// influences: #V by K bone indices (-1 = unused) or empty to choose them automatically.
SkinningRig fit_lbs(const SkinningExamples& ex, const Eigen::MatrixXi& influences = {},
                    const LbsFitOptions& options = {}, LbsFitSummary* summary = nullptr,
                    const ProgressCallback& progress = {});

// The SSD rig an Animation Space or MWE fit builds on: `base` after checking it is an SSD rig
// of the examples' size, or a fresh fit_lbs with up to `max_influences` influences when `base`
// is null. `who` names the caller in error messages.
SkinningRig base_lbs_rig(const SkinningExamples& ex, const SkinningRig* base, int max_influences,
                         const std::string& who);

// min ½ xᵀHx − gᵀx subject to x ≥ 0 (H symmetric positive semi-definite, small): Lawson–Hanson
// active set on the normal equations. Exposed for tests.
Eigen::VectorXd nonnegative_least_squares(const Eigen::MatrixXd& H, const Eigen::VectorXd& g);

// RMS and max of per-vertex residuals of `rig` over the examples (helper for the summaries).
void rig_residuals(const SkinningRig& rig, const SkinningExamples& ex, double* rms, double* max);

}  // namespace bodymodel
