#include "regression/prefix_linear.h"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"
#include "regression/linear.h"

namespace bodymodel {

Eigen::MatrixXd prefix_linear_predictions(const Eigen::MatrixXd& Xtr, const Eigen::VectorXd& ytr,
                                          const Eigen::MatrixXd& Xte, int M) {
  const Eigen::Index n = Xtr.rows(), d = Xtr.cols(), t = Xte.rows();
  if (ytr.size() != n || Xte.cols() != d)
    throw InputError("prefix_linear_predictions: training " + std::to_string(n) + "x" + std::to_string(d) +
                     " with " + std::to_string(ytr.size()) + " labels, test with " + std::to_string(Xte.cols()) +
                     " columns (expected one label per training row and the same columns)");
  if (n == 0 || M < 1 || M > d)
    throw InputError("prefix_linear_predictions: " + std::to_string(n) + " training rows, " + std::to_string(M) +
                     " prefixes of " + std::to_string(d) + " features (expected rows ≥ 1 and 1 ≤ M ≤ #features)");
  const Eigen::RowVectorXd x_mean = Xtr.leftCols(M).colwise().mean();
  const double y_mean = ytr.mean();
  const Eigen::MatrixXd Xc = Xtr.leftCols(M).rowwise() - x_mean;
  const Eigen::MatrixXd Zc = Xte.leftCols(M).rowwise() - x_mean;
  const Eigen::VectorXd yc = ytr.array() - y_mean;
  Eigen::MatrixXd pred(t, M);

  // Over-determined prefixes (m ≤ n − 1): Xc_m = Q_m R_m, so the fit's prediction at z is
  // z_mᵀ R_m⁻¹ (Qᵀy)_m = Σ_{k≤m} w_k c_k with w = R⁻ᵀ z, whose entries do not depend on m
  // (forward substitution), i.e. every prefix from one solve.
  const Eigen::Index L = std::min<Eigen::Index>(M, n - 1);
  Eigen::Index ok = 0;  // prefixes with a well-conditioned R (same rank rule as fit_linear)
  if (L > 0) {
    Eigen::HouseholderQR<Eigen::MatrixXd> qr(Xc.leftCols(L));
    const Eigen::MatrixXd R = qr.matrixQR().topLeftCorner(L, L).triangularView<Eigen::Upper>();
    const Eigen::VectorXd c = (qr.householderQ().transpose() * yc).head(L);
    const double rmax = R.diagonal().cwiseAbs().maxCoeff();
    const double tol = 1e-10 * std::max<double>(1.0, static_cast<double>(std::max(n, d))) * rmax;
    while (ok < L && std::abs(R(ok, ok)) > tol) ++ok;
    if (ok > 0) {
      const Eigen::MatrixXd W = R.topLeftCorner(ok, ok).transpose().triangularView<Eigen::Lower>().solve(
          Zc.leftCols(ok).transpose());  // ok by t
      Eigen::VectorXd acc = Eigen::VectorXd::Constant(t, y_mean);
      for (Eigen::Index k = 0; k < ok; ++k) {
        acc += W.row(k).transpose() * c(k);
        pred.col(k) = acc;
      }
    }
  }
  // Under-determined prefixes (m ≥ n): minimum-norm s = Xcᵀ G⁺ yc with the Gram matrix
  // G = Xc Xcᵀ (n × n, rank n − 1: its null space is the constant vector, which yc is orthogonal
  // to, so G⁺yc = (G + α·11ᵀ)⁻¹ yc). G and the test cross-products grow one column at a time.
  Eigen::Index m = ok;  // prefixes 1..ok done
  if (m == n - 1 && m < M) {
    // (G + α·11ᵀ) is factorised once and each new column is a rank-one update of the factor.
    const double alpha = std::max(Xc.squaredNorm() / static_cast<double>(n), 1e-300);
    Eigen::MatrixXd G = Xc.leftCols(m + 1) * Xc.leftCols(m + 1).transpose();
    Eigen::MatrixXd g = Xc.leftCols(m + 1) * Zc.leftCols(m + 1).transpose();  // n by t
    Eigen::LLT<Eigen::MatrixXd> llt(G + Eigen::MatrixXd::Constant(n, n, alpha / static_cast<double>(n)));
    for (; m < M; ++m) {
      if (m > n - 1) {
        G.noalias() += Xc.col(m) * Xc.col(m).transpose();
        g.noalias() += Xc.col(m) * Zc.col(m).transpose();
        llt.rankUpdate(Xc.col(m), 1.0);
      }
      if (llt.info() != Eigen::Success) break;
      const Eigen::VectorXd v = llt.solve(yc);
      // Rank below n − 1 (yc then need not lie in G's range): leave it to fit_linear.
      if (!v.allFinite() || (G * v - yc).norm() > 1e-6 * std::max(yc.norm(), 1e-300)) break;
      pred.col(m) = (g.transpose() * v).array() + y_mean;
    }
  }
  // Whatever is left (rank-deficient data): one fit_linear per prefix.
  for (; m < M; ++m) {
    const LinearFit f = fit_linear(Xtr.leftCols(m + 1), ytr);
    pred.col(m) = (Xte.leftCols(m + 1) * f.gradient).array() + f.offset;
  }
  return pred;
}

}  // namespace bodymodel
