#include "regression/cross_validation.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "core/error.h"

namespace bodymodel {

std::vector<int> grouped_folds(const std::vector<int>& groups, int rows, int folds, unsigned seed) {
  if (!groups.empty() && static_cast<int>(groups.size()) != rows)
    throw InputError("grouped_folds: " + std::to_string(groups.size()) + " group indices for " +
                     std::to_string(rows) + " rows");
  if (folds < 2) throw InputError("cross-validation needs at least 2 folds, got " + std::to_string(folds));
  std::vector<int> subject_of(rows);
  std::vector<int> distinct;
  if (groups.empty()) {
    for (int i = 0; i < rows; ++i) subject_of[i] = i;
    distinct = subject_of;
  } else {
    subject_of = groups;
    distinct = groups;
    std::sort(distinct.begin(), distinct.end());
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
  }
  if (static_cast<int>(distinct.size()) < folds)
    throw InputError("cross-validation: " + std::to_string(distinct.size()) +
                     " subjects but " + std::to_string(folds) +
                     " folds (expected at least one subject per fold; lower --folds)");
  std::mt19937_64 rng(seed);
  std::shuffle(distinct.begin(), distinct.end(), rng);
  std::map<int, int> fold_of_subject;
  for (size_t k = 0; k < distinct.size(); ++k) fold_of_subject[distinct[k]] = static_cast<int>(k % folds);
  std::vector<int> fold_of(rows);
  for (int i = 0; i < rows; ++i) fold_of[i] = fold_of_subject.at(subject_of[i]);
  return fold_of;
}

std::vector<std::pair<std::vector<int>, std::vector<int>>> fold_splits(const std::vector<int>& fold_of,
                                                                       int folds) {
  std::vector<std::pair<std::vector<int>, std::vector<int>>> out(folds);
  for (int i = 0; i < static_cast<int>(fold_of.size()); ++i)
    for (int f = 0; f < folds; ++f) (fold_of[i] == f ? out[f].second : out[f].first).push_back(i);
  return out;
}

namespace {
// The rows are checked, not trusted: a groups list shorter than X once made cross_validate read
// past its end.
void check_rows(const std::vector<int>& idx, Eigen::Index n, const char* what) {
  for (int i : idx)
    if (i < 0 || i >= n)
      throw InputError("select_rows: row " + std::to_string(i) + " of " + what + " requested, it has " +
                       std::to_string(n) + " rows");
}
}  // namespace

Eigen::MatrixXd select_rows(const Eigen::MatrixXd& X, const std::vector<int>& idx) {
  check_rows(idx, X.rows(), "a matrix");
  Eigen::MatrixXd out(idx.size(), X.cols());
  for (size_t k = 0; k < idx.size(); ++k) out.row(k) = X.row(idx[k]);
  return out;
}

Eigen::VectorXd select_rows(const Eigen::VectorXd& y, const std::vector<int>& idx) {
  check_rows(idx, y.size(), "a vector");
  Eigen::VectorXd out(idx.size());
  for (size_t k = 0; k < idx.size(); ++k) out(k) = y(idx[k]);
  return out;
}

std::vector<int> select_rows(const std::vector<int>& groups, const std::vector<int>& idx) {
  if (groups.empty()) return {};
  check_rows(idx, static_cast<Eigen::Index>(groups.size()), "groups");
  std::vector<int> out(idx.size());
  for (size_t k = 0; k < idx.size(); ++k) out[k] = groups[idx[k]];
  return out;
}

double root_mean_square_error(const Eigen::VectorXd& predicted, const Eigen::VectorXd& truth) {
  if (predicted.size() == 0) return 0;
  return std::sqrt((predicted - truth).squaredNorm() / static_cast<double>(predicted.size()));
}

std::vector<int> usable_label_rows(const Eigen::VectorXd& y, const std::string& label, int min_rows) {
  std::vector<int> rows;
  for (Eigen::Index i = 0; i < y.size(); ++i)
    if (std::isfinite(y(i))) rows.push_back(static_cast<int>(i));
  if (static_cast<int>(rows.size()) < min_rows)
    throw InputError("label '" + label + "': only " + std::to_string(rows.size()) + " of " +
                     std::to_string(y.size()) + " values are present (expected at least " +
                     std::to_string(min_rows) + ")");
  double lo = y(rows.front()), hi = lo;
  for (int i : rows) lo = std::min(lo, y(i)), hi = std::max(hi, y(i));
  if (hi - lo <= 1e-12 * std::max(1.0, std::abs(hi)))
    throw InputError("label '" + label + "' is constant (every present value is " +
                     std::to_string(lo) + "): there is nothing to regress");
  return rows;
}

CrossValidationSummary cross_validate(const Regressor& prototype, const Eigen::MatrixXd& X,
                                      const Eigen::VectorXd& y, const std::vector<int>& groups,
                                      const CrossValidationOptions& options, const std::string& label) {
  if (X.rows() != y.size())
    throw InputError("cross_validate: X has " + std::to_string(X.rows()) + " rows but label '" +
                     label + "' has " + std::to_string(y.size()) + " values");
  if (!groups.empty() && static_cast<Eigen::Index>(groups.size()) != X.rows())
    throw InputError("cross_validate: groups has " + std::to_string(groups.size()) + " entries but X has " +
                     std::to_string(X.rows()) + " rows (expected one subject index per row, or none)");
  if (X.cols() == 0) throw InputError("cross_validate: X has no columns (expected at least one feature)");
  if (!X.allFinite()) throw InputError("cross_validate: X contains NaN or infinite values");
  const std::vector<int> rows = usable_label_rows(y, label, 2);
  const Eigen::MatrixXd Xu = select_rows(X, rows);
  const Eigen::VectorXd yu = select_rows(y, rows);
  const std::vector<int> gu = select_rows(groups, rows);
  std::vector<int> fold_of;
  try {
    fold_of = grouped_folds(gu, static_cast<int>(rows.size()), options.folds, options.seed);
  } catch (const InputError& e) {
    throw InputError("label '" + label + "': " + e.what());
  }

  CrossValidationSummary s;
  s.regressor = prototype.name();
  s.label = label;
  s.folds = options.folds;
  s.samples = static_cast<int>(rows.size());
  s.skipped_missing = static_cast<int>(y.size() - rows.size());
  s.rows = rows;
  s.predictions.resize(rows.size());
  for (const auto& [train, test] : fold_splits(fold_of, options.folds)) {
    auto r = prototype.clone();
    r->fit(select_rows(Xu, train), select_rows(yu, train), select_rows(gu, train));
    for (int i : test) s.predictions(i) = r->predict(Xu.row(i).transpose());
    s.fold_descriptions.push_back(r->describe());
  }
  if (!s.predictions.allFinite())
    throw NumericalError("cross_validate: " + s.regressor + " produced a non-finite prediction for '" +
                         label + "'");
  s.rmse = root_mean_square_error(s.predictions, yu);
  s.mae = (s.predictions - yu).cwiseAbs().mean();
  return s;
}

}  // namespace bodymodel
