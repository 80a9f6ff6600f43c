// Regressors on synthetic data with known answers: linear and quadratic functions recovered within
// stated bounds, grouped folds never leak a subject, filtering beats plain least squares when most
// features are noise, and the project's paths agree with independent computations (closed-form
// normal equations; libsvm's own svm_predict; finite differences of the predictions).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <set>

#include "core/error.h"
#include "regression/cross_validation.h"
#include "regression/gaussian_process.h"
#include "regression/linear_regressors.h"
#include "regression/morph_directions.h"
#include "regression/regression_study.h"
#include "regression/svr.h"

namespace bodymodel {
namespace {

Eigen::MatrixXd gaussian_matrix(int rows, int cols, unsigned seed, double sigma = 1) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, sigma);
  Eigen::MatrixXd M(rows, cols);
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j) M(i, j) = n(rng);
  return M;
}

double stddev(const Eigen::VectorXd& y) { return std::sqrt((y.array() - y.mean()).square().mean()); }

// A smaller hyper-parameter search keeps the tests fast; the defaults are exercised by the bench.
SvrRegressor::Options quick_svr() {
  SvrRegressor::Options o;
  o.C = {10, 100, 1000};
  o.epsilon = {0.02};
  o.gamma = {0.03, 0.1, 0.3};
  o.inner_folds = 4;
  return o;
}

TEST(GroupedFolds, NeverSplitASubjectAndBalanceSubjects) {
  std::vector<int> groups;
  for (int s = 0; s < 23; ++s)
    for (int k = 0; k < 1 + s % 3; ++k) groups.push_back(100 + 7 * s);  // 1..3 rows a subject
  const int folds = 5;
  const std::vector<int> fold_of = grouped_folds(groups, static_cast<int>(groups.size()), folds, 42);
  std::map<int, std::set<int>> folds_of_subject;
  std::vector<std::set<int>> subjects_in_fold(folds);
  for (size_t i = 0; i < groups.size(); ++i) {
    folds_of_subject[groups[i]].insert(fold_of[i]);
    subjects_in_fold[fold_of[i]].insert(groups[i]);
  }
  for (const auto& [subject, fs] : folds_of_subject) EXPECT_EQ(fs.size(), 1u) << "subject " << subject;
  for (const auto& [train, test] : fold_splits(fold_of, folds)) {
    std::set<int> train_subjects, test_subjects;
    for (int i : train) train_subjects.insert(groups[i]);
    for (int i : test) test_subjects.insert(groups[i]);
    for (int s : test_subjects) EXPECT_EQ(train_subjects.count(s), 0u) << "subject " << s << " leaks";
    EXPECT_EQ(train.size() + test.size(), groups.size());
  }
  for (const auto& s : subjects_in_fold) {
    EXPECT_GE(s.size(), 4u);  // 23 subjects into 5 folds: 4 or 5 each
    EXPECT_LE(s.size(), 5u);
  }
  EXPECT_EQ(fold_of, grouped_folds(groups, static_cast<int>(groups.size()), folds, 42));
  EXPECT_NE(fold_of, grouped_folds(groups, static_cast<int>(groups.size()), folds, 43));
}

TEST(GroupedFolds, FewerSubjectsThanFoldsIsAClearError) {
  const std::vector<int> groups = {0, 0, 1, 1, 2, 2};
  try {
    grouped_folds(groups, 6, 10, 1);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("3 subjects but 10 folds"), std::string::npos) << e.what();
  }
}

// Issue 40: groups = {1} for 100 000 rows made cross_validate read far past the list (a
// segfault); for 10 rows it built folds from whatever lay beyond it. A groups list of another
// length than X's rows is refused, naming it; select_rows refuses rows it does not have.
TEST(CrossValidation, RefusesGroupsOfAnotherLengthThanX) {
  for (int rows : {10, 100000}) {
    const Eigen::MatrixXd X = gaussian_matrix(rows, 2, 3);
    const Eigen::VectorXd y = X.col(0) + 2 * X.col(1);
    CrossValidationOptions cv;
    cv.folds = 2;
    try {
      cross_validate(SimpleLinearRegressor(), X, y, {1}, cv);
      FAIL() << "expected InputError for " << rows << " rows";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("groups has 1 entries but X has " + std::to_string(rows) + " rows"),
                std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(select_rows(std::vector<int>{0, 1}, std::vector<int>{0, 2}), InputError);
  EXPECT_THROW(select_rows(Eigen::VectorXd(Eigen::VectorXd::Zero(3)), std::vector<int>{-1}), InputError);
  EXPECT_THROW(select_rows(Eigen::MatrixXd(Eigen::MatrixXd::Zero(3, 2)), std::vector<int>{3}), InputError);
  CrossValidationOptions cv;
  cv.folds = 2;
  EXPECT_THROW(cross_validate(SimpleLinearRegressor(), Eigen::MatrixXd::Zero(10, 0), Eigen::VectorXd::LinSpaced(10, 0, 1),
                              {}, cv), InputError);
}

TEST(Regressors, RecoverALinearFunction) {
  const Eigen::MatrixXd X = gaussian_matrix(120, 6, 11);
  Eigen::VectorXd s(6);
  s << 3, -2, 1, 0.5, 0, 0;
  const Eigen::VectorXd noise = gaussian_matrix(120, 1, 12, 0.01).col(0);
  const Eigen::VectorXd y = (X * s).array() + 10.0 + noise.array();
  const double sy = stddev(y);  // ≈ 3.8
  CrossValidationOptions cv;
  cv.folds = 5;
  // Bounds: linear models reach the noise level (0.01); kernel models within a few % of σ_y.
  EXPECT_LT(cross_validate(SimpleLinearRegressor(), X, y, {}, cv).rmse, 0.015);
  EXPECT_LT(cross_validate(FilteredLinearRegressor(), X, y, {}, cv).rmse, 0.015);
  EXPECT_LT(cross_validate(GaussianProcessRegressor(), X, y, {}, cv).rmse, 0.02 * sy);
  EXPECT_LT(cross_validate(SvrRegressor(quick_svr()), X, y, {}, cv).rmse, 0.05 * sy);
}

TEST(Regressors, KernelModelsRecoverAQuadraticFunctionLinearOnesCannot) {
  const Eigen::MatrixXd X = gaussian_matrix(150, 3, 21);
  const Eigen::VectorXd noise = gaussian_matrix(150, 1, 22, 0.02).col(0);
  const Eigen::VectorXd y = X.col(0).array().square() + 0.5 * X.col(1).array() + noise.array();
  CrossValidationOptions cv;
  cv.folds = 5;
  const double linear = cross_validate(SimpleLinearRegressor(), X, y, {}, cv).rmse;
  const double gp = cross_validate(GaussianProcessRegressor(), X, y, {}, cv).rmse;
  const double svr = cross_validate(SvrRegressor(quick_svr()), X, y, {}, cv).rmse;
  EXPECT_GT(linear, 0.8 * stddev(X.col(0).array().square().matrix()));  // x0² is invisible to a line
  EXPECT_LT(gp, 0.15 * stddev(y));
  EXPECT_LT(svr, 0.2 * stddev(y));
  EXPECT_LT(gp, 0.25 * linear);
  EXPECT_LT(svr, 0.3 * linear);
}

TEST(Regressors, FilteredBeatsSimpleWhenMostFeaturesAreNoise) {
  // 60 subjects, 50 features of which 3 carry the label (like a few PCA components that explain
  // height among many that describe registration noise).
  const Eigen::MatrixXd X = gaussian_matrix(60, 50, 31);
  const Eigen::VectorXd noise = gaussian_matrix(60, 1, 32, 0.3).col(0);
  const Eigen::VectorXd y = 2 * X.col(4) - X.col(17) + 0.5 * X.col(30) + noise;
  CrossValidationOptions cv;
  const auto simple = cross_validate(SimpleLinearRegressor(), X, y, {}, cv);
  const auto filtered = cross_validate(FilteredLinearRegressor(), X, y, {}, cv);
  EXPECT_LT(filtered.rmse, 0.6 * simple.rmse);
  EXPECT_LT(filtered.rmse, 0.5);  // noise σ 0.3
  // One count (the leave-one-out minimum): a few components, the informative ones among them.
  FilteredLinearRegressor::Options one;
  one.selection = CountSelection::minimum;
  FilteredLinearRegressor f(one);
  f.fit(X, y);
  ASSERT_GE(f.kept_components().size(), 3u);
  EXPECT_LE(f.kept_components().size(), 20u);  // of 50
  const std::set<int> kept(f.kept_components().begin(), f.kept_components().end());
  for (int informative : {4, 17, 30}) EXPECT_EQ(kept.count(informative), 1u) << informative;
  // Stacked (the default): more than half the weight on fits of at most 20 components, which
  // hold the informative ones; the 47 noise components get far less coefficient mass than in
  // eq. 10 on everything.
  FilteredLinearRegressor stacked;
  stacked.fit(X, y);
  SimpleLinearRegressor all;
  all.fit(X, y);
  EXPECT_NEAR(stacked.count_weights().sum(), 1.0, 1e-12);
  EXPECT_GT(stacked.count_weights().head(20).sum(), 0.5) << stacked.describe();
  const Eigen::VectorXd g = stacked.gradient(X.row(0).transpose()), g_all = all.gradient(X.row(0).transpose());
  double noise_mass = g.cwiseAbs().sum(), noise_mass_all = g_all.cwiseAbs().sum();
  for (int informative : {4, 17, 30}) {
    EXPECT_NEAR(g(informative), informative == 4 ? 2.0 : informative == 17 ? -1.0 : 0.5, 0.15) << informative;
    noise_mass -= std::abs(g(informative));
    noise_mass_all -= std::abs(g_all(informative));
  }
  EXPECT_LT(noise_mass, 0.6 * noise_mass_all);  // Σ |coefficient| over the 47 noise components
}

TEST(CrossCheck, SimpleLinearMatchesNormalEquationsOnTheSameFolds) {
  const Eigen::MatrixXd X = gaussian_matrix(80, 10, 41);
  const Eigen::VectorXd y = gaussian_matrix(80, 1, 42).col(0) + X.col(0);
  CrossValidationOptions cv;
  cv.folds = 8;
  const auto ours = cross_validate(SimpleLinearRegressor(), X, y, {}, cv);
  // Independent: (AᵀA)⁻¹Aᵀy with A = [1 | X] by Cholesky, same folds.
  const std::vector<int> fold_of = grouped_folds({}, 80, cv.folds, cv.seed);
  double sse = 0;
  for (const auto& [train, test] : fold_splits(fold_of, cv.folds)) {
    Eigen::MatrixXd A(train.size(), 11);
    Eigen::VectorXd b(train.size());
    for (size_t k = 0; k < train.size(); ++k) {
      A(k, 0) = 1;
      A.row(k).tail(10) = X.row(train[k]);
      b(k) = y(train[k]);
    }
    const Eigen::VectorXd w = (A.transpose() * A).llt().solve(A.transpose() * b);
    for (int i : test) sse += std::pow(w(0) + X.row(i).dot(w.tail(10)) - y(i), 2);
  }
  const double reference = std::sqrt(sse / 80);
  EXPECT_NEAR(ours.rmse, reference, 0.01 * reference);
  EXPECT_NEAR(ours.rmse, reference, 1e-9);
}

TEST(CrossCheck, SvrPredictionAndGradientMatchLibsvm) {
  const Eigen::MatrixXd X = gaussian_matrix(70, 4, 51);
  const Eigen::VectorXd y = (X.col(0).array() * 2).sin().matrix() * 5 + X.col(1) * 3;
  SvrRegressor::Options o;
  o.C = {100};
  o.epsilon = {0.02};
  o.gamma = {0.3};
  SvrRegressor svr(o);
  svr.fit(X, y);
  ASSERT_GT(svr.support_vectors(), 5);
  const Eigen::MatrixXd Q = gaussian_matrix(20, 4, 52);
  for (int i = 0; i < Q.rows(); ++i) {
    const Eigen::VectorXd x = Q.row(i).transpose();
    const double ours = svr.predict(x), libsvm = svr.predict_with_libsvm(x);
    EXPECT_NEAR(ours, libsvm, 1e-9 * std::max(1.0, std::abs(libsvm)));
    // Analytic gradient against central differences of libsvm's svm_predict.
    const Eigen::VectorXd g = svr.gradient(x);
    Eigen::VectorXd fd(4);
    const double h = 1e-4;
    for (int j = 0; j < 4; ++j) {
      Eigen::VectorXd a = x, b = x;
      a(j) += h, b(j) -= h;
      fd(j) = (svr.predict_with_libsvm(a) - svr.predict_with_libsvm(b)) / (2 * h);
    }
    EXPECT_LT((g - fd).norm(), 0.01 * fd.norm() + 1e-6) << "at query " << i;
  }
}

TEST(CrossCheck, SvrCrossValidationMatchesLibsvmPredictOnTheSameFolds) {
  const Eigen::MatrixXd X = gaussian_matrix(90, 5, 61);
  const Eigen::VectorXd y = X.col(0).array().square().matrix() + X.col(2);
  CrossValidationOptions cv;
  cv.folds = 5;
  const SvrRegressor prototype(quick_svr());
  const auto ours = cross_validate(prototype, X, y, {}, cv);
  const std::vector<int> fold_of = grouped_folds({}, 90, cv.folds, cv.seed);
  double sse = 0;
  for (const auto& [train, test] : fold_splits(fold_of, cv.folds)) {
    SvrRegressor r(quick_svr());
    r.fit(select_rows(X, train), select_rows(y, train));
    for (int i : test) sse += std::pow(r.predict_with_libsvm(X.row(i).transpose()) - y(i), 2);
  }
  const double reference = std::sqrt(sse / 90);
  EXPECT_NEAR(ours.rmse, reference, 0.01 * reference);
}

TEST(CrossCheck, GaussianProcessGradientMatchesFiniteDifferences) {
  const Eigen::MatrixXd X = gaussian_matrix(60, 3, 71);
  const Eigen::VectorXd y = X.col(0).array().square().matrix() + X.col(1) * 2;
  GaussianProcessRegressor gp;
  gp.fit(X, y);
  const Eigen::MatrixXd Q = gaussian_matrix(10, 3, 72);
  for (int i = 0; i < Q.rows(); ++i) {
    const Eigen::VectorXd x = Q.row(i).transpose();
    const Eigen::VectorXd g = gp.gradient(x);
    Eigen::VectorXd fd(3);
    const double h = 1e-5;
    for (int j = 0; j < 3; ++j) {
      Eigen::VectorXd a = x, b = x;
      a(j) += h, b(j) -= h;
      fd(j) = (gp.predict(a) - gp.predict(b)) / (2 * h);
    }
    EXPECT_LT((g - fd).norm(), 1e-4 * fd.norm() + 1e-7) << "at query " << i;
  }
}

TEST(BadInput, MissingLabelValuesAreSkippedAndCounted) {
  const Eigen::MatrixXd X = gaussian_matrix(40, 3, 81);
  Eigen::VectorXd y = X.col(0) * 2;
  for (int i : {3, 17, 29}) y(i) = std::numeric_limits<double>::quiet_NaN();
  CrossValidationOptions cv;
  cv.folds = 5;
  const auto s = cross_validate(SimpleLinearRegressor(), X, y, {}, cv, "weight_kg");
  EXPECT_EQ(s.skipped_missing, 3);
  EXPECT_EQ(s.samples, 37);
  EXPECT_LT(s.rmse, 1e-9);
  EXPECT_TRUE(s.predictions.allFinite());
}

TEST(BadInput, ConstantLabelAndTooFewSubjectsAreClearErrors) {
  const Eigen::MatrixXd X = gaussian_matrix(12, 3, 91);
  try {
    cross_validate(SimpleLinearRegressor(), X, Eigen::VectorXd::Constant(12, 170.0), {}, {}, "height_cm");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'height_cm' is constant"), std::string::npos) << e.what();
  }
  std::vector<int> groups;
  for (int i = 0; i < 12; ++i) groups.push_back(i / 3);  // 4 subjects
  try {
    cross_validate(SimpleLinearRegressor(), X, X.col(0), groups, {}, "waist_cm");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("4 subjects but 10 folds"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("waist_cm"), std::string::npos) << e.what();
  }
  EXPECT_THROW(make_regressor("random_forest"), InputError);
  EXPECT_EQ(make_regressor("filtered_linear_by_s")->name(), "filtered_linear_by_s");
  EXPECT_EQ(make_regressor("filtered_linear_by_s")->clone()->name(), "filtered_linear_by_s");
}

TEST(MorphDirections, AnglesToTheMeanDirection) {
  // Directions at ±10° about the x axis, both lengths: every angle is 10°, spread 0.
  const double a = 10 * M_PI / 180;
  Eigen::MatrixXd G(4, 2);
  G << std::cos(a), std::sin(a), 2 * std::cos(a), -2 * std::sin(a), 3 * std::cos(a), 3 * std::sin(a),
      std::cos(a), -std::sin(a);
  const MorphDirectionSpread s = morph_direction_spread(G);
  EXPECT_NEAR(s.mean_deg, 10, 1e-9);
  EXPECT_NEAR(s.std_deg, 0, 1e-9);
  EXPECT_NEAR(s.mean_direction(0), 1, 1e-12);
  // A linear regressor has one direction everywhere.
  const Eigen::MatrixXd X = gaussian_matrix(30, 4, 101);
  SimpleLinearRegressor lin;
  lin.fit(X, X.col(0) + X.col(1));
  EXPECT_LT(morph_direction_spread(morph_directions(lin, X)).max_deg, 1e-6);
}

TEST(RegressionStudy, ParallelStudyMatchesSequentialCrossValidation) {
  const Eigen::MatrixXd X = gaussian_matrix(50, 8, 111);
  Eigen::MatrixXd Y(50, 2);
  Y.col(0) = X.col(0) * 3 + gaussian_matrix(50, 1, 112, 0.1).col(0);
  Y.col(1) = X.col(1).array().square().matrix() + X.col(2);
  Y(5, 1) = std::numeric_limits<double>::quiet_NaN();
  RegressionStudyOptions o;
  o.regressors = {"simple_linear", "filtered_linear", "gaussian_process"};
  o.cross_validation.folds = 5;
  o.jobs = 2;
  const RegressionStudy study = run_regression_study(X, Y, {"a", "b"}, {}, o);
  ASSERT_EQ(study.results.size(), 6u);
  for (const auto& name : o.regressors)
    for (int l = 0; l < 2; ++l) {
      const auto ref = cross_validate(*make_regressor(name), X, Y.col(l), {}, o.cross_validation,
                                      l ? "b" : "a");
      EXPECT_NEAR(study.result(name, l ? "b" : "a").rmse, ref.rmse, 1e-9 * (1 + ref.rmse)) << name;
    }
  EXPECT_EQ(study.result("simple_linear", "b").skipped_missing, 1);
  ASSERT_EQ(study.filtered_curves.size(), 2u);
  EXPECT_EQ(study.filtered_curves[0].size(), 8);
  EXPECT_NEAR(study.filtered_curves[0](7), study.result("simple_linear", "a").rmse, 1e-9);
  EXPECT_EQ(study.directions.size(), 6u);
}

}  // namespace
}  // namespace bodymodel
