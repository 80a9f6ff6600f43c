#include "regression/gaussian_process.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <sstream>
#include <limits>

#include "core/error.h"

namespace bodymodel {

void GaussianProcessRegressor::fit(const Eigen::MatrixXd& X, const Eigen::VectorXd& y,
                                   const std::vector<int>& groups) {
  check_regression_input(X, y, groups, 3, "gaussian_process");
  scaling_ = FeatureScaling::fit(X, y, options_.whiten);
  Z_ = scaling_.features(X);
  const Eigen::VectorXd t = scaling_.label(y);
  const Eigen::Index n = Z_.rows();
  const Eigen::MatrixXd D2 = squared_distances(Z_, Z_);
  const Eigen::MatrixXd G = Z_ * Z_.transpose();

  double best = -std::numeric_limits<double>::infinity();
  for (double l : options_.length_scale) {
    const Eigen::MatrixXd R = (-D2 / (2 * l * l)).array().exp().matrix();
    for (double a : options_.rbf_variance)
      for (double b : options_.linear_variance)
        for (double s2 : options_.noise_variance) {
          Eigen::MatrixXd K = a * R + b * G;
          K.diagonal().array() += s2;
          Eigen::LLT<Eigen::MatrixXd> llt(K);
          if (llt.info() != Eigen::Success) continue;
          const Eigen::VectorXd w = llt.solve(t);
          const double logdet = 2 * llt.matrixLLT().diagonal().array().log().sum();
          const double ll = -0.5 * t.dot(w) - 0.5 * logdet - 0.5 * n * std::log(2 * M_PI);
          if (std::isfinite(ll) && ll > best) {
            best = ll, length_ = l, a_ = a, b_ = b, noise_ = s2;
            weights_ = w;
          }
        }
  }
  if (!std::isfinite(best))
    throw NumericalError("gaussian_process: no hyper-parameter setting gave a positive-definite covariance");
  log_likelihood_ = best;
  fitted_ = true;
}

double GaussianProcessRegressor::predict(const Eigen::VectorXd& x) const {
  if (!fitted_) throw InputError("gaussian_process: predict called before fit");
  if (x.size() != Z_.cols())
    throw InputError("gaussian_process: expected " + std::to_string(Z_.cols()) + " features, found " +
                     std::to_string(x.size()));
  const Eigen::VectorXd z = scaling_.feature(x);
  const Eigen::VectorXd d2 = (Z_.rowwise() - z.transpose()).rowwise().squaredNorm();
  const Eigen::VectorXd k =
      a_ * (-d2 / (2 * length_ * length_)).array().exp().matrix() + b_ * (Z_ * z);
  return scaling_.y_mean + scaling_.y_scale * k.dot(weights_);
}

Eigen::VectorXd GaussianProcessRegressor::gradient(const Eigen::VectorXd& x) const {
  if (!fitted_) throw InputError("gaussian_process: gradient called before fit");
  if (x.size() != Z_.cols())
    throw InputError("gaussian_process: expected " + std::to_string(Z_.cols()) + " features, found " +
                     std::to_string(x.size()));
  const Eigen::VectorXd z = scaling_.feature(x);
  const Eigen::MatrixXd diff = Z_.rowwise() - z.transpose();  // z_i − z
  const Eigen::VectorXd r =
      (-diff.rowwise().squaredNorm() / (2 * length_ * length_)).array().exp().matrix();
  const Eigen::VectorXd c = (a_ / (length_ * length_)) * r.cwiseProduct(weights_);
  const Eigen::VectorXd g = diff.transpose() * c + b_ * (Z_.transpose() * weights_);
  return scaling_.y_scale * g.cwiseQuotient(scaling_.scale.transpose());
}

std::unique_ptr<Regressor> GaussianProcessRegressor::clone() const {
  return std::make_unique<GaussianProcessRegressor>(options_);
}

std::string GaussianProcessRegressor::describe() const {
  std::ostringstream s;
  s << "length=" << length_ << " rbf_var=" << a_ << " linear_var=" << b_ << " noise_var=" << noise_;
  return s.str();
}

}  // namespace bodymodel
