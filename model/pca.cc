#include "model/pca.h"

#include <Eigen/Eigenvalues>
#include "model/format.h"

#include "core/error.h"

namespace bodymodel {

void PcaOptions::validate() const {
  if (!(variance_threshold > 0 && variance_threshold <= 1))
    throw InputError(fmt::format("PCA variance_threshold must be in (0, 1], got {}", variance_threshold));
  if (max_components == 0 || max_components < -1)
    throw InputError(fmt::format("PCA max_components must be ≥ 1 or −1, got {}", max_components));
}

std::string PcaSummary::one_line() const {
  return fmt::format("PCA of {} samples × {} values: kept {} components explaining {:.2f}% of the variance",
                     samples, dimension, components, 100 * explained);
}

Eigen::VectorXd Pca::project(const Eigen::VectorXd& x) const {
  if (x.size() != mean.size())
    throw InputError(fmt::format("PCA projection: expected a vector of {} values, got {}", mean.size(), x.size()));
  return basis.transpose() * (x - mean);
}

Eigen::VectorXd Pca::reconstruct(const Eigen::VectorXd& c) const {
  if (c.size() != basis.cols())
    throw InputError(fmt::format("PCA reconstruction: expected {} coefficients, got {}", basis.cols(), c.size()));
  return mean + basis * c;
}

Pca fit_pca(const Eigen::MatrixXd& X, const PcaOptions& options, PcaSummary* summary) {
  options.validate();
  const int D = static_cast<int>(X.rows()), N = static_cast<int>(X.cols());
  if (N < 2) throw InputError(fmt::format("PCA needs at least 2 samples, got {}", N));
  if (!X.allFinite()) throw InputError("PCA: the samples contain non-finite values");
  Pca p;
  p.mean = X.rowwise().mean();
  // Gram matrix of the centred samples (the centred copy costs D·N doubles; fine for the
  // few hundred scans of a database).
  Eigen::MatrixXd G(N, N);
  Eigen::MatrixXd Xc = X.colwise() - p.mean;
  G.noalias() = Xc.transpose() * Xc;
  G /= (N - 1);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(G);
  if (es.info() != Eigen::Success) throw NumericalError("PCA: eigen-decomposition of the Gram matrix failed");
  // Descending order.
  Eigen::VectorXd lambda = es.eigenvalues().reverse();
  Eigen::MatrixXd V = es.eigenvectors().rowwise().reverse();
  for (int i = 0; i < N; ++i) lambda(i) = std::max(lambda(i), 0.0);
  const double total = lambda.sum();
  int rank_limit = N - 1;
  const double tiny = 1e-12 * std::max(total, 1e-300);
  int K = 0;
  double acc = 0;
  int cap = options.max_components > 0 ? std::min(options.max_components, rank_limit) : rank_limit;
  while (K < cap && lambda(K) > tiny) {
    acc += lambda(K);
    ++K;
    if (total > 0 && acc / total >= options.variance_threshold - 1e-12) break;
  }
  if (K == 0) K = 1;  // all samples equal: one (zero-variance) direction keeps shapes valid
  p.eigenvalues = lambda.head(K);
  p.basis.resize(D, K);
  for (int k = 0; k < K; ++k) {
    Eigen::VectorXd b = Xc * V.col(k);
    double n = b.norm();
    if (n > 0) b /= n;
    p.basis.col(k) = b;
  }
  // Re-orthonormalise (numerical hygiene for nearly-degenerate eigenvalues).
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(p.basis);
  Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(D, K);
  for (int k = 0; k < K; ++k)
    if (Q.col(k).dot(p.basis.col(k)) < 0) Q.col(k) *= -1;
  p.basis = std::move(Q);
  p.coefficients = Xc.transpose() * p.basis;
  if (summary) {
    summary->samples = N;
    summary->dimension = D;
    summary->components = K;
    summary->total_variance = total;
    summary->explained = total > 0 ? p.eigenvalues.sum() / total : 1.0;
  }
  return p;
}

}  // namespace bodymodel
