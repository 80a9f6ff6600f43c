// PCA of samples held as float32, for databases too large to hold as doubles (model/pca.h for
// the PCA itself and its options).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "model/pca.h"

namespace bodymodel {

// fit_pca for samples held as float32 (D by N_all; the columns listed in `columns` are the N
// samples, all when empty), for databases whose encodings do not fit in memory as doubles
// (2 000 bodies × 400 000 values = 6.4 GB as double, 3.2 GB as float). Computed in double, a
// block of rows at a time: the mean, the centred Gram matrix Σ_blocks B_cᵀ B_c, its eigenpairs
// (as fit_pca), the basis X_c V Λ^{-1/2} and the training coefficients V √((N−1)Λ) (exact for
// that basis). Memory beyond X: the D by K basis and one block. There is no QR pass: the
// columns are orthogonal to rounding because the Gram matrix is accumulated in double
// (measured in tests/model/pca_semantic_test.cc against fit_pca).
Pca fit_pca(const Eigen::MatrixXf& X, const std::vector<int>& columns, const PcaOptions& options = {},
            PcaSummary* summary = nullptr);
}  // namespace bodymodel
