// Decoding a relative rotation encoding back into a mesh: two sparse linear solves
// (Hasler et al. 2009 §3, METHOD.md §3).
//
//  1. Rotations. Unknown per-triangle matrices X_f ≈ T_f = R_fᵀ (3×3). Every stored relative
//     rotation R_fg = R_fᵀ R_g of an adjacent pair gives the equation R_fg X_g − X_f = 0 (the
//     paper's R_ij R_j − R_i = 0 in the inverse rotations, see relative_rotation_encoding.h);
//     one triangle per connected component is fixed to the global rotation (identity). The least-squares normal equations N X = b are the
//     same for the three columns of X, so X (3·#unknown by 3) is one solve with three right-hand
//     sides. N's diagonal blocks are constant (count·I) and its off-diagonal blocks are −R_fg −
//     R_gfᵀ: the VALUES change with every encoding, the SPARSITY PATTERN never does. The solver
//     therefore never re-analyses it: the default solver is conjugate gradients preconditioned
//     with the dual-graph Laplacian factorised once (exact in one iteration for encoded meshes,
//     see RotationSolver); the Cholesky path analyses the pattern once (symbolic factorisation,
//     AMD ordering) and only refactorises numerically per decode. Each X_fᵀ is then
//     orthonormalised by SVD (closest rotation) to give R_f.
//  2. Positions. With U_f = R_f S_f the target gradient of triangle f, minimise
//     Σ_f area_f ‖∇X|_f − U_f‖² (gradient-domain Poisson): K X = Gᵀ A B with K = Gᵀ A G the
//     cotangent Laplacian (up to sign), which depends only on the template: factorised once.
//     One vertex per component is fixed (translation); optional soft positional constraints add
//     w‖x_v − t_v‖² rows (the factorisation is redone only when the constrained vertex set or
//     the weights change).
//
// The decoder is built once per template and reused; it is not thread-safe (decode() reuses
// its factorisations and scratch memory): use one decoder per thread.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "encoding/relative_rotation_encoding.h"

namespace bodymodel {

// How the rotation system is solved (both give the least-squares solution).
enum class RotationSolver {
  // Preconditioned conjugate gradients (default, fastest; see the .cc): the preconditioner is
  // the dual-graph Laplacian L (topology only, factorised ONCE) in the gauge of rotations
  // propagated along a spanning tree, P = D (L ⊗ I₃) Dᵀ, D = blockdiag(T̃_f). For a consistent
  // encoding (any encoded mesh) P equals the system matrix and CG stops after one iteration.
  // Inconsistent encodings (blends, model samples, masked changes) accumulate holonomy that
  // this preconditioner does not capture: when CG has not reduced the residual below 1e-4
  // after 3 iterations (or reached cg_tolerance within cg_max_iterations) the decoder falls
  // back to kCholeskyRefactor (symbolic analysis done at the first fallback, then reused).
  kPreconditionedCG,
  // Sparse Cholesky (CHOLMOD, AMD ordering) of the 3·#F system: symbolic analysis once,
  // numeric refactorisation on every decode.
  kCholeskyRefactor,
};

struct DecoderOptions {
  RotationSolver rotation_solver = RotationSolver::kPreconditionedCG;
  // Conjugate gradients: stop when every column's residual ‖b − N X‖ ≤ tolerance · ‖b‖; after
  // max_iterations without convergence the decoder falls back to the Cholesky solve.
  double cg_tolerance = 1e-10;
  int cg_max_iterations = 20;
  // Reuse the symbolic analysis of the rotation system and the Poisson factorisation across
  // calls. false = the baseline that analyses and factorises everything on every call (only
  // useful for benchmarks).
  bool reuse_factorisations = true;
  // Without positional constraints the result is only defined up to a rigid motion; when true
  // it is rigidly aligned (Kabsch) to the template's rest vertices, so decoded meshes sit where
  // the template is. When false, the first triangle of each component keeps its rest
  // orientation and the first vertex of each component sits at the origin.
  bool align_to_template = true;
  // With positional constraints: first orient the unconstrained solution onto the targets
  // (rigid fit over the constrained vertices, needs ≥ 3), then solve with the constraints, so
  // the constraints only have to produce the non-rigid part of the change.
  bool orient_to_constraints = true;
  // Weight of a soft positional constraint when PositionConstraints::weights is empty,
  // relative to the cotangent weights (dimensionless). 1e4 makes the constraints near-hard
  // (a 50 mm handle move lands within ~0.1 mm on a body).
  double constraint_weight = 1e4;

  // Throws InputError describing the first invalid field.
  void validate() const;
};

// Soft positional constraints (paper §5.3 handles, §5.4 limb tips).
struct PositionConstraints {
  Eigen::VectorXi vertices;   // #C vertex indices
  Eigen::MatrixX3d targets;   // #C by 3 target positions (mm for bodies)
  Eigen::VectorXd weights;    // #C weights, or empty = DecoderOptions::constraint_weight
  bool empty() const { return vertices.size() == 0; }
};

// Wall-clock milliseconds of the last decode, by stage.
struct DecodeTiming {
  double assemble_ms = 0;        // encoding → matrices, rotation system values
  double rotation_solve_ms = 0;  // rotation system: CG iterations, or numeric factorisation + solve
  int cg_iterations = 0;         // CG iterations of the rotation solve (0 for Cholesky)
  double orthonormalise_ms = 0;  // per-triangle SVD
  double poisson_ms = 0;         // right-hand side + Poisson solve (+ factorisation if needed)
  double finish_ms = 0;          // alignment and checks
  double total_ms = 0;
};

class RelativeRotationDecoder {
 public:
  // One-time set-up: adjacency, components, pattern analysis of the rotation system,
  // Poisson factorisation.
  explicit RelativeRotationDecoder(std::shared_ptr<const EncodingTemplate> tmpl,
                                   DecoderOptions options = {});
  ~RelativeRotationDecoder();
  RelativeRotationDecoder(const RelativeRotationDecoder&) = delete;
  RelativeRotationDecoder& operator=(const RelativeRotationDecoder&) = delete;

  // Vertex positions (#V by 3) of an encoding. Throws InputError if the encoding does not fit
  // the template or has non-finite values; NumericalError if a solve fails (never NaN output).
  Eigen::MatrixX3d decode(const Encoding& e);
  // The same with soft positional constraints (no alignment to the template: the constraints
  // place the mesh).
  Eigen::MatrixX3d decode(const Encoding& e, const PositionConstraints& constraints);

  // The two stages on their own.
  //   slot_rotations 3·#F relative rotations (encoding_matrices); returns #F rotations R_f.
  std::vector<Eigen::Matrix3d> solve_rotations(const std::vector<Eigen::Matrix3d>& slot_rotations);
  //   R, S #F each; returns #V by 3 positions (first vertex of each component at the origin
  //   unless constrained).
  Eigen::MatrixX3d solve_positions(const std::vector<Eigen::Matrix3d>& R,
                                   const std::vector<Eigen::Matrix3d>& S,
                                   const PositionConstraints* constraints = nullptr);

  const DecodeTiming& last_timing() const { return timing_; }
  const EncodingTemplate& encoding_template() const { return *tmpl_; }
  const std::shared_ptr<const EncodingTemplate>& template_ptr() const { return tmpl_; }
  int component_count() const;

  struct Impl;

 private:
  void analyse_rotation_pattern();
  bool solve_rotations_cg(const std::vector<Eigen::Matrix3d>& slot_rotations,
                          const std::vector<Eigen::Matrix3d>& R_fixed, Eigen::MatrixXd& X);

  std::shared_ptr<const EncodingTemplate> tmpl_;
  DecoderOptions options_;
  std::unique_ptr<Impl> impl_;
  DecodeTiming timing_;
};

// One-off convenience: builds a decoder for `tmpl` and decodes `e`.
Eigen::MatrixX3d decode(std::shared_ptr<const EncodingTemplate> tmpl, const Encoding& e,
                        const DecoderOptions& options = {});

}  // namespace bodymodel
