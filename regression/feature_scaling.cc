#include "regression/feature_scaling.h"

#include <algorithm>
#include <cmath>

namespace bodymodel {

FeatureScaling FeatureScaling::fit(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, bool whiten) {
  FeatureScaling s;
  s.mean = X.colwise().mean();
  const double rows = std::max<double>(1.0, static_cast<double>(X.rows()));
  if (whiten) {
    // σ_j·√#features, so the mean squared norm of a scaled row is 1 as with the global scale.
    s.scale = ((X.rowwise() - s.mean).colwise().squaredNorm() / rows).cwiseSqrt() *
              std::sqrt(static_cast<double>(X.cols()));
    for (Eigen::Index j = 0; j < s.scale.size(); ++j)
      if (!(s.scale(j) > 0)) s.scale(j) = 1.0;
  } else {
    const double ms = (X.rowwise() - s.mean).squaredNorm() / rows;
    s.scale = Eigen::RowVectorXd::Constant(X.cols(), ms > 0 ? std::sqrt(ms) : 1.0);
  }
  s.y_mean = y.size() ? y.mean() : 0.0;
  const double vy = y.size() ? (y.array() - s.y_mean).square().mean() : 0.0;
  s.y_scale = vy > 0 ? std::sqrt(vy) : 1.0;
  return s;
}

Eigen::MatrixXd FeatureScaling::features(const Eigen::MatrixXd& X) const {
  return (X.rowwise() - mean).array().rowwise() / scale.array();
}

Eigen::VectorXd FeatureScaling::feature(const Eigen::VectorXd& x) const {
  return (x - mean.transpose()).cwiseQuotient(scale.transpose());
}

Eigen::VectorXd FeatureScaling::label(const Eigen::VectorXd& y) const {
  return (y.array() - y_mean) / y_scale;
}

Eigen::MatrixXd squared_distances(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) {
  Eigen::MatrixXd D = -2.0 * A * B.transpose();
  D.colwise() += A.rowwise().squaredNorm();
  D.rowwise() += B.rowwise().squaredNorm().transpose();
  return D.cwiseMax(0.0);
}

}  // namespace bodymodel
