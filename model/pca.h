// Principal component analysis of high-dimensional samples through the N×N Gram matrix
// (Hasler et al. 2009 §4, docs/method.md §4.1): with N samples of dimension D ≫ N (encodings have
// D = 15·#F ≈ 400k numbers, N ≤ a few hundred) the eigenvectors of the D×D covariance are
// X_c·v / √((N−1)·λ) for the eigenpairs (λ, v) of G = X_cᵀX_c / (N−1). Cost O(N²·D).
#pragma once

#include <Eigen/Core>
#include <string>

namespace bodymodel {

// How the Gram matrix's eigenpairs are found.
enum class PcaEigenSolver {
  // The partial solver when few components of many samples are wanted (see fit_pca), else full.
  automatic,
  // Every eigenpair (Eigen's dense SelfAdjointEigenSolver, O(N³)).
  full,
  // Only the max_components leading ones (Spectra's Lanczos SymEigsSolver, O(N²) per iteration);
  // needs max_components ≥ 1. Falls back to the full solver if it does not converge.
  partial,
};

struct PcaOptions {
  // Keep the fewest leading components whose eigenvalues explain at least this fraction of the
  // total variance (the paper keeps "enough components"; 0.99 keeps nearly all of the shape
  // variation of a few dozen subjects while dropping the noise tail).
  double variance_threshold = 0.99;
  // Upper bound on the number of components (−1 = N − 1, the rank of centred data).
  int max_components = -1;
  PcaEigenSolver eigen_solver = PcaEigenSolver::automatic;
  // Throws InputError describing the first invalid field.
  void validate() const;
};

struct PcaSummary {
  int samples = 0;
  int dimension = 0;
  int components = 0;           // kept
  double explained = 0;         // fraction of the total variance the kept components explain
  double total_variance = 0;    // Σ of all eigenvalues
  std::string one_line() const;
};

// A fitted PCA: x ≈ mean + basis · c.
struct Pca {
  Eigen::VectorXd mean;         // D
  Eigen::MatrixXd basis;        // D by K, orthonormal columns
  Eigen::VectorXd eigenvalues;  // K, descending (variance of each coefficient)
  Eigen::MatrixXd coefficients; // N by K, coefficients of the training samples
  int dimension() const { return static_cast<int>(mean.size()); }
  int component_count() const { return static_cast<int>(basis.cols()); }
  // c = basisᵀ (x − mean); x of size D. Throws InputError on a size mismatch.
  Eigen::VectorXd project(const Eigen::VectorXd& x) const;
  // mean + basis · c (c of size K).
  Eigen::VectorXd reconstruct(const Eigen::VectorXd& c) const;
};

// PCA of the COLUMNS of X (D by N, one sample per column, N ≥ 2). Throws InputError for fewer
// than two samples or non-finite values. With PcaEigenSolver::automatic the partial solver is
// used when N ≥ kPartialEigenMinSamples and max_components ≤ N / kPartialEigenMinRatio:
// there the whole fit takes a fraction of the full solver's CPU with the same eigenpairs
// (bench/model_bench.cc BM_PcaEigen; measured in docs/benchmarks.md).
inline constexpr int kPartialEigenMinSamples = 200;
inline constexpr int kPartialEigenMinRatio = 10;
Pca fit_pca(const Eigen::MatrixXd& X, const PcaOptions& options = {}, PcaSummary* summary = nullptr);

}  // namespace bodymodel
