// Model quality as statistical-shape-model papers measure it (Styner et al. 2003, "Evaluation
// of 3D correspondence methods for model building"; docs/model.md §3), for the relative-rotation
// model and for a plain vertex-position PCA built from the same meshes:
//
//   generalisation G(K)  how well the model describes meshes it never saw: the mean vertex error
//                        of the best K-component fit to each test mesh (model/fit.h for the
//                        rotation-invariant model; least squares for vertex PCA), both rigidly
//                        placed on the test mesh;
//   specificity S(K)     whether it generates only plausible bodies: the mean over random model
//                        samples (c_k ~ N(0, λ_k), k < K) of the distance to the NEAREST training
//                        mesh (mean vertex error after a rigid fit);
//   compactness C(K)     Σ_{k<K} λ_k / Σ_k λ_k, the fraction of the training variance the first
//                        K components carry (each model in its own space: encodings vs mm²).
//
// Everything takes arrays (meshes in mm, one topology); the verb eval-model reads files.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "core/geometry.h"
#include "core/progress.h"
#include "model/body_model.h"
#include "model/fit.h"
#include "model/pca.h"

namespace bodymodel {

// ---- the vertex-PCA baseline ---------------------------------------------------------------

// PCA of vertex positions (3·#V per mesh, x y z per vertex) of meshes rigidly aligned to a
// reference (the mean of the training meshes after aligning each to the first, then each
// re-aligned to that mean once more).
struct VertexPcaModel {
  Eigen::MatrixX3d reference;  // #V by 3
  Pca pca;                     // dimension 3·#V
  Eigen::MatrixX3d mesh(const Eigen::VectorXd& c) const;  // mean + basis·c (c ≤ K values)
};
// Keeps every component (variance threshold 1). Throws InputError for fewer than 2 meshes or
// meshes of different vertex counts.
VertexPcaModel build_vertex_pca(const std::vector<Eigen::MatrixX3d>& meshes);

struct VertexPcaFit {
  Eigen::VectorXd coefficients;  // K
  Eigen::MatrixX3d V;            // fitted mesh rigidly placed on the target
  Eigen::VectorXd vertex_error;  // #V
  int iterations = 0;
};
// min over c (K values) and a rigid motion of Σ_i ‖Q (m + B_K c)_i + t − y_i‖², by alternating
// the exact least-squares coefficients (B orthonormal: c = B_Kᵀ (Qᵀ(y − t) − m)) and the
// exact rigid fit (Kabsch) until no vertex moves by more than tolerance_mm.
VertexPcaFit fit_vertex_pca(const VertexPcaModel& model, const Eigen::MatrixX3d& target, int K,
                            int max_iterations = 50, double tolerance_mm = 1e-4);

// ---- the three measures --------------------------------------------------------------------

struct ModelQualityOptions {
  std::vector<int> components;      // K values (clamped to each model's count; empty = a default grid)
  int specificity_samples = 1000;
  // K values at which the specificity is computed (each costs specificity_samples decodes and
  // nearest-neighbour searches); empty = 5, 20 and each model's maximum (those ≤ it).
  std::vector<int> specificity_components;
  uint64_t seed = 1;
  bool vertex_baseline = true;
  ModelFitOptions fit;              // components field ignored (set per K)
};

// One row of results: a model at one K.
struct QualityRow {
  std::string model;                // "rre" or "vertex_pca"
  int components = 0;
  double generalisation_mean_mm = 0;  // mean over test meshes of each mesh's mean vertex error
  double generalisation_p95_mm = 0;   // 95th percentile over all vertices of all test meshes
  double generalisation_max_mm = 0;
  double specificity_mean_mm = 0, specificity_std_mm = 0;  // over samples (NaN when not computed)
  double compactness = 0;             // fraction of the training variance
  int unconverged_fits = 0;           // test meshes whose model fit stopped at its iteration cap
};

// Per test mesh and K (the generalisation's detail).
struct TestMeshError {
  std::string model, mesh;
  int components = 0;
  double mean_mm = 0, p95_mm = 0, max_mm = 0;
  double seconds = 0;                 // fit time
  // 1 / 0: the model fit (model/fit.h) converged / stopped at its iteration cap; −1: vertex PCA
  // (a closed-form fit with a rigid alignment, no cap to hit).
  int converged = -1;
  // The model fit's start error (mm) and its iterations (NaN / 0 for vertex PCA).
  double start_mm = std::numeric_limits<double>::quiet_NaN();
  int iterations = 0;
};

struct ModelQuality {
  std::vector<QualityRow> rows;       // rre rows then vertex_pca rows, K ascending
  std::vector<TestMeshError> per_mesh;
  // Raw pooled per-vertex errors by (model, K) for pooling over folds: rows' order.
  std::vector<std::vector<float>> pooled_errors;
  std::vector<std::vector<double>> specificity_samples_mm;  // per row (empty when not computed)
};

// The default K grid for a model with `max` components: 1, 2, 5, 10, 20, 40, 80, … below max,
// then max.
std::vector<int> default_component_grid(int max);

// Generalisation over `test` (named by `test_names`), specificity against `train`, compactness,
// for the full (pose and shape) sub-model of `model` and, unless disabled, a vertex PCA of
// `train`. All meshes in mm in the model's topology; `total_variance` of the RRE PCA (all
// eigenvalues; ≤ 0 = the kept eigenvalues' sum). Throws InputError for K < 1, an empty test
// set or a mesh of another vertex count (naming it).
ModelQuality evaluate_model_quality(const BodyModel& model, const std::vector<Eigen::MatrixX3d>& train,
                                    const std::vector<Eigen::MatrixX3d>& test,
                                    const std::vector<std::string>& test_names, double total_variance,
                                    const ModelQualityOptions& options = {}, const ProgressCallback& progress = {});

// Pools several evaluations (folds) into one table: generalisation means over all test meshes
// of all folds, p95 over all their vertices; specificity over all samples; compactness averaged
// over folds. Rows are matched by (model, K); a K missing from a fold is skipped there.
std::vector<QualityRow> pool_model_quality(const std::vector<ModelQuality>& folds);


}  // namespace bodymodel
