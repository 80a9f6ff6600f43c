#include "regression/linear_regressors.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

#include "core/error.h"
#include "regression/cross_validation.h"
#include "regression/prefix_linear.h"
#include "regression/stacking.h"

namespace bodymodel {

// ---- simple linear --------------------------------------------------------------------------

void SimpleLinearRegressor::fit(const Eigen::MatrixXd& X, const Eigen::VectorXd& y,
                                const std::vector<int>& groups) {
  check_regression_input(X, y, groups, 2, "simple_linear");
  fit_ = fit_linear(X, y, options_.ridge);
}

double SimpleLinearRegressor::predict(const Eigen::VectorXd& x) const { return fit_.predict(x); }

Eigen::VectorXd SimpleLinearRegressor::gradient(const Eigen::VectorXd& x) const {
  if (x.size() != fit_.gradient.size())
    throw InputError("simple_linear: expected " + std::to_string(fit_.gradient.size()) +
                     " features, found " + std::to_string(x.size()));
  return fit_.gradient;
}

std::unique_ptr<Regressor> SimpleLinearRegressor::clone() const {
  return std::make_unique<SimpleLinearRegressor>(options_);
}

std::string SimpleLinearRegressor::describe() const {
  return "all " + std::to_string(fit_.gradient.size()) + " components";
}

// ---- ranking and the filtered curve ---------------------------------------------------------

std::vector<int> rank_components(const Eigen::MatrixXd& X, const Eigen::VectorXd& y,
                                 ComponentRanking ranking) {
  const Eigen::Index d = X.cols();
  Eigen::VectorXd score(d);
  if (ranking == ComponentRanking::gradient) {
    score = fit_linear(X, y).gradient.cwiseAbs();
  } else {
    const Eigen::MatrixXd Xc = X.rowwise() - X.colwise().mean();
    const Eigen::VectorXd yc = y.array() - y.mean();
    for (Eigen::Index j = 0; j < d; ++j) {
      const double sx = Xc.col(j).norm();
      score(j) = sx > 0 ? std::abs(Xc.col(j).dot(yc)) / sx : 0.0;
    }
  }
  std::vector<int> order(d);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return score(a) > score(b); });
  return order;
}

namespace {

Eigen::MatrixXd select_columns(const Eigen::MatrixXd& X, const std::vector<int>& cols, int m) {
  Eigen::MatrixXd out(X.rows(), m);
  for (int k = 0; k < m; ++k) out.col(k) = X.col(cols[k]);
  return out;
}

}  // namespace

Eigen::MatrixXd filtered_linear_residuals(const Eigen::MatrixXd& X, const Eigen::VectorXd& y,
                                          const std::vector<int>& fold_of, int folds, int max_components,
                                          ComponentRanking ranking) {
  if (X.rows() != y.size() || static_cast<Eigen::Index>(fold_of.size()) != X.rows())
    throw InputError("filtered_linear_residuals: " + std::to_string(X.rows()) + " feature rows, " +
                     std::to_string(y.size()) + " labels, " + std::to_string(fold_of.size()) +
                     " fold indices (expected one of each per row)");
  const int d = static_cast<int>(X.cols());
  const int M = max_components <= 0 ? d : std::min(max_components, d);
  Eigen::MatrixXd residual = Eigen::MatrixXd::Constant(X.rows(), M, std::nan(""));
  bool any = false;
  for (const auto& [train, test] : fold_splits(fold_of, folds)) {
    if (test.empty() || train.size() < 2) continue;
    const Eigen::MatrixXd Xtr = select_rows(X, train), Xte = select_rows(X, test);
    const Eigen::VectorXd ytr = select_rows(y, train);
    const std::vector<int> order = rank_components(Xtr, ytr, ranking);
    const Eigen::MatrixXd pred =
        prefix_linear_predictions(select_columns(Xtr, order, M), ytr, select_columns(Xte, order, M), M);
    for (size_t k = 0; k < test.size(); ++k)
      residual.row(test[k]) = pred.row(static_cast<Eigen::Index>(k)).array() - y(test[k]);
    any = true;
  }
  if (!any) throw InputError("filtered_linear_residuals: no test rows in any fold");
  return residual;
}

Eigen::VectorXd filtered_linear_curve(const Eigen::MatrixXd& X, const Eigen::VectorXd& y,
                                      const std::vector<int>& fold_of, int folds, int max_components,
                                      ComponentRanking ranking) {
  const Eigen::MatrixXd r = filtered_linear_residuals(X, y, fold_of, folds, max_components, ranking);
  Eigen::VectorXd sse = Eigen::VectorXd::Zero(r.cols());
  Eigen::Index tested = 0;
  for (Eigen::Index i = 0; i < r.rows(); ++i)
    if (std::isfinite(r(i, 0))) sse += r.row(i).transpose().cwiseAbs2(), ++tested;
  return (sse / static_cast<double>(tested)).cwiseSqrt();
}

int choose_component_count(const Eigen::MatrixXd& residuals, CountSelection selection,
                           const std::vector<bool>& allowed) {
  if (!allowed.empty() && static_cast<Eigen::Index>(allowed.size()) != residuals.cols())
    throw InputError("choose_component_count: " + std::to_string(allowed.size()) + " candidate flags for " +
                     std::to_string(residuals.cols()) + " counts");
  std::vector<Eigen::Index> rows;
  for (Eigen::Index i = 0; i < residuals.rows(); ++i)
    if (residuals.row(i).allFinite()) rows.push_back(i);
  if (rows.empty() || residuals.cols() == 0)
    throw InputError("choose_component_count: no held-out residuals (expected at least one tested row)");
  const double n = static_cast<double>(rows.size());
  Eigen::VectorXd mse = Eigen::VectorXd::Zero(residuals.cols());
  for (Eigen::Index i : rows) mse += residuals.row(i).transpose().cwiseAbs2();
  mse /= n;
  for (Eigen::Index m = 0; m < mse.size(); ++m)
    if (!allowed.empty() && !allowed[m]) mse(m) = std::numeric_limits<double>::infinity();
  Eigen::Index best = 0;
  mse.minCoeff(&best);
  if (!std::isfinite(mse(best))) throw InputError("choose_component_count: no candidate count allowed");
  if (selection == CountSelection::minimum || rows.size() < 2) return static_cast<int>(best) + 1;
  // One-standard-error rule (Hastie, Tibshirani & Friedman, §7.10): the fewest components whose
  // cross-validated MSE is within one standard error of the minimum's. The standard error is
  // that of the mean of the per-row squared errors at the minimum.
  double var = 0;
  for (Eigen::Index i : rows) var += std::pow(residuals(i, best) * residuals(i, best) - mse(best), 2);
  const double se = std::sqrt(var / (n - 1) / n);
  for (Eigen::Index m = 0; m <= best; ++m)
    if (mse(m) <= mse(best) + se) return static_cast<int>(m) + 1;
  return static_cast<int>(best) + 1;
}

// ---- filtered linear ------------------------------------------------------------------------

void FilteredLinearRegressor::fit(const Eigen::MatrixXd& X, const Eigen::VectorXd& y,
                                  const std::vector<int>& groups) {
  check_regression_input(X, y, groups, 3, "filtered_linear");
  features_ = static_cast<int>(X.cols());
  const int cap = options_.max_components <= 0 ? features_ : std::min(options_.max_components, features_);
  weights_ = Eigen::VectorXd::Zero(cap);
  inner_curve_.resize(0);
  if (options_.fixed_components > 0) {
    weights_(std::min(options_.fixed_components, cap) - 1) = 1;
  } else {
    // Inner grouped cross-validation on these (training) rows only.
    int subjects = static_cast<int>(X.rows());
    if (!groups.empty()) {
      std::vector<int> g = groups;
      std::sort(g.begin(), g.end());
      subjects = static_cast<int>(std::unique(g.begin(), g.end()) - g.begin());
    }
    const int inner = options_.inner_folds <= 0 ? subjects : std::min(options_.inner_folds, subjects);
    if (inner < 2) throw InputError("filtered_linear: needs at least 2 subjects to choose the component count");
    const std::vector<int> fold_of =
        grouped_folds(groups, static_cast<int>(X.rows()), inner, options_.inner_seed);
    const Eigen::MatrixXd residuals = filtered_linear_residuals(X, y, fold_of, inner, cap, options_.ranking);
    inner_curve_ = (residuals.colwise().squaredNorm() / static_cast<double>(X.rows())).cwiseSqrt().transpose();
    std::vector<bool> allowed;
    if (options_.skip_interpolating_subsets) {
      allowed.assign(cap, false);
      for (int k = 1; k <= cap; ++k) allowed[k - 1] = k <= static_cast<int>(X.rows()) - 2 || k == features_;
      if (std::find(allowed.begin(), allowed.end(), true) == allowed.end()) allowed.clear();
    }
    if (options_.selection == CountSelection::stacked) {
      if (allowed.empty()) allowed.assign(cap, true);
      const Eigen::ArrayXd mse = inner_curve_.array().square();
      double best = std::numeric_limits<double>::infinity();
      for (int k = 0; k < cap; ++k)
        if (allowed[k]) best = std::min(best, mse(k));
      for (int k = 0; k < cap; ++k) allowed[k] = allowed[k] && mse(k) <= options_.competitive_factor * best;
      weights_ = stacking_weights(residuals, allowed);
      // Weights below 1e-6 are round-off of the non-negative solve: dropped, the rest rescaled.
      weights_ = (weights_.array() < 1e-6).select(0.0, weights_);
      weights_ /= weights_.sum();
    } else {
      weights_(choose_component_count(residuals, options_.selection, allowed) - 1) = 1;
    }
  }
  // The combined model: Σ_m w_m (eq. 10 on the top m components), again linear.
  const std::vector<int> order = rank_components(X, y, options_.ranking);
  full_gradient_ = Eigen::VectorXd::Zero(features_);
  offset_ = 0;
  int largest = 0;
  for (int m = 1; m <= cap; ++m) {
    const double w = weights_(m - 1);
    if (w <= 0) continue;
    const LinearFit f = fit_linear(select_columns(X, order, m), y);
    offset_ += w * f.offset;
    for (int k = 0; k < m; ++k) full_gradient_(order[k]) += w * f.gradient(k);
    largest = m;
  }
  kept_.assign(order.begin(), order.begin() + largest);
}

double FilteredLinearRegressor::predict(const Eigen::VectorXd& x) const {
  if (x.size() != features_)
    throw InputError("filtered_linear: expected " + std::to_string(features_) + " features, found " +
                     std::to_string(x.size()));
  return offset_ + full_gradient_.dot(x);
}

Eigen::VectorXd FilteredLinearRegressor::gradient(const Eigen::VectorXd& x) const {
  if (x.size() != features_)
    throw InputError("filtered_linear: expected " + std::to_string(features_) + " features, found " +
                     std::to_string(x.size()));
  return full_gradient_;
}

std::unique_ptr<Regressor> FilteredLinearRegressor::clone() const {
  return std::make_unique<FilteredLinearRegressor>(options_);
}

std::string FilteredLinearRegressor::describe() const {
  std::string counts;
  int used = 0;
  for (Eigen::Index m = 0; m < weights_.size(); ++m)
    if (weights_(m) > 0) {
      char part[48];
      std::snprintf(part, sizeof part, "%s%d (%.2f)", used++ ? " + " : "", static_cast<int>(m) + 1, weights_(m));
      counts += part;
    }
  if (used <= 1) return "kept " + std::to_string(kept_.size()) + " of " + std::to_string(features_) + " components";
  return "stacked counts " + counts + " of " + std::to_string(features_) + " components";
}

}  // namespace bodymodel
