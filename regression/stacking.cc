#include "regression/stacking.h"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/error.h"

namespace bodymodel {

Eigen::VectorXd lawson_hanson_nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
  if (A.rows() != b.size())
    throw InputError("lawson_hanson_nnls: " + std::to_string(A.rows()) + " rows but " +
                     std::to_string(b.size()) + " right-hand side entries");
  if (!A.allFinite() || !b.allFinite())
    throw InputError("lawson_hanson_nnls: non-finite entries in the system");
  const Eigen::Index n = A.cols();
  Eigen::VectorXd w = Eigen::VectorXd::Zero(n);
  if (n == 0) return w;
  std::vector<bool> passive(static_cast<size_t>(n), false);
  const double tol = 1e-12 * std::max((A.transpose() * b).cwiseAbs().maxCoeff(), 1e-300);
  // Least squares on the passive columns only.
  auto solve_passive = [&](std::vector<Eigen::Index>& idx) {
    idx.clear();
    for (Eigen::Index k = 0; k < n; ++k)
      if (passive[k]) idx.push_back(k);
    Eigen::MatrixXd As(A.rows(), static_cast<Eigen::Index>(idx.size()));
    for (size_t k = 0; k < idx.size(); ++k) As.col(static_cast<Eigen::Index>(k)) = A.col(idx[k]);
    return Eigen::VectorXd(As.colPivHouseholderQr().solve(b));
  };
  std::vector<Eigen::Index> idx;
  for (Eigen::Index outer = 0; outer < 3 * n + 10; ++outer) {
    const Eigen::VectorXd gradient = A.transpose() * (b - A * w);  // −½ ∂‖Aw − b‖²/∂w
    Eigen::Index enter = -1;
    double best = tol;
    for (Eigen::Index k = 0; k < n; ++k)
      if (!passive[k] && gradient(k) > best) best = gradient(k), enter = k;
    if (enter < 0) break;  // Kuhn–Tucker conditions hold
    passive[enter] = true;
    for (Eigen::Index inner = 0; inner < 3 * n + 10; ++inner) {
      const Eigen::VectorXd z = solve_passive(idx);
      if (!z.allFinite()) {
        passive[enter] = false;
        return w;
      }
      if ((z.array() > 0).all()) {
        w.setZero();
        for (size_t k = 0; k < idx.size(); ++k) w(idx[k]) = z(static_cast<Eigen::Index>(k));
        break;
      }
      // Step from w toward z until the first passive weight reaches zero, then drop it.
      double alpha = 1;
      for (size_t k = 0; k < idx.size(); ++k) {
        const double zk = z(static_cast<Eigen::Index>(k)), wk = w(idx[k]);
        if (zk <= 0) alpha = std::min(alpha, wk / std::max(wk - zk, 1e-300));
      }
      for (size_t k = 0; k < idx.size(); ++k) {
        double& wk = w(idx[k]);
        wk += alpha * (z(static_cast<Eigen::Index>(k)) - wk);
        if (wk <= 1e-14) wk = 0, passive[idx[k]] = false;
      }
      if (std::none_of(passive.begin(), passive.end(), [](bool p) { return p; })) break;
    }
  }
  return w.cwiseMax(0.0);
}

Eigen::VectorXd stacking_weights(const Eigen::MatrixXd& residuals, const std::vector<bool>& allowed) {
  const Eigen::Index K = residuals.cols();
  if (!allowed.empty() && static_cast<Eigen::Index>(allowed.size()) != K)
    throw InputError("stacking_weights: " + std::to_string(allowed.size()) + " candidate flags for " +
                     std::to_string(K) + " candidates");
  std::vector<Eigen::Index> rows, cand;
  for (Eigen::Index i = 0; i < residuals.rows(); ++i)
    if (residuals.row(i).allFinite()) rows.push_back(i);
  for (Eigen::Index k = 0; k < K; ++k)
    if (allowed.empty() || allowed[k]) cand.push_back(k);
  if (rows.empty()) throw InputError("stacking_weights: no held-out residuals (expected at least one tested row)");
  if (cand.empty()) throw InputError("stacking_weights: no candidate allowed");
  const Eigen::Index n = static_cast<Eigen::Index>(rows.size()), c = static_cast<Eigen::Index>(cand.size());
  // Σw = 1 by weighting (Lawson & Hanson ch. 22): one extra row s·(1 … 1 | 1) with s far above
  // the best candidate's residual norm, so the constraint holds to ~1e-6 before the final
  // rescaling (not the worst's: candidates at an interpolation peak can be 1e6 times worse).
  Eigen::MatrixXd A(n + 1, c);
  double smallest = std::numeric_limits<double>::infinity(), largest = 0;
  for (Eigen::Index j = 0; j < c; ++j) {
    for (Eigen::Index i = 0; i < n; ++i) A(i, j) = residuals(rows[i], cand[j]);
    const double norm = A.col(j).head(n).norm();
    smallest = std::min(smallest, norm), largest = std::max(largest, norm);
  }
  const double s = 1e3 * std::max({smallest, 1e-6 * largest, 1e-300});
  A.row(n).setConstant(s);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n + 1);
  b(n) = s;
  const Eigen::VectorXd v = lawson_hanson_nnls(A, b);
  Eigen::VectorXd w = Eigen::VectorXd::Zero(K);
  const double total = v.sum();
  if (total > 0 && std::isfinite(total)) {
    for (Eigen::Index j = 0; j < c; ++j) w(cand[j]) = v(j) / total;
  } else {  // degenerate: the single best candidate
    Eigen::Index best = 0;
    double best_sse = std::numeric_limits<double>::infinity();
    for (Eigen::Index j = 0; j < c; ++j)
      if (A.col(j).head(n).squaredNorm() < best_sse) best_sse = A.col(j).head(n).squaredNorm(), best = j;
    w(cand[best]) = 1;
  }
  return w;
}

}  // namespace bodymodel
