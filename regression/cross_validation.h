// k-fold cross-validation with subject-grouped folds (docs/evaluation.md#subject-grouped-folds):
// a subject's rows are never split between training and test. Seeded, so a run can be repeated
// exactly.
#pragma once

#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "regression/regressor.h"

namespace bodymodel {

// Fold of each row, in [0, folds).
//   groups  #rows subject index of each row, or empty (= every row its own subject)
//   rows    number of rows (used when groups is empty)
// The distinct subjects are shuffled with `seed` and dealt round-robin, so fold sizes (in subjects)
// differ by at most one. Throws InputError when folds < 2 or there are fewer subjects than folds.
std::vector<int> grouped_folds(const std::vector<int>& groups, int rows, int folds, unsigned seed);

// For each fold f: (training rows, test rows), from a fold index per row.
std::vector<std::pair<std::vector<int>, std::vector<int>>> fold_splits(const std::vector<int>& fold_of,
                                                                       int folds);

// Rows `idx` of X (#idx by #cols) / entries of y / of groups (empty stays empty).
Eigen::MatrixXd select_rows(const Eigen::MatrixXd& X, const std::vector<int>& idx);
Eigen::VectorXd select_rows(const Eigen::VectorXd& y, const std::vector<int>& idx);
std::vector<int> select_rows(const std::vector<int>& groups, const std::vector<int>& idx);

struct CrossValidationOptions {
  int folds = 10;     // Hasler et al. §5.1, Table 1: 10-fold cross-validation
  unsigned seed = 1;  // shuffles subjects into folds
};

struct CrossValidationSummary {
  std::string regressor, label;
  double rmse = 0;          // √(mean (ŷ − y)²) over all held-out predictions, label unit
  double mae = 0;           // mean |ŷ − y|, label unit
  int folds = 0;
  int samples = 0;          // rows evaluated
  int skipped_missing = 0;  // rows skipped because the label was NaN
  std::vector<int> rows;    // the rows evaluated (indices into the input)
  Eigen::VectorXd predictions;  // #rows evaluated: held-out prediction of each, label unit
  std::vector<std::string> fold_descriptions;  // the hyper-parameters chosen in each fold
};

// Rows of a label that can be used: the finite entries. Throws InputError, naming `label`, when
// fewer than `min_rows` remain or the remaining values are constant (nothing to regress).
std::vector<int> usable_label_rows(const Eigen::VectorXd& y, const std::string& label, int min_rows);

// Cross-validates a regressor (cloned for each fold) on one label.
//   X       #rows by #features;  y #rows (label unit, NaN = missing: those rows are skipped and
//           counted in skipped_missing);  groups #rows subject index, or empty.
// Throws InputError for a constant label, or fewer subjects with a value than folds.
CrossValidationSummary cross_validate(const Regressor& prototype, const Eigen::MatrixXd& X,
                                      const Eigen::VectorXd& y, const std::vector<int>& groups,
                                      const CrossValidationOptions& options = {},
                                      const std::string& label = "label");

// RMSE of ŷ against y (same size).
double root_mean_square_error(const Eigen::VectorXd& predicted, const Eigen::VectorXd& truth);

}  // namespace bodymodel
