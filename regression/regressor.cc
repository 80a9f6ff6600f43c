#include "regression/regressor.h"

#include "core/error.h"
#include "regression/gaussian_process.h"
#include "regression/linear_regressors.h"
#include "regression/svr.h"

namespace bodymodel {

Eigen::VectorXd Regressor::predict_rows(const Eigen::MatrixXd& X) const {
  Eigen::VectorXd out(X.rows());
  for (Eigen::Index i = 0; i < X.rows(); ++i) out(i) = predict(X.row(i).transpose());
  return out;
}

std::vector<std::string> regressor_names() {
  return {"simple_linear", "filtered_linear", "svr", "gaussian_process"};
}

std::unique_ptr<Regressor> make_regressor(const std::string& name) {
  if (name == "simple_linear") return std::make_unique<SimpleLinearRegressor>();
  if (name == "filtered_linear") return std::make_unique<FilteredLinearRegressor>();
  if (name == "filtered_linear_by_s") {  // the paper's literal ranking: |s_j| of the full fit
    FilteredLinearRegressor::Options o;
    o.ranking = ComponentRanking::gradient;
    o.name = name;
    return std::make_unique<FilteredLinearRegressor>(o);
  }
  if (name == "filtered_linear_10fold") {  // count by inner 10-fold CV (the earlier default)
    FilteredLinearRegressor::Options o;
    o.inner_folds = 10;
    o.selection = CountSelection::minimum;
    o.name = name;
    return std::make_unique<FilteredLinearRegressor>(o);
  }
  if (name == "filtered_linear_select") {  // one count: the leave-one-out minimum (no stacking)
    FilteredLinearRegressor::Options o;
    o.selection = CountSelection::minimum;
    o.name = name;
    return std::make_unique<FilteredLinearRegressor>(o);
  }
  if (name == "svr") return std::make_unique<SvrRegressor>();
  if (name == "gaussian_process") return std::make_unique<GaussianProcessRegressor>();
  std::string known;
  for (const auto& n : regressor_names()) known += (known.empty() ? "" : ", ") + n;
  known += ", filtered_linear_by_s, filtered_linear_10fold, filtered_linear_select";
  throw InputError("unknown regressor '" + name + "' (expected one of " + known + ")");
}

void check_regression_input(const Eigen::MatrixXd& X, const Eigen::VectorXd& y,
                            const std::vector<int>& groups, int min_samples, const std::string& who) {
  if (X.rows() != y.size())
    throw InputError(who + ": X has " + std::to_string(X.rows()) + " rows but y has " +
                     std::to_string(y.size()) + " values (expected one label per row)");
  if (!groups.empty() && static_cast<Eigen::Index>(groups.size()) != X.rows())
    throw InputError(who + ": " + std::to_string(groups.size()) + " group indices for " +
                     std::to_string(X.rows()) + " rows (expected one subject index per row)");
  if (X.rows() < min_samples)
    throw InputError(who + ": " + std::to_string(X.rows()) + " samples, expected at least " +
                     std::to_string(min_samples));
  if (X.cols() == 0) throw InputError(who + ": no features (X has 0 columns)");
  if (!X.allFinite()) throw InputError(who + ": the features contain NaN or infinite values");
  if (!y.allFinite()) throw InputError(who + ": the label contains NaN or infinite values");
}

}  // namespace bodymodel
