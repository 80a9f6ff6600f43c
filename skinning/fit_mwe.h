// Fitting Multi-Weight Enveloping (Wang & Phillips 2002, §3–4) exactly as the paper specifies.
// Per vertex (§4) and per output dimension j (eq. 4–5), with the vertex's n influence bones:
//   A (m by 4n):  A[p, 4k+i] = μ_k (M_k(p))_ji ṽ_i           one row per unique pose
//   b (m):        b[p] = q_p,j − base_p,j                   delta space over a base rig (§4.5)
//  1. duplicate poses (the vertex's bone matrices equal within a tolerance) are averaged (§4);
//  2. per-pose weights ω_p scale rows of A and b (§4.2); influence maps μ_k scale columns (§4.2);
//  3. PCA on the columns of A: eigenvectors of the covariance of A's columns, largest first; keep
//     p of them, E = [e_1 … e_p], C = A E (§4.3);
//  4. local ridge regression (C ᵀC + Λ) w_c = Cᵀ b with λ_h = s / σ²(c_h), σ²(c_h) the variance
//     of column h of C, and w_c,h = 0 when σ²(c_h) = 0 (eq. 8–9);
//  5. solve by SVD, dropping singular values below a relative tolerance (§4.4); w = E w_c.
// The base (SSD or the vertex's best rigid bone) is folded into the stored 12 weights per slot.
// Extension (issue 26): the underlying system may also be an Animation Space rig fitted to the
// same examples — §4.5 allows any underlying rig; AS is folded in as W_k[j][i] = p_k,i / ṽ_i
// (where a rest coordinate ṽ_i is exactly 0 the SSD weight is folded instead, and the delta fit
// sees the folded base's positions, so the stored rig reproduces what was fitted).
// Several ridge scales s can be solved at once (fit_mwe_path): per vertex and dimension the
// ridge system is diagonalised once, S = Λ^{-1/2} CᵀC Λ^{-1/2} = Q diag(μ) Qᵀ with Λ the
// diagonal of 1/σ²(c_h), so (CᵀC + sΛ)⁻¹ = Λ^{-1/2} Q diag(1/(μ + s)) Qᵀ Λ^{-1/2} for every s;
// eigenvalues μ + s below the tolerance of the largest are dropped (the pseudo-inverse of §4.4,
// taken in the scaled basis — identical to the SVD solve whenever nothing is dropped).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/progress.h"
#include "skinning/skinning_examples.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

enum class MweBase { none, rigid, lbs, animation_space };

struct MweFitOptions {
  // Principal components kept per vertex and dimension (p of §4.3); 0 = keep as many as needed
  // to explain `variance_kept` of the variance. Components with zero variance are always dropped
  // (λ_h = ∞). Defaults from our horse sensitivity grid (README): keeping every component with
  // non-zero variance and letting the local ridge damp the weak ones generalised best.
  int components = 0;
  double variance_kept = 1.0;
  // s of eq. 9, λ_h = s / σ²(c_h). σ² and CᵀC carry (data unit)², so s carries (data unit)⁴;
  // with ridge_scale_relative the s used is ridge_scale · d⁴ (d = rest bounding-box diagonal),
  // which makes the default independent of the data's unit. Horse grid optimum: s ≈ 1e-8 in
  // Sumner's units (d = 1.5168), i.e. 2e-9 relative.
  double ridge_scale = 2e-9;
  bool ridge_scale_relative = true;
  // SVD solve: singular values below this fraction of the largest are dropped (§4.4).
  double singular_value_tolerance = 1e-8;
  // Poses whose bone matrices (for the vertex's bones) differ by at most this much in every entry
  // (translations divided by the rest bounding-box diagonal) are duplicates and averaged (§4).
  double duplicate_tolerance = 1e-6;
  // The underlying system of §4.5: MWE learns the refinement over it.
  MweBase base = MweBase::lbs;
  // Scale columns by the base SSD weights as influence maps μ_k (§4.2), floored at this value;
  // 0 = μ_k = 1 for every influence (no scaling).
  double influence_map_floor = 0.0;
  // Influences when no base rig is given: SSD fitted with this many slots.
  int max_influences = 4;
  // Influences whose 12 weights are refined (the largest SSD weights first); 0 = all slots.
  // Fewer columns per vertex is the "weight count" regulariser of the paper's §4.3 discussion.
  int delta_influences = 0;
  // Ridge λ of the Animation Space base (MweBase::animation_space; see fit_animation_space.h).
  double base_as_ridge = 1e-4;
};

struct MweFitSummary {
  int vertices = 0, poses = 0, unique_poses_min = 0, max_influences = 0;
  double mean_components = 0;   // average p kept per vertex and dimension
  double rms_residual = 0, max_residual = 0;
  double seconds = 0;           // MWE solve only (excludes fitting the base)
  double base_seconds = 0;
  std::string brief() const;
};

// base_lbs: SSD rig fitted to the same examples (influence sets, base and influence maps); nullptr
// = fit one here with options.max_influences.
SkinningRig fit_mwe(const SkinningExamples& ex, const SkinningRig* base_lbs = nullptr,
                    const MweFitOptions& options = {}, MweFitSummary* summary = nullptr,
                    const ProgressCallback& progress = {});

// One rig per ridge scale in `ridge_scales` (each used as options.ridge_scale), sharing the base,
// the duplicate grouping, the PCA and the diagonalisation: the cost of about one fit. The
// summary describes the last scale.
std::vector<SkinningRig> fit_mwe_path(const SkinningExamples& ex, const SkinningRig* base_lbs,
                                      const MweFitOptions& options, const std::vector<double>& ridge_scales,
                                      MweFitSummary* summary = nullptr, const ProgressCallback& progress = {});

// An Animation Space rig written as an MWE rig (W_k[j][i] = p_k,i / ṽ_i; `lbs` supplies the weight
// folded where ṽ_i = 0). Same influences as `as_rig`.
SkinningRig animation_space_as_mwe(const SkinningRig& as_rig, const SkinningRig& lbs);

}  // namespace bodymodel
