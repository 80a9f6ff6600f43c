// Eq. 10 (fit_linear): recovers known affine functions; ridge and minimum-norm cases checked
// against closed-form normal equations computed independently here.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "core/error.h"
#include "regression/linear.h"

namespace bodymodel {
namespace {

Eigen::MatrixXd random_matrix(int rows, int cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, 1);
  Eigen::MatrixXd M(rows, cols);
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j) M(i, j) = n(rng);
  return M;
}

TEST(FitLinear, RecoversExactAffineFunction) {
  const Eigen::MatrixXd X = random_matrix(50, 6, 1);
  Eigen::VectorXd s(6);
  s << 1.5, -2, 0.25, 0, 3, -0.5;
  const Eigen::VectorXd y = (X * s).array() + 7.0;
  const LinearFit fit = fit_linear(X, y);
  EXPECT_NEAR(fit.offset, 7.0, 1e-9);
  EXPECT_LT((fit.gradient - s).norm(), 1e-9);
  EXPECT_NEAR(fit.predict(X.row(3).transpose()), y(3), 1e-9);
}

TEST(FitLinear, MatchesClosedFormNormalEquationsWithNoiseAndRidge) {
  const Eigen::MatrixXd X = random_matrix(40, 5, 2);
  const Eigen::VectorXd y = random_matrix(40, 1, 3).col(0);
  for (double ridge : {0.0, 0.7}) {
    // Independent solve: augmented [1 | X] with the offset unpenalised.
    Eigen::MatrixXd A(40, 6);
    A << Eigen::VectorXd::Ones(40), X;
    Eigen::MatrixXd N = A.transpose() * A;
    N.diagonal().tail(5).array() += ridge;
    const Eigen::VectorXd w = N.inverse() * (A.transpose() * y);
    const LinearFit fit = fit_linear(X, y, ridge);
    EXPECT_NEAR(fit.offset, w(0), 1e-9);
    EXPECT_LT((fit.gradient - w.tail(5)).norm(), 1e-9);
  }
}

TEST(FitLinear, UnderdeterminedGivesMinimumNormInterpolant) {
  const Eigen::MatrixXd X = random_matrix(5, 20, 4);
  const Eigen::VectorXd y = random_matrix(5, 1, 5).col(0);
  const LinearFit fit = fit_linear(X, y);
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(fit.predict(X.row(i).transpose()), y(i), 1e-9);
  // Minimum norm: s lies in the row space of the centred X.
  const Eigen::MatrixXd Xc = X.rowwise() - X.colwise().mean();
  const Eigen::VectorXd projected =
      Xc.transpose() * (Xc * Xc.transpose()).completeOrthogonalDecomposition().solve(Xc * fit.gradient);
  EXPECT_LT((projected - fit.gradient).norm(), 1e-8 * fit.gradient.norm());
}

TEST(FitLinear, BadInputThrows) {
  EXPECT_THROW(fit_linear(Eigen::MatrixXd(3, 2), Eigen::VectorXd(4)), InputError);
  Eigen::MatrixXd X = Eigen::MatrixXd::Zero(3, 2);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(3);
  y(1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(fit_linear(X, y), InputError);
  EXPECT_THROW(fit_linear(X, Eigen::VectorXd::Zero(3), -1.0), InputError);
}

}  // namespace
}  // namespace bodymodel
