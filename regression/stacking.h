// Stacked regression (Breiman, "Stacked regressions", Machine Learning 24:49–64, 1996): instead of
// keeping the one candidate model with the lowest cross-validated error, combine the candidates
// with non-negative weights that sum to one, chosen to minimise the squared error of the combined
// held-out predictions. Breiman's own example stacks nested subset regressions of every size, the
// filtered linear regressor's candidates (Hasler et al. 2009 §4); the combination is again linear.
// Choosing one count from a noisy cross-validation curve is a high-variance decision (synthetic
// weight, realistic label noise: the leave-one-out count, averaged over the 10 outer folds, went
// from 4 to 82 components from one noise draw to the next); stacked weights vary smoothly.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace bodymodel {

// Non-negative least squares (Lawson & Hanson 1974, ch. 23): argmin ‖A w − b‖ subject to w ≥ 0.
//   A #rows by #cols, b #rows. Returns #cols (all finite, ≥ 0).
Eigen::VectorXd lawson_hanson_nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b);

// Stacking weights from held-out residuals.
//   residuals  #rows by #candidates: held-out prediction − label of each candidate model (label
//              unit); rows with a non-finite entry (untested) are ignored
//   allowed    #candidates flags (empty = every candidate)
// Returns #candidates weights w ≥ 0, Σw = 1 (0 where not allowed) minimising ‖residuals·w‖²,
// the squared error of the combined prediction Σ w_k ŷ_k (Σw = 1 keeps the label's offset).
// Throws InputError when no row is tested or no candidate allowed.
Eigen::VectorXd stacking_weights(const Eigen::MatrixXd& residuals, const std::vector<bool>& allowed = {});

}  // namespace bodymodel
