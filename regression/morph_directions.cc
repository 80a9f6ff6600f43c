#include "regression/morph_directions.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace bodymodel {

Eigen::MatrixXd morph_directions(const Regressor& fitted, const Eigen::MatrixXd& X) {
  Eigen::MatrixXd G(X.rows(), X.cols());
  for (Eigen::Index i = 0; i < X.rows(); ++i) G.row(i) = fitted.gradient(X.row(i).transpose()).transpose();
  return G;
}

MorphDirectionSpread morph_direction_spread(const Eigen::MatrixXd& G) {
  MorphDirectionSpread s;
  const Eigen::VectorXd norms = G.rowwise().norm();
  const double tiny = 1e-300;
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(G.cols());
  for (Eigen::Index i = 0; i < G.rows(); ++i) {
    if (norms(i) <= tiny) {
      ++s.zero_gradients;
      continue;
    }
    mean += G.row(i).transpose() / norms(i);
    ++s.subjects;
  }
  if (s.subjects == 0 || mean.norm() <= tiny)
    throw InputError("morph_direction_spread: every gradient is zero (or they cancel): no direction");
  s.mean_direction = mean.normalized();
  s.angles_deg.resize(s.subjects);
  int k = 0;
  for (Eigen::Index i = 0; i < G.rows(); ++i) {
    if (norms(i) <= tiny) continue;
    const double c = std::clamp(G.row(i).dot(s.mean_direction) / norms(i), -1.0, 1.0);
    s.angles_deg(k++) = std::acos(c) * 180.0 / M_PI;
  }
  s.mean_deg = s.angles_deg.mean();
  s.std_deg = std::sqrt((s.angles_deg.array() - s.mean_deg).square().mean());
  s.max_deg = s.angles_deg.maxCoeff();
  return s;
}

}  // namespace bodymodel
