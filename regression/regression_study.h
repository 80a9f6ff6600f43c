// The whole regressor comparison of Hasler et al. 2009 §5.1 on one feature matrix: every
// regressor × every label cross-validated with the same subject-grouped folds (Table 1), the
// spread of morph directions across subjects (Table 2), and the filtered model's RMSE against the
// number of kept components. Parallel over (label, regressor, fold) with TBB.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/progress.h"
#include "regression/cross_validation.h"
#include "regression/morph_directions.h"

namespace bodymodel {

struct RegressionStudyOptions {
  std::vector<std::string> regressors = regressor_names();  // names for make_regressor
  CrossValidationOptions cross_validation;                  // 10 folds (Table 1), seed 1
  int jobs = 0;                      // worker threads; 0 = all cores
  bool directions = true;            // compute Table 2 (fits each regressor on all rows)
  bool filtered_curve = true;        // RMSE against kept components (outer folds)
  int curve_max_components = 0;      // ≤ 0 = all features
};

struct DirectionResult {
  std::string regressor, label;
  MorphDirectionSpread spread;
};

struct RegressionStudy {
  std::vector<std::string> labels;
  std::vector<CrossValidationSummary> results;   // regressor-major: results[r·#labels + l]
  std::vector<DirectionResult> directions;       // one per regressor × label (if requested)
  std::vector<Eigen::VectorXd> filtered_curves;  // per label: RMSE for 1..M kept components
  double seconds = 0;

  const CrossValidationSummary& result(const std::string& regressor, const std::string& label) const;
};

// X #rows by #features (PCA coefficients); Y #rows by #labels (NaN = missing, rows skipped per
// label); labels #labels names; groups #rows subject index (or empty: one subject per row).
// Throws InputError (naming the label) for a constant label or fewer subjects than folds.
RegressionStudy run_regression_study(const Eigen::MatrixXd& X, const Eigen::MatrixXd& Y,
                                     const std::vector<std::string>& labels,
                                     const std::vector<int>& groups,
                                     const RegressionStudyOptions& options = {},
                                     const ProgressCallback& progress = {});

}  // namespace bodymodel
