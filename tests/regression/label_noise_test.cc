// Simulated label noise (regression/label_noise.h): spec parsing, σ in label units, the statistics
// of the added noise, one draw per subject; and the regime it exists for: with about as many PCA
// components as subjects, eq. 10 on every component fits the label noise (Hasler et al. §4:
// "severely overtrained") while the filtered regressor does not.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

#include "core/error.h"
#include "regression/cross_validation.h"
#include "regression/label_noise.h"
#include "regression/linear_regressors.h"

namespace bodymodel {
namespace {

TEST(LabelNoise, ParsesRelativeAndAbsoluteSpecsAndRejectsBadOnes) {
  LabelNoiseSpec s = parse_label_noise("0.2");
  EXPECT_DOUBLE_EQ(s.relative, 0.2);
  EXPECT_TRUE(s.absolute.empty());
  s = parse_label_noise("0.1, weight_kg=0.5,height_cm=1");
  EXPECT_DOUBLE_EQ(s.relative, 0.1);
  ASSERT_EQ(s.absolute.size(), 2u);
  EXPECT_EQ(s.absolute[0].first, "weight_kg");
  EXPECT_DOUBLE_EQ(s.absolute[0].second, 0.5);
  EXPECT_TRUE(parse_label_noise("").empty());
  EXPECT_TRUE(parse_label_noise("0").empty());
  EXPECT_THROW(parse_label_noise("-1"), InputError);
  EXPECT_THROW(parse_label_noise("height_cm=lots"), InputError);
  EXPECT_THROW(parse_label_noise("=2"), InputError);
  EXPECT_THROW(parse_label_noise("0.1,0.2"), InputError);
}

TEST(LabelNoise, SigmaIsAFractionOfTheSpreadOrGivenInTheLabelUnit) {
  Eigen::MatrixXd Y(4, 2);
  Y << 1, 10, 2, 20, 3, NAN, 4, 40;
  const std::vector<std::string> names{"a", "b"};
  const Eigen::VectorXd rel = label_noise_sigma(parse_label_noise("0.5"), Y, names);
  EXPECT_NEAR(rel(0), 0.5 * std::sqrt(5.0 / 3.0), 1e-12);                  // sample std of 1..4
  const double m = 70.0 / 3;  // of 10, 20, 40 (the NaN skipped)
  EXPECT_NEAR(rel(1), 0.5 * std::sqrt(((10 - m) * (10 - m) + (20 - m) * (20 - m) + (40 - m) * (40 - m)) / 2), 1e-9);
  const Eigen::VectorXd mixed = label_noise_sigma(parse_label_noise("0.5,b=3"), Y, names);
  EXPECT_DOUBLE_EQ(mixed(1), 3.0);
  EXPECT_THROW(label_noise_sigma(parse_label_noise("c=1"), Y, names), InputError);
}

TEST(LabelNoise, AddsGaussianNoiseOfTheGivenSigmaOncePerSubject) {
  const int subjects = 4000;
  Eigen::MatrixXd Y = Eigen::MatrixXd::Constant(2 * subjects, 2, 5.0);
  Y(7, 1) = NAN;
  std::vector<int> groups(2 * subjects);
  for (int i = 0; i < 2 * subjects; ++i) groups[i] = i / 2;  // two rows a subject
  const Eigen::Vector2d sigma(0.5, 2.0);
  const Eigen::MatrixXd N = add_label_noise(Y, sigma, groups, 3);
  EXPECT_TRUE(std::isnan(N(7, 1)));
  for (int l = 0; l < 2; ++l) {
    double sum = 0, sum2 = 0;
    int n = 0;
    for (int s = 0; s < subjects; ++s) {
      if (s == 3) continue;  // holds the NaN
      EXPECT_EQ(N(2 * s, l), N(2 * s + 1, l)) << "subject " << s;  // the subject's rows share a draw
      const double e = N(2 * s, l) - 5.0;
      sum += e, sum2 += e * e, ++n;
    }
    const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
    EXPECT_NEAR(sd, sigma(l), 0.05 * sigma(l));        // 4000 draws: sd within ≈ 2.2% at 2σ
    EXPECT_NEAR(mean, 0.0, 4 * sigma(l) / std::sqrt(n));
  }
  const Eigen::MatrixXd again = add_label_noise(Y, sigma, groups, 3);
  for (int i = 0; i < N.rows(); ++i)
    for (int l = 0; l < 2; ++l)
      if (!std::isnan(N(i, l))) EXPECT_EQ(N(i, l), again(i, l));  // seeded: repeatable
  EXPECT_NE(add_label_noise(Y, sigma, groups, 4)(0, 0), N(0, 0));
}

TEST(LabelNoise, AtAsManyComponentsAsSubjectsFilteringBeatsSimpleLinearOnNoisyLabels) {
  // 100 subjects, 99 "PCA coefficients" (independent, standard deviation 30/j: a decaying
  // spectrum), label = two leading components + one weaker + noise σ 1 — the paper's regime:
  // 10-fold training sets of 90 subjects and 99 components, so eq. 10 on everything
  // interpolates the noise.
  const int n = 100, p = 99;
  std::mt19937 rng(17);
  std::normal_distribution<double> z(0, 1);
  Eigen::MatrixXd X(n, p);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < p; ++j) X(i, j) = z(rng) * 30.0 / (j + 1);
  Eigen::VectorXd clean = 0.3 * X.col(0) - 0.4 * X.col(1) + 1.0 * X.col(5);
  const double sigma = 1.0;
  Eigen::MatrixXd Y = add_label_noise(clean, Eigen::VectorXd::Constant(1, sigma), {}, 5);
  CrossValidationOptions cv;  // 10 folds
  const auto simple = cross_validate(SimpleLinearRegressor(), X, Y.col(0), {}, cv);
  const auto filtered = cross_validate(FilteredLinearRegressor(), X, Y.col(0), {}, cv);
  // Without noise both are near exact; with it, simple linear is far above the noise floor.
  EXPECT_GT(simple.rmse, 1.5 * sigma);
  EXPECT_LT(filtered.rmse, 1.3 * sigma);
  EXPECT_LT(filtered.rmse, 0.75 * simple.rmse);
  const auto simple_clean = cross_validate(SimpleLinearRegressor(), X, clean, {}, cv);
  EXPECT_LT(simple_clean.rmse, 0.05 * sigma);
}

}  // namespace
}  // namespace bodymodel
