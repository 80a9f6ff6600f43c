// Fitting a PCA body model to a mesh of its topology (docs/model.md §1): the coefficients c
// (and a rigid placement) that minimise the VERTEX error of the decoded body against the mesh,
//
//     E(c, Q, t) = Σ_i ‖Q v_i(c) + t − y_i‖²,     v(c) = decode(pca.mean + B_K c)
//
// (y the target's vertices, B_K the first K basis columns, decode = the two sparse solves of
// encoding/relative_rotation_decoder.h). Projecting the target's encoding onto the basis
// (c = B_Kᵀ (x − mean)) minimises the error in ENCODING space instead, where a small residual
// in every relative rotation adds up along the limbs into centimetres at the hands and feet
// (docs/results.md, model generalisation); the fit starts from that projection.
//
// Solver: Levenberg–Marquardt on (c, rigid motion) with the EXACT Jacobian of the decoder,
// computed in forward mode per coefficient (docs/model.md §1.2):
//   1. rotations: the decoder's least-squares system N(R̂) X = b(R̂) over the per-triangle
//      matrices X_f (one triangle fixed), differentiated w.r.t. the relative rotations
//      R̂_s = R̄_s exp(δ_s): N dX = Σ_s [g: dR̂_sᵀ X_f ; f: dR̂_s X_g], dR̂_s = R̂_s [J_r(δ_s) dδ_s]×,
//      one CHOLMOD factorisation of N per iteration and 3 right-hand sides per coefficient;
//   2. the closest rotation R_f of X_fᵀ = R_f P_f: dR_f = R_f [ν]×,
//      (tr P_f · I − P_f) ν = axial(R_fᵀ dM − dMᵀ R_f), dM = dX_fᵀ;
//   3. positions: the decoder's Poisson solve is linear in U_f = R_f S_f, so
//      dv = solve_positions(dR_f S_f + R_f dS_f).
// The gauge (fixed triangle, pinned vertex) differs from the template-aligned decode only by
// a rigid motion, which the rigid unknowns absorb: the step in c does not depend on it.
//
// Thread safety: fit() and evaluate() are const and may run concurrently on one fitter.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>
#include <string>
#include <vector>

#include "core/geometry.h"
#include "core/progress.h"
#include "encoding/relative_rotation_decoder.h"
#include "encoding/relative_rotation_encoding.h"
#include "model/pca.h"

namespace bodymodel {

struct ModelFitOptions {
  int components = -1;            // K: leading components used (−1 = all of the PCA's)
  int max_iterations = 20;        // Levenberg–Marquardt iterations (steps tried)
  // Each Jacobian (the costly part: a set of solves per component) also serves this many
  // further steps, with the residual and the rigid columns recomputed (a chord step); a chord
  // step that fails, or that would stop the fit, is retried with a fresh Jacobian. 0 = a fresh
  // Jacobian every step.
  int jacobian_reuse = 2;
  // Stop when an accepted step lowers the sum of squared vertex errors by less than this
  // fraction of it (or after a step that changes no vertex by more than step_tolerance_mm).
  double relative_tolerance = 1e-4;
  double step_tolerance_mm = 1e-4;
  // Optional Gaussian prior on the coefficients: adds prior_weight · Σ_k c_k² / λ_k to E
  // (mm², per unit Mahalanobis norm²). 0 = the plain best fit (what generalisation measures).
  double prior_weight = 0;
  // Start from the projection of the target's encoding (true) or from the mean body (c = 0),
  // unless `start` is given (its coefficients, the rest 0: e.g. a fit with fewer components).
  bool start_from_projection = true;
  Eigen::VectorXd start;
  // Also try each training sample's coefficients (the PCA's `coefficients`, first K) as the
  // start: each is decoded once and the fit starts from whichever of them and the start above
  // lies closest to the target (lowest E). A projection far from the target (a pose whose
  // encoding residuals add up along the limbs) then gives way to the nearest training pose.
  bool try_training_starts = false;
  // Continuation: first fit only the leading `continuation_components` (0 = off) to a looser
  // relative tolerance, then all K. The Jacobian costs one solve per component, so the many
  // iterations a far start needs are cheap; the final answer is the K-component fit's.
  int continuation_components = 16;
  double continuation_tolerance = 1e-2;
  // At most this many of max_iterations go to the continuation stage: on FAUST it otherwise
  // crawled for 12 of 20 iterations at ≈ 1 % per step while every decode costs as much as at K.
  int continuation_iterations = 4;
  // Rotation system solved with CHOLMOD's supernodal Cholesky and the Jacobian's right-hand
  // sides 32 coefficients per (serial) solve, as before the block solver: the same numbers to
  // rounding, kept as the benchmark's baseline and a cross-check in tests.
  bool reference_solver = false;
  void validate() const;  // InputError naming the field
};

struct ModelFitSummary {
  int components = 0;
  int iterations = 0;             // steps (loop iterations)
  int jacobians = 0;              // Jacobian evaluations
  int evaluations = 0;            // decodes (residual evaluations), including rejected steps
  // Whether the fit stopped at a minimum (to the tolerances) rather than at max_iterations; a fit
  // that did not converge returns its last accepted point and says why in stop_reason.
  bool converged = false;
  std::string stop_reason;
  double start_mean_mm = 0;       // mean vertex error at the start (projection or mean body)
  // With try_training_starts: the training sample the fit started from (row of the PCA's
  // coefficients), −1 when the projection (or the given start) was closer.
  int start_sample = -1;
  double mean_mm = 0, rms_mm = 0, p95_mm = 0, max_mm = 0;  // final vertex error (target units)
  double seconds = 0;
  // Wall seconds in decodes (factorisation of the rotation system + solves) and in Jacobians:
  // where a fit's time goes (docs/model.md §5.6).
  double decode_seconds = 0, jacobian_seconds = 0;
  std::vector<double> history_mean_mm;  // mean vertex error after each iteration (start first)
  std::string report() const;     // one line, ending in "converged (...)" or "NOT CONVERGED (...)"
};

struct ModelFit {
  Eigen::VectorXd coefficients;   // K
  Eigen::MatrixX3d V;             // #V by 3: the fitted body rigidly placed on the target
  Eigen::VectorXd vertex_error;   // #V: ‖V_i − y_i‖ (target units)
  ModelFitSummary summary;
};

class ModelFitter {
 public:
  // `pca` is a PCA of encodings relative to `mean` on `tmpl` (a BodyModel's SubModel::pca);
  // it must outlive the fitter. Throws InputError when its dimension is not 15·#F or the
  // template's triangles are not one connected surface (one rigid placement per fit).
  ModelFitter(std::shared_ptr<const EncodingTemplate> tmpl, std::shared_ptr<const EncodingMean> mean,
              const Pca& pca);
  ~ModelFitter();
  ModelFitter(const ModelFitter&) = delete;
  ModelFitter& operator=(const ModelFitter&) = delete;

  // Fits the first K components to `target` (#V by 3, the template's vertex order; any
  // units: the error is reported in the target's units). Throws InputError for a wrong vertex
  // count, non-finite coordinates or K larger than the PCA; NumericalError if a solve fails.
  ModelFit fit(const Eigen::MatrixX3d& target, const ModelFitOptions& options = {},
               const ProgressCallback& progress = {}) const;

  // The projection of `V`'s encoding onto the first K components (the fit's start).
  Eigen::VectorXd project(const Eigen::MatrixX3d& V, int K) const;

  // Decoded vertices (#V by 3) of coefficients c (size ≤ the PCA's components; missing ones 0)
  // in the solver's gauge (triangle 0 keeps its rest orientation, vertex 0 at the origin), and
  // optionally their Jacobian J (3·#V by size(c), row 3i + d = coordinate d of vertex i).
  // reference_solver: as ModelFitOptions::reference_solver.
  Eigen::MatrixX3d evaluate(const Eigen::VectorXd& c, Eigen::MatrixXd* J = nullptr,
                            bool reference_solver = false) const;

  const RelativeRotationDecoder& decoder() const { return decoder_; }
  int max_components() const { return pca_.component_count(); }

  struct Impl;

 private:
  struct Workspace;
  // Decoded vertices of c (solver gauge); keeps the state and factorisation in ws.
  Eigen::MatrixX3d solve(Workspace& ws, const Eigen::VectorXd& c) const;
  // The fit's start (K coefficients): options.start, the projection or the mean body, or with
  // try_training_starts the training sample's coefficients that lie closer (summary.start_sample;
  // the candidates' decodes are counted in the summary).
  Eigen::VectorXd start_point(const Eigen::MatrixX3d& Y, int K, const ModelFitOptions& options,
                              ModelFitSummary& summary) const;
  // Jacobian (3·#V by K) at the state of the last solve(ws, ·).
  void jacobian(Workspace& ws, int K, Eigen::MatrixXd& J) const;
  std::shared_ptr<const EncodingTemplate> tmpl_;
  std::shared_ptr<const EncodingMean> mean_;
  const Pca& pca_;
  RelativeRotationDecoder decoder_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bodymodel
