// A second non-linear regressor: Gaussian-process regression (Rasmussen & Williams 2006, §2.2,
// §5.4) with the covariance
//   k(z, z') = a·exp(−‖z − z'‖²/(2ℓ²)) + b·zᵀz' + σ_n²·δ(z, z'),
// on the scaled features of FeatureScaling and the standardised label. a, b, ℓ and σ_n are picked
// from a grid by the log marginal likelihood of the training rows (no inner cross-validation
// needed). The posterior mean and its gradient are analytic:
//   ŷ(x) = ȳ + σ_y Σ_i w_i k(z, z_i),   w = (K + σ_n² I)⁻¹ t,
//   ∇ŷ(x) = σ_y/scale · Σ_i w_i [a·exp(−‖z − z_i‖²/(2ℓ²))·(z_i − z)/ℓ² + b·z_i].
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "regression/feature_scaling.h"
#include "regression/regressor.h"

namespace bodymodel {

class GaussianProcessRegressor : public Regressor {
 public:
  struct Options {
    bool whiten = false;  // FeatureScaling: per-feature standardisation instead of one global scale
    std::vector<double> length_scale = {0.5, 1, 2, 4};        // ℓ, scaled units (‖z‖ ≈ 1)
    std::vector<double> rbf_variance = {0.1, 1};              // a, standardised label units²
    // b: prior variance of the linear part's weights; large values let small-variance components
    // carry a label (e.g. muscle tone) that an RBF on the PCA geometry barely sees.
    std::vector<double> linear_variance = {0, 1, 100, 1e4, 1e6};
    std::vector<double> noise_variance = {1e-4, 1e-3, 1e-2, 0.1, 0.3};  // σ_n², standardised
  };
  GaussianProcessRegressor() = default;
  explicit GaussianProcessRegressor(const Options& options) : options_(options) {}

  std::string name() const override { return "gaussian_process"; }
  void fit(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, const std::vector<int>& groups = {}) override;
  double predict(const Eigen::VectorXd& x) const override;
  Eigen::VectorXd gradient(const Eigen::VectorXd& x) const override;
  std::unique_ptr<Regressor> clone() const override;
  std::string describe() const override;

  double log_marginal_likelihood() const { return log_likelihood_; }

 private:
  Options options_;
  FeatureScaling scaling_;
  Eigen::MatrixXd Z_;       // #samples by #features, scaled training features
  Eigen::VectorXd weights_; // #samples, w
  double length_ = 1, a_ = 1, b_ = 0, noise_ = 0.01, log_likelihood_ = 0;
  bool fitted_ = false;
};

}  // namespace bodymodel
