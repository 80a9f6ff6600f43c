// Linear regression of a label on PCA coefficients: eq. 10 of Hasler et al. 2009 (§4),
//   [o s] = argmin ‖[1 | X][o; s] − y‖,
// where o is the offset and s the gradient (morph direction in coefficient space).
#pragma once

#include <Eigen/Core>

namespace bodymodel {

// A fitted affine function y ≈ offset + gradient·x.
struct LinearFit {
  double offset = 0;         // o, in the label's unit
  Eigen::VectorXd gradient;  // s, #features, label unit per feature unit
  // x #features; returns offset + gradient·x.
  double predict(const Eigen::VectorXd& x) const;
};

// Eq. 10: least-squares affine fit of y on the rows of X.
//   X      #samples by #features (e.g. PCA coefficients of each subject)
//   y      #samples (the label, any unit)
//   ridge  ≥ 0 adds ridge·‖s‖² to the objective (the offset is never penalised). 0 = plain least
//          squares; when under-determined (#samples − 1 < #features) the minimum-norm s is returned.
// The fit is computed on centred data (o = ȳ − x̄·s), so it is invariant to shifts of X.
// Throws InputError on mismatched sizes, no samples, non-finite values or negative ridge.
LinearFit fit_linear(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, double ridge = 0);

}  // namespace bodymodel
