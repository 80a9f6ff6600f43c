#include "model/pca.h"
#include "model/pca_float.h"

#include <Spectra/MatOp/DenseSymMatProd.h>
#include <Spectra/SymEigsSolver.h>

#include <Eigen/Eigenvalues>

#include "model/format.h"

#include "core/error.h"

namespace bodymodel {

void PcaOptions::validate() const {
  if (!(variance_threshold > 0 && variance_threshold <= 1))
    throw InputError(fmt::format("PCA variance_threshold must be in (0, 1], got {}", variance_threshold));
  if (max_components == 0 || max_components < -1)
    throw InputError(fmt::format("PCA max_components must be ≥ 1 or −1, got {}", max_components));
  if (eigen_solver == PcaEigenSolver::partial && max_components < 1)
    throw InputError("PCA: the partial eigen-solver needs max_components ≥ 1 (the components to find)");
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

namespace {

bool use_partial_eigen_solver(const PcaOptions& o, int N) {
  if (o.max_components <= 0 || o.eigen_solver == PcaEigenSolver::full) return false;
  if (o.eigen_solver == PcaEigenSolver::partial) return true;
  return N >= kPartialEigenMinSamples && o.max_components <= N / kPartialEigenMinRatio;
}

// The K leading eigenpairs of the symmetric G (descending, eigenvalues clamped at 0) by
// Lanczos iteration; false when it did not converge (the caller then solves in full).
bool partial_eigenpairs(const Eigen::MatrixXd& G, int K, Eigen::VectorXd& lambda, Eigen::MatrixXd& V) {
  const int N = static_cast<int>(G.rows());
  if (K < 1 || K >= N) return false;  // Spectra needs nev < n
  // Krylov subspace: Spectra's advice is ≥ 2·nev; a few more vectors converge in fewer restarts.
  const int ncv = std::min(N, std::max(2 * K + 1, K + 20));
  Spectra::DenseSymMatProd<double> op(G);
  Spectra::SymEigsSolver<Spectra::DenseSymMatProd<double>> eigs(op, K, ncv);
  eigs.init();  // fixed start vector: the result is reproducible
  eigs.compute(Spectra::SortRule::LargestAlge, 1000, 1e-12);
  if (eigs.info() != Spectra::CompInfo::Successful) return false;
  lambda = eigs.eigenvalues().cwiseMax(0.0);  // already descending
  V = eigs.eigenvectors();
  return true;
}

}  // namespace

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
  const int rank_limit = N - 1;
  Eigen::VectorXd lambda;  // descending, ≥ 0
  Eigen::MatrixXd V;       // N by lambda.size()
  double total = 0;        // Σ of all N eigenvalues
  const int wanted = options.max_components > 0 ? std::min(options.max_components, rank_limit) : rank_limit;
  if (use_partial_eigen_solver(options, N) && partial_eigenpairs(G, wanted, lambda, V)) {
    total = G.trace();  // = Σ of every eigenvalue, without computing them
  } else {
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(G);
    if (es.info() != Eigen::Success) throw NumericalError("PCA: eigen-decomposition of the Gram matrix failed");
    lambda = es.eigenvalues().reverse();
    V = es.eigenvectors().rowwise().reverse();
    for (int i = 0; i < N; ++i) lambda(i) = std::max(lambda(i), 0.0);
    total = lambda.sum();
  }
  const double tiny = 1e-12 * std::max(total, 1e-300);
  int K = 0;
  double acc = 0;
  const int cap = std::min<int>(wanted, static_cast<int>(lambda.size()));
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

Pca fit_pca(const Eigen::MatrixXf& X, const std::vector<int>& columns_in, const PcaOptions& options,
            PcaSummary* summary) {
  options.validate();
  const int D = static_cast<int>(X.rows());
  std::vector<int> columns = columns_in;
  if (columns.empty())
    for (int i = 0; i < X.cols(); ++i) columns.push_back(i);
  const int N = static_cast<int>(columns.size());
  if (N < 2) throw InputError(fmt::format("PCA needs at least 2 samples, got {}", N));
  for (int c : columns)
    if (c < 0 || c >= X.cols()) throw InputError(fmt::format("PCA: sample column {} out of range", c));
  constexpr int kBlock = 4096;  // rows per block: 4096 × N doubles (64 MB at N = 2 000)
  auto block_of = [&](int r0, int rows, Eigen::MatrixXd& B) {
    B.resize(rows, N);
    for (int j = 0; j < N; ++j) B.col(j) = X.block(r0, columns[j], rows, 1).cast<double>();
  };
  Pca p;
  p.mean = Eigen::VectorXd::Zero(D);
  Eigen::MatrixXd B;
  for (int r0 = 0; r0 < D; r0 += kBlock) {
    const int rows = std::min(kBlock, D - r0);
    block_of(r0, rows, B);
    if (!B.allFinite()) throw InputError("PCA: the samples contain non-finite values");
    p.mean.segment(r0, rows) = B.rowwise().mean();
  }
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(N, N);
  for (int r0 = 0; r0 < D; r0 += kBlock) {
    const int rows = std::min(kBlock, D - r0);
    block_of(r0, rows, B);
    B.colwise() -= p.mean.segment(r0, rows);
    G.selfadjointView<Eigen::Lower>().rankUpdate(B.transpose());
  }
  G = G.selfadjointView<Eigen::Lower>();
  G /= (N - 1);
  const int rank_limit = N - 1;
  Eigen::VectorXd lambda;
  Eigen::MatrixXd V;
  double total = 0;
  const int wanted = options.max_components > 0 ? std::min(options.max_components, rank_limit) : rank_limit;
  if (use_partial_eigen_solver(options, N) && partial_eigenpairs(G, wanted, lambda, V)) {
    total = G.trace();
  } else {
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(G);
    if (es.info() != Eigen::Success) throw NumericalError("PCA: eigen-decomposition of the Gram matrix failed");
    lambda = es.eigenvalues().reverse().cwiseMax(0.0);
    V = es.eigenvectors().rowwise().reverse();
    total = lambda.sum();
  }
  const double tiny = 1e-12 * std::max(total, 1e-300);
  int K = 0;
  double acc = 0;
  const int cap = std::min<int>(wanted, static_cast<int>(lambda.size()));
  while (K < cap && lambda(K) > tiny) {
    acc += lambda(K);
    ++K;
    if (total > 0 && acc / total >= options.variance_threshold - 1e-12) break;
  }
  if (K == 0) K = 1;
  p.eigenvalues = lambda.head(K);
  // Basis X_c v_k / ‖X_c v_k‖, with ‖X_c v_k‖ = √((N−1) λ_k); a zero-variance direction (all
  // samples equal) keeps a zero column, as fit_pca's does.
  Eigen::VectorXd scale(K);
  for (int k = 0; k < K; ++k) {
    const double n = std::sqrt((N - 1) * p.eigenvalues(k));
    scale(k) = n > 0 ? 1.0 / n : 0.0;
  }
  const Eigen::MatrixXd W = V.leftCols(K) * scale.asDiagonal();
  p.basis.resize(D, K);
  for (int r0 = 0; r0 < D; r0 += kBlock) {
    const int rows = std::min(kBlock, D - r0);
    block_of(r0, rows, B);
    B.colwise() -= p.mean.segment(r0, rows);
    p.basis.middleRows(r0, rows).noalias() = B * W;
  }
  // Coefficients X_cᵀ b_k = (N−1) G v_k / √((N−1) λ_k) = v_k √((N−1) λ_k).
  p.coefficients = V.leftCols(K) * (p.eigenvalues * (N - 1)).cwiseSqrt().asDiagonal();
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
