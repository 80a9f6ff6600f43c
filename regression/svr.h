// Non-linear regressor of Hasler et al. 2009 §4 / Table 1: ε-support vector regression with an RBF
// kernel (libsvm), C, ε and γ chosen by an inner grouped cross-validation on the training rows.
// Prediction and gradient are evaluated from the support-vector expansion
//   ŷ(x) = ȳ + σ_y (Σ_i α_i exp(−γ‖z − z_i‖²) − ρ),  z = (x − x̄)/scale,
//   ∇ŷ(x) = σ_y/scale · Σ_i α_i exp(−γ‖z − z_i‖²) · (−2γ)(z − z_i).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "regression/feature_scaling.h"
#include "regression/regressor.h"

namespace bodymodel {

class SvrRegressor : public Regressor {
 public:
  struct Options {
    bool whiten = false;  // FeatureScaling: per-feature standardisation instead of one global scale
    // Grids in scaled units: labels are standardised (unit variance), features divided by their
    // RMS distance to the mean (so ‖z − z'‖² ≈ 2 on average). Small γ with large C approaches a
    // linear fit, so the grid spans linear-like to clearly non-linear models.
    std::vector<double> C = {3, 30, 300, 3000};
    std::vector<double> epsilon = {0.02, 0.1};
    std::vector<double> gamma = {0.01, 0.03, 0.1, 0.3};
    int inner_folds = 5;
    unsigned inner_seed = 7;
    double tolerance = 1e-3;  // libsvm stopping tolerance
  };
  SvrRegressor() = default;
  explicit SvrRegressor(const Options& options) : options_(options) {}

  std::string name() const override { return "svr"; }
  void fit(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, const std::vector<int>& groups = {}) override;
  double predict(const Eigen::VectorXd& x) const override;
  Eigen::VectorXd gradient(const Eigen::VectorXd& x) const override;
  std::unique_ptr<Regressor> clone() const override;
  std::string describe() const override;

  // libsvm's own svm_predict on the model of the last fit (label unit): an independent path for
  // checking predict().
  double predict_with_libsvm(const Eigen::VectorXd& x) const;

  double chosen_C() const { return C_; }
  double chosen_epsilon() const { return epsilon_; }
  double chosen_gamma() const { return gamma_; }
  int support_vectors() const { return static_cast<int>(coef_.size()); }

  struct LibsvmModel;  // owns the svm_model and the training nodes it points into

 private:
  Options options_;
  FeatureScaling scaling_;
  double C_ = 0, epsilon_ = 0, gamma_ = 0, rho_ = 0;
  Eigen::MatrixXd sv_;     // #SV by #features, scaled units
  Eigen::VectorXd coef_;   // #SV
  std::shared_ptr<LibsvmModel> model_;
};

}  // namespace bodymodel
