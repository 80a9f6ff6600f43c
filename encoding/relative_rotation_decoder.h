// Decoding a relative rotation encoding back into a mesh: two sparse linear solves
// (Hasler et al. 2009 §3, docs/method.md §3.4–§3.5).
//
//  1. Rotations. Unknown per-triangle matrices X_f ≈ T_f = R_fᵀ (3×3). Every stored relative
//     rotation R_fg = R_fᵀ R_g of an adjacent pair gives the equation R_fg X_g − X_f = 0 (the
//     paper's R_ij R_j − R_i = 0 in the inverse rotations, see relative_rotation_encoding.h);
//     one triangle per connected component is fixed to the global rotation (identity). The
//     least-squares normal equations N X = b are the same for the three columns of X, so X
//     (3·#unknown by 3) is one solve with three right-hand sides. N's diagonal blocks are
//     constant (count·I) and its off-diagonal blocks are −R_fg − R_gfᵀ: the VALUES change with
//     every encoding, the SPARSITY PATTERN never does.
//     Solve order (RotationSolver::kPreconditionedCG, the default):
//       a. integrate the R_fg along a spanning tree of the dual graph from the fixed triangle
//          (#F 3×3 products). If every equation then holds (max ‖R_fg T_g − T_f‖ ≤
//          DecoderOptions::consistency_tolerance) the encoding is realisable and T is the exact
//          least-squares solution (objective 0): no linear solve at all. Every encoded mesh and
//          every rebase/relative_to of one takes this path.
//       b. nearly consistent encodings (max equation residual ≤ cg_start_residual): conjugate
//          gradients from T, preconditioned with the dual-graph Laplacian (factorised once) in
//          the gauge of T.
//       c. otherwise (blends, model samples, masked changes: the relative rotations have
//          holonomy, so no flat gauge exists and the preconditioner above needs > 20 iterations
//          even in the gauge of the exact solution): sparse Cholesky of N as 3×3 blocks
//          (encoding/block_cholesky.h: AMD ordering, elimination tree and supernodes analysed
//          once at set-up, supernodal numeric factorisation per decode, parallel over disjoint
//          subtrees). Preconditioning with a factorisation kept from a reference encoding
//          (the set mean), even gauge-transformed by the exact solution's rotations, was
//          measured too: 55–60+ CG iterations on the body's blends, each costing a quarter of
//          a factorisation, because holonomy changes the magnitude (shrinkage) of the
//          least-squares solution, not only its rotations; so the decoder refactorises.
//     Each X_fᵀ is then orthonormalised (closest rotation) to give R_f.
//  2. Positions. With U_f = R_f S_f the target gradient of triangle f, minimise
//     Σ_f area_f ‖∇X|_f − U_f‖² (gradient-domain Poisson): K X = Gᵀ A B with K = Gᵀ A G the
//     cotangent Laplacian (up to sign), which depends only on the template: factorised once,
//     per decode one sparse product (the divergence Gᵀ A, precomputed) and a back-substitution
//     with three right-hand sides. One vertex per component is fixed (translation); optional
//     soft positional constraints add w‖x_v − t_v‖² rows (that factorisation is redone only
//     when the constrained vertex set or the weights change, and is cached).
//
// THREAD SAFETY: decode(), solve_rotations() and solve_positions() are const and may be called
// concurrently from several threads on ONE decoder (each call has its own workspace; the
// shared factorisations are only read; the per-call Cholesky factorisations come from a pool
// of pre-analysed solvers, one per concurrent caller; the constrained-Poisson cache is
// guarded). Concurrent calls give bit-identical results to sequential ones. last_timing() is
// the timing of the most recent call to finish (from any thread); pass a DecodeTiming* to
// decode() for the timing of one call.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "encoding/relative_rotation_encoding.h"

namespace bodymodel {

// How the rotation system is solved (both give the least-squares solution).
enum class RotationSolver {
  // Default: exact tree integration for realisable encodings, preconditioned conjugate
  // gradients for nearly consistent ones, else the Cholesky refactorisation (see above).
  kPreconditionedCG,
  // Always CHOLMOD's scalar sparse Cholesky (AMD ordering) of the 3·#F system: symbolic
  // analysis once, numeric refactorisation on every decode (the reference for tests and the
  // benchmark's baseline).
  kCholeskyRefactor,
};

struct DecoderOptions {
  RotationSolver rotation_solver = RotationSolver::kPreconditionedCG;
  // Tree integration: the encoding counts as realisable when every rotation equation holds to
  // this (max Frobenius norm of R_fg T_g − T_f; rounding in an encoded mesh gives ~1e-14).
  double consistency_tolerance = 1e-9;
  // Conjugate gradients are tried only when the largest equation residual of the tree
  // integration is at most this (above it they do not converge in a few iterations: Cholesky).
  double cg_start_residual = 1e-5;
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
  // (handles moved 50 mm land within a small fraction of a millimetre: docs/results.md#summary).
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
  // Which path solved the rotations: 0 exact tree integration (realisable encoding), 1 CG,
  // 2 Cholesky refactorisation (block Cholesky by default, CHOLMOD with kCholeskyRefactor).
  int rotation_path = 0;
  double orthonormalise_ms = 0;  // per-triangle SVD
  double poisson_ms = 0;         // right-hand side + Poisson solve (+ factorisation if needed)
  double finish_ms = 0;          // alignment and checks
  double total_ms = 0;
};

class RelativeRotationDecoder {
 public:
  // One-time set-up: adjacency, components, spanning tree, dual-graph Laplacian factorisation,
  // block-Cholesky analysis of the rotation system, Poisson factorisation.
  explicit RelativeRotationDecoder(std::shared_ptr<const EncodingTemplate> tmpl,
                                   DecoderOptions options = {});
  ~RelativeRotationDecoder();
  RelativeRotationDecoder(const RelativeRotationDecoder&) = delete;
  RelativeRotationDecoder& operator=(const RelativeRotationDecoder&) = delete;

  // Vertex positions (#V by 3) of an encoding. Throws InputError if the encoding does not fit
  // the template or has non-finite values; NumericalError if a solve fails (never NaN output).
  // Thread-safe (see the top of this file).
  Eigen::MatrixX3d decode(const Encoding& e) const;
  // The same with soft positional constraints (no alignment to the template: the constraints
  // place the mesh). `timing`, if given, receives this call's timing.
  Eigen::MatrixX3d decode(const Encoding& e, const PositionConstraints& constraints,
                          DecodeTiming* timing = nullptr) const;

  // The two stages on their own (thread-safe).
  //   slot_rotations 3·#F relative rotations (encoding_matrices); returns #F rotations R_f.
  std::vector<Eigen::Matrix3d> solve_rotations(
      const std::vector<Eigen::Matrix3d>& slot_rotations) const;
  //   R, S #F each; returns #V by 3 positions (first vertex of each component at the origin
  //   unless constrained).
  Eigen::MatrixX3d solve_positions(const std::vector<Eigen::Matrix3d>& R,
                                   const std::vector<Eigen::Matrix3d>& S,
                                   const PositionConstraints* constraints = nullptr) const;

  //   The unconstrained Poisson stage for `fields` target-gradient fields at once (the model
  //   fit's Jacobian columns): U holds fields × #F matrices U_f = R_f S_f, field j's at
  //   j·#F + f; returns #V by 3·fields positions (field j in columns 3j … 3j+2), as
  //   solve_positions(U_j, identities) would, in one pass through the factor.
  Eigen::MatrixXd solve_positions_many(const std::vector<Eigen::Matrix3d>& U, int fields) const;

  // Timing of the most recent call to finish (any thread).
  DecodeTiming last_timing() const;
  const EncodingTemplate& encoding_template() const { return *tmpl_; }
  const std::shared_ptr<const EncodingTemplate>& template_ptr() const { return tmpl_; }
  const DecoderOptions& options() const { return options_; }
  int component_count() const;

  struct Impl;

 private:
  std::vector<Eigen::Matrix3d> rotations(const std::vector<Eigen::Matrix3d>& slot_rotations,
                                         DecodeTiming& timing) const;
  bool rotations_cg(const std::vector<Eigen::Matrix3d>& slot_rotations,
                    const std::vector<Eigen::Matrix3d>& T, const Eigen::MatrixXd& b,
                    Eigen::MatrixXd& X, DecodeTiming& timing) const;
  Eigen::MatrixX3d positions(const std::vector<Eigen::Matrix3d>& R,
                             const std::vector<Eigen::Matrix3d>& S,
                             const PositionConstraints* constraints, DecodeTiming& timing) const;
  void set_last_timing(const DecodeTiming& t) const;

  std::shared_ptr<const EncodingTemplate> tmpl_;
  DecoderOptions options_;
  std::unique_ptr<Impl> impl_;
};

// One-off convenience: builds a decoder for `tmpl` and decodes `e`.
Eigen::MatrixX3d decode(std::shared_ptr<const EncodingTemplate> tmpl, const Encoding& e,
                        const DecoderOptions& options = {});

}  // namespace bodymodel
