#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "core/error.h"

#include "model/pca.h"
#include "model/semantic.h"

namespace bodymodel {
namespace {

Eigen::MatrixXd random_low_rank(int D, int N, int rank, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, 1);
  Eigen::MatrixXd A(D, rank), B(rank, N);
  for (int i = 0; i < A.size(); ++i) A.data()[i] = n(rng);
  for (int i = 0; i < B.size(); ++i) B.data()[i] = n(rng) * (rank - i % rank);
  return A * B + Eigen::MatrixXd::Constant(D, N, 3.0);
}

TEST(Pca, GramPcaReconstructsLowRankDataAndMatchesCovariance) {
  Eigen::MatrixXd X = random_low_rank(500, 12, 5, 1);
  PcaSummary s;
  Pca p = fit_pca(X, {0.999999, -1}, &s);
  EXPECT_EQ(p.component_count(), 5);
  EXPECT_NEAR((p.basis.transpose() * p.basis - Eigen::MatrixXd::Identity(5, 5)).norm(), 0, 1e-10);
  for (int i = 0; i < X.cols(); ++i)
    EXPECT_NEAR((p.reconstruct(p.project(X.col(i))) - X.col(i)).norm(), 0, 1e-8 * X.col(i).norm());
  // Eigenvalues = variance of the coefficients.
  for (int k = 0; k < 5; ++k) {
    double var = p.coefficients.col(k).squaredNorm() / (X.cols() - 1);
    EXPECT_NEAR(var, p.eigenvalues(k), 1e-8 * p.eigenvalues(0));
  }
  // A lower threshold keeps fewer components, and says how much they explain.
  PcaSummary s2;
  Pca q = fit_pca(X, {0.6, -1}, &s2);
  EXPECT_LT(q.component_count(), 5);
  EXPECT_GE(s2.explained, 0.6);
}

// The partial (Spectra) eigen-solver finds the same leading components as the full one: same
// count under a variance threshold, eigenvalues, basis (up to sign) and coefficients.
TEST(Pca, PartialEigenSolverAgreesWithTheFullOne) {
  Eigen::MatrixXd X = random_low_rank(300, 120, 40, 2);
  for (double threshold : {1.0, 0.8}) {
    SCOPED_TRACE(threshold);
    PcaSummary sf, sp;
    Pca f = fit_pca(X, {threshold, 10, PcaEigenSolver::full}, &sf);
    Pca p = fit_pca(X, {threshold, 10, PcaEigenSolver::partial}, &sp);
    ASSERT_EQ(p.component_count(), f.component_count());
    EXPECT_NEAR(sp.explained, sf.explained, 1e-10);
    EXPECT_NEAR(sp.total_variance, sf.total_variance, 1e-10 * sf.total_variance);
    for (int k = 0; k < f.component_count(); ++k) {
      EXPECT_NEAR(p.eigenvalues(k), f.eigenvalues(k), 1e-10 * f.eigenvalues(0)) << k;
      const double sign = p.basis.col(k).dot(f.basis.col(k)) < 0 ? -1 : 1;
      EXPECT_LT((p.basis.col(k) - sign * f.basis.col(k)).cwiseAbs().maxCoeff(), 1e-8) << k;
      EXPECT_LT((p.coefficients.col(k) - sign * f.coefficients.col(k)).cwiseAbs().maxCoeff(),
                1e-8 * f.coefficients.cwiseAbs().maxCoeff()) << k;
    }
  }
  // Automatic choice: few components of few samples stay on the full solver (bit-identical).
  Pca a = fit_pca(X, {1.0, 10});
  Pca f = fit_pca(X, {1.0, 10, PcaEigenSolver::full});
  EXPECT_TRUE(a.basis == f.basis);
  EXPECT_THROW(fit_pca(X, {1.0, -1, PcaEigenSolver::partial}), InputError);
}

TEST(ConstrainedChange, MeetsEveryConstraintWithMinimumNorm) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0, 1);
  Eigen::MatrixXd S(10, 3);
  for (int i = 0; i < S.size(); ++i) S.data()[i] = n(rng);
  Eigen::VectorXd d(3);
  d << 2.0, 0.0, -1.0;  // second label held
  Eigen::VectorXd z = constrained_change(S, d);
  EXPECT_NEAR((S.transpose() * z - d).norm(), 0, 1e-10);
  // Minimum norm ⇔ z lies in the span of the constraint directions.
  Eigen::VectorXd coef = S.colPivHouseholderQr().solve(z);
  EXPECT_NEAR((S * coef - z).norm(), 0, 1e-10);
  // Any other solution is longer.
  Eigen::VectorXd null = Eigen::VectorXd::Random(10);
  null -= S * S.colPivHouseholderQr().solve(null);
  EXPECT_GT((z + null).norm(), z.norm());
}

// The metric form: min Σ z²/w subject to Sᵀz = Δ has the closed form z = W S (Sᵀ W S)⁻¹ Δ
// (W = diag(w)); with the PCA eigenvalues it is the Gaussian's conditional mean.
TEST(ConstrainedChange, MetricGivesTheMostLikelyChange) {
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0, 1);
  Eigen::MatrixXd S(8, 2);
  for (int i = 0; i < S.size(); ++i) S.data()[i] = n(rng);
  Eigen::VectorXd w(8), d(2);
  w << 9, 4, 2, 1, 0.5, 0.25, 0.1, 0.01;
  d << 1.5, -0.5;
  ConstrainedChangeOptions o;
  o.metric = w;
  const Eigen::VectorXd z = constrained_change(S, d, o);
  EXPECT_NEAR((S.transpose() * z - d).norm(), 0, 1e-10);
  const Eigen::MatrixXd WS = w.asDiagonal() * S;
  const Eigen::VectorXd expected = WS * (S.transpose() * WS).ldlt().solve(d);
  EXPECT_NEAR((z - expected).norm(), 0, 1e-10);
  // It differs from the Euclidean minimum norm, which is shorter but less likely.
  const Eigen::VectorXd e = constrained_change(S, d);
  EXPECT_LT(e.norm(), z.norm());
  EXPECT_LT(z.cwiseAbs2().cwiseQuotient(w).sum(), e.cwiseAbs2().cwiseQuotient(w).sum());
  o.metric(3) = 0;  // not a metric
  EXPECT_THROW(constrained_change(S, d, o), InputError);
}

TEST(SemanticRegression, RecoversALinearLabelAndBuildsAnOrthonormalBasis) {
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0, 1);
  const int N = 40, K = 6;
  Eigen::MatrixXd C(N, K);
  for (int i = 0; i < C.size(); ++i) C.data()[i] = n(rng);
  Eigen::VectorXd s_true(K);
  s_true << 1, -2, 0.5, 0, 3, 0;
  Eigen::MatrixXd Y(N, 2);
  Y.col(0) = (C * s_true).array() + 170.0;
  Y.col(1) = C.col(0) * 4 + C.col(1);
  SemanticRegression r = fit_semantic_regression(C, Y, {{"height_cm", "cm"}, {"weight_kg", "kg"}}, {0});
  EXPECT_NEAR((r.gradients.col(0) - s_true).norm(), 0, 1e-8);
  EXPECT_NEAR(r.offsets(0), 170.0, 1e-8);
  EXPECT_THROW(r.index("hight"), InputError);
  SemanticBasis b = build_semantic_basis(r, {"height_cm", "weight_kg"}, C);
  EXPECT_EQ(b.semantic_count(), 2);
  EXPECT_NEAR((b.basis.transpose() * b.basis - Eigen::MatrixXd::Identity(K, K)).norm(), 0, 1e-8);
  // Changing a remainder coordinate leaves both labels' predictions unchanged.
  for (int k = 2; k < K; ++k) {
    Eigen::VectorXd dp = r.gradients.transpose() * b.basis.col(k);
    EXPECT_NEAR(dp.norm(), 0, 1e-8);
  }
}

}  // namespace
}  // namespace bodymodel
