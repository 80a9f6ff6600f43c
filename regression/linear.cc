#include "regression/linear.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"

namespace bodymodel {

double LinearFit::predict(const Eigen::VectorXd& x) const {
  if (x.size() != gradient.size())
    throw InputError("LinearFit::predict: expected " + std::to_string(gradient.size()) +
                     " features, found " + std::to_string(x.size()));
  return offset + gradient.dot(x);
}

LinearFit fit_linear(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, double ridge) {
  if (X.rows() != y.size())
    throw InputError("fit_linear: X has " + std::to_string(X.rows()) + " rows but y has " +
                     std::to_string(y.size()) + " entries (expected one label per sample)");
  if (X.rows() == 0) throw InputError("fit_linear: no samples (expected at least one row in X)");
  if (!(ridge >= 0)) throw InputError("fit_linear: ridge must be >= 0, found " + std::to_string(ridge));
  if (!X.allFinite()) throw InputError("fit_linear: X contains NaN or infinite values");
  if (!y.allFinite()) throw InputError("fit_linear: y contains NaN or infinite values");

  const Eigen::RowVectorXd x_mean = X.colwise().mean();
  const double y_mean = y.mean();
  const Eigen::MatrixXd Xc = X.rowwise() - x_mean;
  const Eigen::VectorXd yc = y.array() - y_mean;

  LinearFit fit;
  const Eigen::Index n = Xc.rows(), d = Xc.cols();
  if (d == 0) {
    fit.gradient.resize(0);
  } else if (ridge == 0) {
    // Minimum-norm least squares; the rank is decided relative to the largest pivot.
    Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(Xc);
    const double scale = Xc.cwiseAbs().maxCoeff();
    cod.setThreshold(1e-10 * std::max<double>(1.0, static_cast<double>(std::max(n, d))));
    fit.gradient = scale > 0 ? Eigen::VectorXd(cod.solve(yc)) : Eigen::VectorXd::Zero(d);
  } else if (d <= n) {
    // Primal normal equations (XᵀX + ridge I) s = Xᵀy.
    Eigen::MatrixXd A = Xc.transpose() * Xc;
    A.diagonal().array() += ridge;
    fit.gradient = A.ldlt().solve(Xc.transpose() * yc);
  } else {
    // Dual form s = Xᵀ (XXᵀ + ridge I)⁻¹ y, cheaper when #features > #samples.
    Eigen::MatrixXd K = Xc * Xc.transpose();
    K.diagonal().array() += ridge;
    fit.gradient = Xc.transpose() * K.ldlt().solve(yc);
  }
  fit.offset = y_mean - x_mean.dot(fit.gradient);
  if (!fit.gradient.allFinite() || !std::isfinite(fit.offset))
    throw NumericalError("fit_linear: the least-squares solve produced non-finite coefficients");
  return fit;
}

}  // namespace bodymodel
