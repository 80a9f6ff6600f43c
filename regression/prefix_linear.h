// Eq. 10 of Hasler et al. 2009 (§4) fitted on every prefix of an ordered feature list at once:
// the building block of the filtered linear regressor's count selection. One QR factorisation
// of the ordered, centred training features gives the held-out predictions of all the nested
// models with fewer columns than training rows; past that (more components than rows, where
// eq. 10 is the minimum-norm interpolant) the n × n Gram matrix is updated one column at a time.
// The results equal fit_linear() on each prefix separately (tests/regression/linear_test.cc).
#pragma once

#include <Eigen/Core>

namespace bodymodel {

// Predictions of eq. 10 fitted on the first m columns of Xtr, for m = 1..M.
//   Xtr  #train by #features (columns in the order they are kept), ytr #train (label unit)
//   Xte  #test by #features (same columns)
//   M    number of prefixes, 1 ≤ M ≤ #features
// Returns #test by M: column m−1 holds the predictions of the fit on m columns (least squares
// when m ≤ #train − 1 with full column rank, minimum-norm otherwise, exactly as fit_linear()).
Eigen::MatrixXd prefix_linear_predictions(const Eigen::MatrixXd& Xtr, const Eigen::VectorXd& ytr,
                                          const Eigen::MatrixXd& Xte, int M);

}  // namespace bodymodel
