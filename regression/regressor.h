// One interface for every regressor of a label on PCA coefficients (Hasler et al. 2009 §4, §5.1):
// fit on plain matrices, predict, and the gradient at a point (the morph direction there).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

namespace bodymodel {

class Regressor {
 public:
  virtual ~Regressor() = default;

  // Short machine name, as written in report files ("simple_linear", "svr", ...).
  virtual std::string name() const = 0;

  // Fits the regressor.
  //   X       #samples by #features (e.g. the shape-only model's PCA coefficients)
  //   y       #samples, the label (its own unit; all finite)
  //   groups  #samples subject index of each row, or empty (= every row its own subject); inner
  //           cross-validations that pick hyper-parameters keep a subject's rows together.
  // Throws InputError on mismatched sizes, non-finite values or too few samples.
  virtual void fit(const Eigen::MatrixXd& X, const Eigen::VectorXd& y,
                   const std::vector<int>& groups = {}) = 0;

  // x #features; the predicted label (label unit). Call after fit.
  virtual double predict(const Eigen::VectorXd& x) const = 0;

  // x #features; ∂ŷ/∂x at x (#features, label unit per feature unit): the morph direction.
  virtual Eigen::VectorXd gradient(const Eigen::VectorXd& x) const = 0;

  // A fresh, unfitted regressor with the same options (for cross-validation).
  virtual std::unique_ptr<Regressor> clone() const = 0;

  // The hyper-parameters chosen by the last fit, human-readable ("kept 12 of 99 components").
  virtual std::string describe() const = 0;

  // X #samples by #features → #samples predictions.
  Eigen::VectorXd predict_rows(const Eigen::MatrixXd& X) const;
};

// The regressors the project provides, in report order:
//   simple_linear    eq. 10 on all components
//   filtered_linear  eq. 10 on the components most correlated with the label: the fits on the
//                    top m components for every m, combined by stacking on their inner
//                    leave-one-subject-out predictions (regression/stacking.h)
//   svr              ε-SVR with an RBF kernel (libsvm), C/ε/γ by inner CV
//   gaussian_process GP regression, RBF + linear kernel, hyper-parameters by marginal likelihood
std::vector<std::string> regressor_names();

// A regressor with default options by name; throws InputError listing the known names. Besides
// regressor_names(), "filtered_linear_by_s" ranks components by |s_j| of the eq. 10 fit on all
// components (the paper's wording taken literally) instead of by correlation, and
// "filtered_linear_10fold" chooses the count by inner 10-fold cross-validation and
// "filtered_linear_select" keeps the one count with the lowest leave-one-out error (no stacking),
// both for comparison.
std::unique_ptr<Regressor> make_regressor(const std::string& name);

// Checks shared by every fit: X rows == y size == groups size (when given), all finite, at least
// `min_samples` rows. `who` names the caller in the message.
void check_regression_input(const Eigen::MatrixXd& X, const Eigen::VectorXd& y,
                            const std::vector<int>& groups, int min_samples, const std::string& who);

}  // namespace bodymodel
