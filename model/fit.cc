#include "model/fit.h"

#include "core/statistics.h"

#include <Eigen/CholmodSupport>
#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numeric>
#include <tbb/parallel_for.h>
#if defined(__x86_64__)
#include <immintrin.h>
#endif


#include "core/error.h"
#include "encoding/block_cholesky.h"
#include "encoding/deformation_gradient.h"
#include "model/format.h"

namespace bodymodel {

namespace {

using SparseMatrixd = Eigen::SparseMatrix<double>;
using Cholesky = Eigen::CholmodSupernodalLLT<SparseMatrixd, Eigen::Lower>;

Eigen::Matrix3d skew(const Eigen::Vector3d& w) {
  Eigen::Matrix3d S;
  S << 0, -w(2), w(1), w(2), 0, -w(0), -w(1), w(0), 0;
  return S;
}

// Right Jacobian of SO(3): exp(φ + ε) ≈ exp(φ) exp([J_r(φ) ε]×).
Eigen::Matrix3d right_jacobian(const Eigen::Vector3d& phi) {
  const double t2 = phi.squaredNorm(), t = std::sqrt(t2);
  double a, b;  // (1 − cos θ)/θ², (θ − sin θ)/θ³
  if (t < 1e-4) {
    a = 0.5 - t2 / 24;
    b = 1.0 / 6 - t2 / 120;
  } else {
    a = (1 - std::cos(t)) / t2;
    b = (t - std::sin(t)) / (t2 * t);
  }
  const Eigen::Matrix3d K = skew(phi);
  return Eigen::Matrix3d::Identity() - a * K + b * K * K;
}

Eigen::Matrix3d stretch_of(const double* s6) {
  Eigen::Matrix3d S;
  S << s6[0], s6[1], s6[2], s6[1], s6[3], s6[4], s6[2], s6[4], s6[5];
  return S;
}


// One unknown's block row of the Jacobian's right-hand-side panel (3 rows × 12: column 4c + j
// is column c of coefficient j): Z += Σ_t Σ_e b_t,e,j M_t,e over `count` terms, M_t the 27
// numbers v[(3a + c)·3 + e], b_t,e,j = basis[j][off_t + e].
void assemble_panel_row_portable(double* Z, int count, const double* const* M, const int* off,
                                 const double* const* basis) {
  for (int t = 0; t < count; ++t) {
    double b[3][4];
    for (int e = 0; e < 3; ++e)
      for (int j = 0; j < 4; ++j) b[e][j] = basis[j][off[t] + e];
    for (int ac = 0; ac < 9; ++ac) {
      double* out = Z + (ac / 3) * 12 + (ac % 3) * 4;
      const double* m = M[t] + 3 * ac;
      for (int j = 0; j < 4; ++j) out[j] += m[0] * b[0][j] + m[1] * b[1][j] + m[2] * b[2][j];
    }
  }
}
#if defined(__x86_64__) && defined(__GNUC__)
#define BODYMODEL_FIT_AVX2 1
// The same with the four coefficients in one register: 27 fused multiply-adds per term.
__attribute__((target("avx2,fma"))) void assemble_panel_row_avx2(double* Z, int count, const double* const* M,
                                                                 const int* off, const double* const* basis) {
  __m256d acc[9];
  for (int ac = 0; ac < 9; ++ac) acc[ac] = _mm256_loadu_pd(Z + (ac / 3) * 12 + (ac % 3) * 4);
  for (int t = 0; t < count; ++t) {
    const int o = off[t];
    const __m256d b0 = _mm256_set_pd(basis[3][o], basis[2][o], basis[1][o], basis[0][o]);
    const __m256d b1 = _mm256_set_pd(basis[3][o + 1], basis[2][o + 1], basis[1][o + 1], basis[0][o + 1]);
    const __m256d b2 = _mm256_set_pd(basis[3][o + 2], basis[2][o + 2], basis[1][o + 2], basis[0][o + 2]);
    const double* m = M[t];
    for (int ac = 0; ac < 9; ++ac) {
      acc[ac] = _mm256_fmadd_pd(_mm256_set1_pd(m[3 * ac]), b0, acc[ac]);
      acc[ac] = _mm256_fmadd_pd(_mm256_set1_pd(m[3 * ac + 1]), b1, acc[ac]);
      acc[ac] = _mm256_fmadd_pd(_mm256_set1_pd(m[3 * ac + 2]), b2, acc[ac]);
    }
  }
  for (int ac = 0; ac < 9; ++ac) _mm256_storeu_pd(Z + (ac / 3) * 12 + (ac % 3) * 4, acc[ac]);
}
#endif
using AssembleKernel = void (*)(double*, int, const double* const*, const int*, const double* const*);
AssembleKernel assemble_kernel() {
#ifdef BODYMODEL_FIT_AVX2
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return assemble_panel_row_avx2;
#endif
  return assemble_panel_row_portable;
}
const AssembleKernel assemble_panel_row = assemble_kernel();

using Clock = std::chrono::steady_clock;

}  // namespace

void ModelFitOptions::validate() const {
  if (components == 0 || components < -1)
    throw InputError(fmt::format("fit: components must be ≥ 1 or −1 (all), got {}", components));
  if (continuation_iterations < 0)
    throw InputError(fmt::format("fit: continuation_iterations must be ≥ 0, got {}", continuation_iterations));
  if (max_iterations < 0) throw InputError(fmt::format("fit: max_iterations must be ≥ 0, got {}", max_iterations));
  if (!(relative_tolerance >= 0) || !(step_tolerance_mm >= 0))
    throw InputError("fit: tolerances must be ≥ 0");
  if (!(prior_weight >= 0) || !std::isfinite(prior_weight))
    throw InputError(fmt::format("fit: prior_weight must be ≥ 0 and finite, got {}", prior_weight));
}

std::string ModelFitSummary::report() const {
  return fmt::format(
      "{} components: mean vertex error {:.3f} (start {:.3f}{}), RMS {:.3f}, p95 {:.3f}, max {:.3f}; {} "
      "iterations, {} Jacobians ({:.2f} s), {} decodes ({:.2f} s), {:.2f} s; {} ({})",
      components, mean_mm, start_mean_mm,
      start_sample >= 0 ? fmt::format(" at training sample {}", start_sample) : std::string(), rms_mm, p95_mm,
      max_mm, iterations, jacobians, jacobian_seconds, evaluations, decode_seconds, seconds,
      converged ? "converged" : "NOT CONVERGED", stop_reason);
}

// Everything that depends only on the template: slots, the rotation system's pattern and where
// each slot's 3×3 block lives in it.
struct ModelFitter::Impl {
  int nf = 0, nv = 0, n = 0;      // triangles, vertices, unknown triangles
  int fixed = 0;                  // the fixed triangle (the decoder's: smallest index)
  std::vector<int> unknown;       // #F → unknown index or −1
  struct Slot {
    int f, k, g;                  // slot 3f + k, neighbour g
    bool f_high;                  // unknown(f) > unknown(g): the slot's block is stored as is
    std::array<int, 9> pos;       // value positions of the lower block (row-major a, c)
  };
  std::vector<Slot> slots;        // slots with a neighbour
  // The rotation system as 3×3 blocks for BlockCholesky3 (the default solver): slot i adds
  // −R̂ (or −R̂ᵀ when its f is the lower unknown) to off-diagonal block slot_edge[i] (−1: a
  // slot touching the fixed triangle).
  std::vector<int> slot_edge;
  int edge_count = 0;
  std::unique_ptr<BlockCholesky3> block;
  std::vector<int> solver_row;    // unknown → its block row in the block solver's order
  // The Jacobian's right-hand side of unknown p gathers terms[term_begin[p] … term_begin[p+1]):
  // slot index, and whether p is the slot's g (dR̂ᵀ X_f) rather than its f (dR̂ X_g).
  std::vector<int> term_begin;
  std::vector<std::pair<int, bool>> terms;
  std::vector<std::array<int, 9>> diag_pos;  // per unknown, −1 above the diagonal
  std::vector<double> diag_count; // per unknown: I × (number of slots touching it)
  SparseMatrixd pattern;          // 3n × 3n, lower triangle
  std::vector<char> referenced;   // #V: vertex used by a triangle

  // Per-evaluation state.
  struct State {
    std::vector<Eigen::Matrix3d> slot_R, S, R, Pinv;  // R̂ per slot, S_f, R_f, (tr P − P)⁻¹
    Eigen::MatrixXd X;                                // 3n × 3 rotation-system solution
  };
};

// Per-fit workspace: the rotation-system solver (analysed once: the pattern never changes) and
// the state of the last evaluation, whose factorisation the solver holds.
// A slot's right-hand-side term of the Jacobian: three 3×3 matrices, one per basis value of
// the slot, stored as v[(3a + c)·3 + e] = entry (a, c) of the e-th.
struct JacobianTerm {
  double v[27];
};

struct ModelFitter::Workspace {
  bool reference = false;  // CHOLMOD (chol) instead of the block factorisation (factor)
  std::unique_ptr<Cholesky> chol;
  BlockCholesky3::Factor factor;
  Impl::State state;       // of the last solve(): its factorisation is in chol / factor
  Eigen::VectorXd x;       // its encoding values
  std::vector<Eigen::Matrix3d> diag, off;  // the block system's values (kept: no re-allocation)
  std::vector<JacobianTerm> at_f, at_g;     // the Jacobian's per-slot terms (jacobian())
};

ModelFitter::ModelFitter(std::shared_ptr<const EncodingTemplate> tmpl, std::shared_ptr<const EncodingMean> mean,
                         const Pca& pca)
    : tmpl_(std::move(tmpl)), mean_(std::move(mean)), pca_(pca),
      decoder_(tmpl_, [] {
        DecoderOptions o;
        o.align_to_template = false;
        return o;
      }()),
      impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.nf = tmpl_->triangle_count();
  m.nv = tmpl_->vertex_count();
  if (pca_.dimension() != tmpl_->encoding_size())
    throw InputError(fmt::format("fit: the PCA has dimension {}, the template's encoding has {} values",
                                 pca_.dimension(), tmpl_->encoding_size()));
  if (decoder_.component_count() != 1)
    throw InputError(fmt::format("fit: the template has {} separate surface components; the fit places "
                                 "one rigid body and needs a connected mesh",
                                 decoder_.component_count()));
  const Eigen::MatrixX3i& TT = tmpl_->adjacency();
  const Eigen::MatrixX3i& F = tmpl_->faces();
  m.fixed = 0;  // the decoder fixes the smallest triangle index of each (here: the one) component
  m.unknown.assign(m.nf, -1);
  for (int f = 0; f < m.nf; ++f)
    if (f != m.fixed) m.unknown[f] = m.n++;
  m.diag_count.assign(m.n, 0.0);
  std::vector<Eigen::Triplet<double>> trip;
  for (int p = 0; p < m.n; ++p)
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c <= a; ++c) trip.emplace_back(3 * p + a, 3 * p + c, 1.0);
  for (int f = 0; f < m.nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      if (g < 0) continue;
      Impl::Slot s{f, k, g, false, {}};
      s.pos.fill(-1);
      const int pf = m.unknown[f], pg = m.unknown[g];
      if (pf >= 0) m.diag_count[pf] += 1;
      if (pg >= 0) m.diag_count[pg] += 1;
      if (pf >= 0 && pg >= 0) {
        s.f_high = pf > pg;
        const int hi = std::max(pf, pg), lo = std::min(pf, pg);
        for (int a = 0; a < 3; ++a)
          for (int c = 0; c < 3; ++c) trip.emplace_back(3 * hi + a, 3 * lo + c, 1.0);
      }
      m.slots.push_back(s);
    }
  m.pattern.resize(3 * m.n, 3 * m.n);
  m.pattern.setFromTriplets(trip.begin(), trip.end());
  m.pattern.makeCompressed();
  auto position = [&](int row, int col) {
    const int* inner = m.pattern.innerIndexPtr();
    const int b = m.pattern.outerIndexPtr()[col], e = m.pattern.outerIndexPtr()[col + 1];
    const int* it = std::lower_bound(inner + b, inner + e, row);
    if (it == inner + e || *it != row) throw NumericalError("fit: rotation-system pattern is inconsistent");
    return static_cast<int>(it - inner);
  };
  for (auto& s : m.slots) {
    const int pf = m.unknown[s.f], pg = m.unknown[s.g];
    if (pf < 0 || pg < 0) continue;
    const int hi = std::max(pf, pg), lo = std::min(pf, pg);
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) s.pos[3 * a + c] = position(3 * hi + a, 3 * lo + c);
  }
  {
    std::map<std::pair<int, int>, int> edge_of;  // (hi, lo) unknowns → edge (a pair may have 2 slots)
    std::vector<std::pair<int, int>> lower;
    m.slot_edge.assign(m.slots.size(), -1);
    for (size_t i = 0; i < m.slots.size(); ++i) {
      const int pf = m.unknown[m.slots[i].f], pg = m.unknown[m.slots[i].g];
      if (pf < 0 || pg < 0) continue;
      const std::pair<int, int> key(std::max(pf, pg), std::min(pf, pg));
      auto [it, added] = edge_of.emplace(key, static_cast<int>(lower.size()));
      if (added) lower.push_back(key);
      m.slot_edge[i] = it->second;
    }
    m.edge_count = static_cast<int>(lower.size());
    if (m.n > 0) {
      m.block = std::make_unique<BlockCholesky3>(m.n, lower);
      m.solver_row.assign(m.n, 0);
      for (int i = 0; i < m.n; ++i) m.solver_row[m.block->permutation()[i]] = i;
    }
    std::vector<std::vector<std::pair<int, bool>>> by_unknown(m.n);
    for (size_t i = 0; i < m.slots.size(); ++i) {
      const int pf = m.unknown[m.slots[i].f], pg = m.unknown[m.slots[i].g];
      if (pf >= 0) by_unknown[pf].emplace_back(static_cast<int>(i), false);
      if (pg >= 0) by_unknown[pg].emplace_back(static_cast<int>(i), true);
    }
    m.term_begin.assign(1, 0);
    for (const auto& list : by_unknown) {
      m.terms.insert(m.terms.end(), list.begin(), list.end());
      m.term_begin.push_back(static_cast<int>(m.terms.size()));
    }
  }
  m.diag_pos.resize(m.n);
  for (int p = 0; p < m.n; ++p)
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) m.diag_pos[p][3 * a + c] = c <= a ? position(3 * p + a, 3 * p + c) : -1;
  m.referenced.assign(m.nv, 0);
  for (int f = 0; f < m.nf; ++f)
    for (int k = 0; k < 3; ++k) m.referenced[F(f, k)] = 1;
  (void)F;
}

ModelFitter::~ModelFitter() = default;

Eigen::VectorXd ModelFitter::project(const Eigen::MatrixX3d& V, int K) const {
  if (K < 1 || K > pca_.component_count())
    throw InputError(fmt::format("fit: {} components requested, the model has {}", K, pca_.component_count()));
  const Encoding e = encode(*tmpl_, V, mean_);
  return pca_.basis.leftCols(K).transpose() * (e.values - pca_.mean);
}

Eigen::MatrixX3d ModelFitter::evaluate(const Eigen::VectorXd& c, Eigen::MatrixXd* J, bool reference_solver) const {
  Workspace ws;
  ws.reference = reference_solver;
  Eigen::MatrixX3d V = solve(ws, c);
  if (J) jacobian(ws, static_cast<int>(c.size()), *J);
  return V;
}

Eigen::MatrixX3d ModelFitter::solve(Workspace& ws, const Eigen::VectorXd& c) const {
  const Impl& m = *impl_;
  const int K = static_cast<int>(c.size());
  if (K > pca_.component_count())
    throw InputError(fmt::format("fit: {} coefficients given, the model has {} components", K, pca_.component_count()));
  // mean + B c in row blocks on all cores: the product reads the whole basis (D × K doubles,
  // ≈ 100 MB for FAUST at 59 components), bound by memory bandwidth on one core.
  ws.x.resize(pca_.mean.size());
  const Eigen::Index D = pca_.mean.size(), rows = 8192;
  tbb::parallel_for(Eigen::Index(0), (D + rows - 1) / rows, [&](Eigen::Index i) {
    const Eigen::Index r0 = i * rows, nr = std::min(rows, D - r0);
    ws.x.segment(r0, nr).noalias() = pca_.mean.segment(r0, nr) + pca_.basis.block(r0, 0, nr, K) * c;
  });
  const Eigen::VectorXd& x = ws.x;
  Impl::State& st = ws.state;
  encoding_matrices(Encoding{x, mean_}, st.slot_R, st.S);

  // Rotation system N X = b (the decoder's, docs/method.md §3.4): right-hand side from the
  // slots touching the fixed triangle, matrix from the rest.
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(3 * m.n, 3);
  for (const auto& s : m.slots) {
    const Eigen::Matrix3d& Rs = st.slot_R[3 * s.f + s.k];
    const int pf = m.unknown[s.f], pg = m.unknown[s.g];
    if (pf < 0 && pg >= 0) {
      b.middleRows<3>(3 * pg) += Rs.transpose();  // X_f = I (fixed)
    } else if (pg < 0 && pf >= 0) {
      b.middleRows<3>(3 * pf) += Rs;              // X_g = I (fixed)
    }
  }
  if (!ws.reference && m.block) {
    // Block (f, g) gets −R̂ per slot; the lower block of the pair (hi, lo) is stored.
    ws.diag.resize(m.n);
    ws.off.assign(m.edge_count, Eigen::Matrix3d::Zero());
    for (int p = 0; p < m.n; ++p) ws.diag[p] = m.diag_count[p] * Eigen::Matrix3d::Identity();
    for (size_t i = 0; i < m.slots.size(); ++i) {
      const int e = m.slot_edge[i];
      if (e < 0) continue;
      const auto& s = m.slots[i];
      const Eigen::Matrix3d& Rs = st.slot_R[3 * s.f + s.k];
      if (s.f_high)
        ws.off[e] -= Rs;
      else
        ws.off[e] -= Rs.transpose();
    }
    if (!m.block->factorize(ws.diag, ws.off, ws.factor))
      throw NumericalError("fit: the rotation system is not positive definite");
    m.block->solve(ws.factor, b);
    st.X = std::move(b);
  } else {
    SparseMatrixd N = m.pattern;
    double* val = N.valuePtr();
    std::fill(val, val + N.nonZeros(), 0.0);
    for (int p = 0; p < m.n; ++p)
      for (int a = 0; a < 3; ++a) val[m.diag_pos[p][3 * a + a]] = m.diag_count[p];
    for (const auto& s : m.slots) {
      if (m.unknown[s.f] < 0 || m.unknown[s.g] < 0) continue;
      const Eigen::Matrix3d& Rs = st.slot_R[3 * s.f + s.k];
      // Block (f, g) gets −R̂; stored lower: as is when f is the higher index, else transposed.
      for (int a = 0; a < 3; ++a)
        for (int cc = 0; cc < 3; ++cc) val[s.pos[3 * a + cc]] -= s.f_high ? Rs(a, cc) : Rs(cc, a);
    }
    if (!ws.chol) {
      ws.chol = std::make_unique<Cholesky>();
      ws.chol->analyzePattern(N);
    }
    Cholesky& chol = *ws.chol;
    chol.factorize(N);
    if (chol.info() != Eigen::Success) throw NumericalError("fit: the rotation system is not positive definite");
    st.X = chol.solve(b);
  }
  if (!st.X.allFinite()) throw NumericalError("fit: the rotation solve produced NaN");
  st.R.assign(m.nf, Eigen::Matrix3d::Identity());
  st.Pinv.assign(m.nf, Eigen::Matrix3d::Zero());
  tbb::parallel_for(0, m.nf, [&](int f) {
    const int p = m.unknown[f];
    if (p < 0) return;
    const Eigen::Matrix3d M = st.X.middleRows<3>(3 * p).transpose();
    st.R[f] = closest_rotation(M);
    Eigen::Matrix3d P = st.R[f].transpose() * M;
    P = 0.5 * (P + P.transpose()).eval();
    st.Pinv[f] = (P.trace() * Eigen::Matrix3d::Identity() - P).inverse();
  });
  return decoder_.solve_positions(st.R, st.S);
}

// Forward-mode derivative of the decoded vertices w.r.t. the first K coefficients at the state
// of the last solve() (see the header).
void ModelFitter::jacobian(Workspace& ws, int K, Eigen::MatrixXd& Jout) const {
  const Impl& m = *impl_;
  const Impl::State& st = ws.state;
  const Eigen::VectorXd& x = ws.x;
  Eigen::MatrixXd* J = &Jout;
  J->resize(3 * m.nv, K);
  std::vector<Eigen::Matrix3d> Jr(m.slots.size());
  tbb::parallel_for(0, static_cast<int>(m.slots.size()), [&](int i) {
    const auto& s = m.slots[i];
    Jr[i] = right_jacobian(x.segment<3>(15 * s.f + 3 * s.k));
  });
  auto X_of = [&](int f) -> Eigen::Matrix3d {
    const int p = m.unknown[f];
    return p < 0 ? Eigen::Matrix3d::Identity() : Eigen::Matrix3d(st.X.middleRows<3>(3 * p));
  };
  // Coefficient k's column of J from the derivative dX of the rotation system's solution
  // (dX_block(p): its 3×3 block of unknown p): the polar factor's derivative, then one Poisson
  // solve.
  // Columns k0 … k0+kc−1 of J from the derivatives dX of the rotation system's solution
  // (dX_block(p, j): the 3×3 block of unknown p for coefficient k0 + j): the polar factor's
  // derivative for all kc in one pass over the triangles, then one Poisson solve each.
  auto positions_columns = [&](int k0, int kc, const auto& dX_block) {
    std::vector<Eigen::Matrix3d> dU(static_cast<size_t>(kc) * m.nf);  // coefficient j's at j·#F + f
    for (int f = 0; f < m.nf; ++f) {
      const int p = m.unknown[f];
      const Eigen::Matrix3d& R = st.R[f];
      for (int j = 0; j < kc; ++j) {
        Eigen::Matrix3d dU_local = stretch_of(pca_.basis.col(k0 + j).data() + 15 * f + 9);  // dS_f
        if (p >= 0) {
          // R_fᵀ dU_f = [ν]× S_f + dS_f, ν = Pinv_f axial(Aᵀ − A), A = R_fᵀ dM, dM = dXᵀ: only
          // A's off-diagonal entries are needed.
          const Eigen::Matrix3d dX = dX_block(p, j);
          auto A = [&](int a, int b) { return R.col(a).dot(dX.row(b)); };
          const Eigen::Vector3d w(A(2, 1) - A(1, 2), A(0, 2) - A(2, 0), A(1, 0) - A(0, 1));
          const Eigen::Vector3d nu = st.Pinv[f] * w;
          for (int c = 0; c < 3; ++c) dU_local.col(c) += nu.cross(st.S[f].col(c));
        }
        dU[static_cast<size_t>(j) * m.nf + f] = R * dU_local;
      }
    }
    const Eigen::MatrixXd dV = decoder_.solve_positions_many(dU, kc);  // one pass through the factor
    for (int j = 0; j < kc; ++j)
      for (int v = 0; v < m.nv; ++v)
        J->block<3, 1>(3 * v, k0 + j) =
            m.referenced[v] ? Eigen::Vector3d(dV.block<1, 3>(v, 3 * j).transpose()) : Eigen::Vector3d::Zero();
  };

  if (!ws.reference && m.block) {
    // dR̂ = R̂ [J_r b]× is linear in the basis segment b of the slot, so each slot's two
    // right-hand-side terms are 3×3 matrices per component of b, computed once per Jacobian:
    //   f rows: dR̂ X_g = Σ_e b_e R̂ [J_r e_e]× X_g,   g rows: dR̂ᵀ X_f = −Σ_e b_e [J_r e_e]× R̂ᵀ X_f.
    // Kept in the workspace (≈ 18 MB for FAUST: re-allocating them per Jacobian page-faults).
    std::vector<JacobianTerm>& at_f = ws.at_f;
    std::vector<JacobianTerm>& at_g = ws.at_g;
    at_f.resize(m.slots.size());
    at_g.resize(m.slots.size());
    tbb::parallel_for(0, static_cast<int>(m.slots.size()), [&](int i) {
      const auto& s = m.slots[i];
      const Eigen::Matrix3d& Rs = st.slot_R[3 * s.f + s.k];
      const Eigen::Matrix3d Xg = X_of(s.g), RtXf = Rs.transpose() * X_of(s.f);
      for (int e = 0; e < 3; ++e) {
        const Eigen::Matrix3d E = skew(Jr[i].col(e));
        const Eigen::Matrix3d F = Rs * E * Xg, G = -E * RtXf;
        for (int a = 0; a < 3; ++a)
          for (int c = 0; c < 3; ++c) {
            at_f[i].v[(3 * a + c) * 3 + e] = F(a, c);
            at_g[i].v[(3 * a + c) * 3 + e] = G(a, c);
          }
      }
    });
    // Groups of four coefficients (kPanel = 12 columns) run in parallel (the block solve is
    // const; CHOLMOD's is not), each assembling its right-hand sides straight into the
    // solver's row-major layout (3n × 12 doubles: in cache, no copies). Column 4c + j of the
    // panel is column c of coefficient j's 3×3 blocks, so the four coefficients of one entry
    // are contiguous and the assembly vectorises.
    constexpr int W = BlockCholesky3::kPanel, group = W / 3;
    static_assert(group == 4, "panel layout: 3 columns × 4 coefficients");
    const int groups = (K + group - 1) / group;
    tbb::parallel_for(0, groups, [&](int gi) {
      const int k0 = group * gi, kc = std::min(group, K - k0);
      std::vector<double> z(static_cast<size_t>(3 * m.n) * W);
      const double* basis[group];
      for (int j = 0; j < group; ++j) basis[j] = pca_.basis.col(k0 + std::min(j, kc - 1)).data();
      // Unknowns in template order: the slots' terms and basis rows are read nearly in
      // sequence; each block row of z is written once.
      // (A last group of fewer than four repeats its last coefficient in the spare columns.)
      for (int p = 0; p < m.n; ++p) {
        double* Z = z.data() + static_cast<size_t>(3 * W) * m.solver_row[p];
        std::fill(Z, Z + 3 * W, 0.0);
        const double* M[8];
        int off[8], count = 0;
        for (int t = m.term_begin[p]; t < m.term_begin[p + 1]; ++t) {
          const auto [i, at_g_rows] = m.terms[t];
          M[count] = (at_g_rows ? at_g[i] : at_f[i]).v;
          off[count++] = 15 * m.slots[i].f + 3 * m.slots[i].k;
          if (count == 8 || t + 1 == m.term_begin[p + 1]) {
            assemble_panel_row(Z, count, M, off, basis);
            count = 0;
          }
        }
      }
      m.block->solve_panel(ws.factor, z.data());
      positions_columns(k0, kc, [&](int p, int j) {
        const double* Z = z.data() + static_cast<size_t>(3 * W) * m.solver_row[p];
        Eigen::Matrix3d dX;
        for (int a = 0; a < 3; ++a)
          for (int c = 0; c < 3; ++c) dX(a, c) = Z[a * W + c * group + j];
        return dX;
      });
    });
    return;
  }

  // The reference path (CHOLMOD): 32 coefficients per solve (memory: 3n × 96 doubles).
  for (int k0 = 0; k0 < K; k0 += 32) {
    const int kc = std::min(32, K - k0);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(3 * m.n, 3 * kc);
    tbb::parallel_for(0, kc, [&](int j) {
      const Eigen::Ref<const Eigen::VectorXd> bk = pca_.basis.col(k0 + j);
      auto out = rhs.middleCols<3>(3 * j);
      for (size_t i = 0; i < m.slots.size(); ++i) {
        const auto& s = m.slots[i];
        const Eigen::Vector3d w = Jr[i] * bk.segment<3>(15 * s.f + 3 * s.k);
        if (w.squaredNorm() == 0) continue;
        const Eigen::Matrix3d dR = st.slot_R[3 * s.f + s.k] * skew(w);
        const int pf = m.unknown[s.f], pg = m.unknown[s.g];
        if (pg >= 0) out.middleRows<3>(3 * pg) += dR.transpose() * X_of(s.f);
        if (pf >= 0) out.middleRows<3>(3 * pf) += dR * X_of(s.g);
      }
    });
    const Eigen::MatrixXd dX = ws.chol->solve(rhs);
    tbb::parallel_for(0, kc, [&](int j) {
      positions_columns(k0 + j, 1, [&](int p, int) { return Eigen::Matrix3d(dX.block<3, 3>(3 * p, 3 * j)); });
    });
  }
}

namespace {

// The Gauss–Newton system of one iteration: the Jacobian in the target's frame, [Q·dv/dc |
// rotation about the centroid | translation], into Jt (the stage's buffer, 3·#V by P), then
// H = JtᵀJt (H zero on entry, P by P) and g = Jtᵀr for the residuals r = placed − Y.
void normal_equations(const Eigen::MatrixXd& Jraw, int Kc, const Eigen::Matrix3d& Q, const Eigen::MatrixX3d& placed,
                      const Eigen::MatrixX3d& Y, Eigen::MatrixXd& Jt, Eigen::MatrixXd& H, Eigen::VectorXd& g) {
  const int nv = static_cast<int>(Y.rows());
  const Eigen::RowVector3d centroid = placed.colwise().mean();
  tbb::parallel_for(0, nv, [&](int v) {
    Jt.block(3 * v, 0, 3, Kc) = Q * Jraw.block(3 * v, 0, 3, Kc);
    const Eigen::Vector3d p = (placed.row(v) - centroid).transpose();
    Jt.block<3, 3>(3 * v, Kc) = -skew(p);
    Jt.block<3, 3>(3 * v, Kc + 3).setIdentity();
  });
  Eigen::VectorXd r(3 * nv);
  for (int v = 0; v < nv; ++v) r.segment<3>(3 * v) = (placed.row(v) - Y.row(v)).transpose();
  H.selfadjointView<Eigen::Lower>().rankUpdate(Jt.transpose());
  H = H.selfadjointView<Eigen::Lower>();
  g = Jt.transpose() * r;
}

// The fit's error figures from its placed vertices: per-vertex error, mean, RMS, 95th
// percentile and maximum.
void error_summary(const Eigen::MatrixX3d& placed, const Eigen::MatrixX3d& Y, ModelFit& out) {
  out.vertex_error = (placed - Y).rowwise().norm();
  std::vector<double> e(out.vertex_error.data(), out.vertex_error.data() + out.vertex_error.size());
  out.summary.mean_mm = out.vertex_error.mean();
  out.summary.rms_mm = std::sqrt(out.vertex_error.squaredNorm() / std::max<Eigen::Index>(1, out.vertex_error.size()));
  out.summary.p95_mm = percentile(e, 95);
  out.summary.max_mm = out.vertex_error.maxCoeff();
}

}  // namespace

Eigen::VectorXd ModelFitter::start_point(const Eigen::MatrixX3d& Y, int K, const ModelFitOptions& o,
                                         ModelFitSummary& summary) const {
  Eigen::VectorXd c = Eigen::VectorXd::Zero(K);
  if (o.start.size() > 0)
    c.head(o.start.size()) = o.start;
  else if (o.start_from_projection)
    c = project(Y, K);
  summary.start_sample = -1;
  if (!o.try_training_starts || pca_.coefficients.rows() == 0) return c;
  // E of each candidate as the fit measures it (rigid placement, prior), one decode each.
  auto cost_of = [&](Workspace& w, const Eigen::VectorXd& cc) {
    const auto t0 = Clock::now();
    const Eigen::MatrixX3d raw = solve(w, cc);
    summary.decode_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
    ++summary.evaluations;
    double prior = 0;
    for (int k = 0; k < K; ++k)
      if (pca_.eigenvalues(k) > 0) prior += cc(k) * cc(k) / pca_.eigenvalues(k);
    return (apply(fit_rigid_motion(raw, Y), raw) - Y).squaredNorm() + o.prior_weight * prior;
  };
  Workspace w;
  w.reference = o.reference_solver;
  double best = cost_of(w, c);
  for (int s = 0; s < pca_.coefficients.rows(); ++s) {
    const Eigen::VectorXd cs = pca_.coefficients.row(s).head(K).transpose();
    const double e = cost_of(w, cs);
    if (e < best) {
      best = e;
      c = cs;
      summary.start_sample = s;
    }
  }
  return c;
}

ModelFit ModelFitter::fit(const Eigen::MatrixX3d& Y, const ModelFitOptions& o,
                          const ProgressCallback& progress) const {
  o.validate();
  const auto t_start = Clock::now();
  const Impl& m = *impl_;
  if (Y.rows() != m.nv)
    throw InputError(fmt::format("fit: the mesh has {} vertices, the model's template has {}", Y.rows(), m.nv));
  if (!Y.allFinite()) throw InputError("fit: the mesh has NaN or infinite coordinates");
  const int K = o.components < 0 ? pca_.component_count() : o.components;
  if (K > pca_.component_count())
    throw InputError(fmt::format("fit: {} components requested, the model has {}", K, pca_.component_count()));
  if (o.start.size() > K)
    throw InputError(fmt::format("fit: a start of {} coefficients for a fit of {} components", o.start.size(), K));
  ModelFit out;
  out.summary.components = K;
  Eigen::VectorXd c = start_point(Y, K, o, out.summary);
  Eigen::VectorXd inv_lambda = Eigen::VectorXd::Zero(K);
  for (int k = 0; k < K; ++k)
    if (pca_.eigenvalues(k) > 0) inv_lambda(k) = 1.0 / pca_.eigenvalues(k);

  // An evaluation: decoded (solver gauge) and rigidly placed vertices, cost.
  struct Eval {
    Eigen::MatrixX3d raw, placed;
    RigidMotion rigid;
    double cost = 0;
  };
  // Two workspaces: the accepted point's (its factorisation serves the next Jacobian) and the
  // trial step's, swapped on acceptance, so a rejected step never costs a second decode of
  // the accepted point.
  Workspace ws, trial;
  ws.reference = trial.reference = o.reference_solver;
  auto evaluate_at = [&](Workspace& w, const Eigen::VectorXd& cc) {
    Eval e;
    const auto t0 = Clock::now();
    e.raw = solve(w, cc);
    out.summary.decode_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
    e.rigid = fit_rigid_motion(e.raw, Y);
    e.placed = apply(e.rigid, e.raw);
    e.cost = (e.placed - Y).squaredNorm() +
             o.prior_weight * (cc.array().square() * inv_lambda.head(cc.size()).array()).sum();
    ++out.summary.evaluations;
    return e;
  };
  Eval cur = evaluate_at(ws, c);  // ws holds cur's state from here on
  out.summary.start_mean_mm = (cur.placed - Y).rowwise().norm().mean();
  out.summary.history_mean_mm.push_back(out.summary.start_mean_mm);

  // Levenberg–Marquardt on the first Kc components; the continuation stage (Kc < K, looser
  // tolerance) brings a far start close at a fraction of the Jacobian's cost, which is
  // linear in the number of components.
  auto run = [&](int Kc, double tolerance, int max_iterations) {
    double mu = 1e-4;
    const int P = Kc + 6;
    Eigen::MatrixXd Jraw, Jt(3 * m.nv, P);  // allocated once per stage (10 MB each: page faults)
    // Steps since Jraw was computed (−1: none yet, or it must be recomputed).
    int age = -1;
    for (int it = 0; it < max_iterations; ++it) {
      report_progress(progress, std::min(0.99, static_cast<double>(out.summary.iterations) / std::max(1, o.max_iterations)),
                      fmt::format("iteration {} ({} components)", out.summary.iterations + 1, Kc));
      const bool fresh = age < 0 || age >= o.jacobian_reuse;
      if (fresh) {
        const auto t0 = Clock::now();
        jacobian(ws, Kc, Jraw);
        out.summary.jacobian_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
        ++out.summary.jacobians;
        age = 0;
      } else {
        ++age;
      }
      ++out.summary.iterations;
      // Jacobian in the target's frame: [Q·dv/dc | rotation about the centroid | translation].
      Eigen::MatrixXd H = Eigen::MatrixXd::Zero(P, P);
      Eigen::VectorXd g;
      normal_equations(Jraw, Kc, cur.rigid.R, cur.placed, Y, Jt, H, g);
      for (int k = 0; k < Kc; ++k) {
        H(k, k) += o.prior_weight * inv_lambda(k);
        g(k) += o.prior_weight * inv_lambda(k) * c(k);
      }
      bool accepted = false, done = false;
      // A chord step (stale Jacobian) gets one try: if it fails, the next step is a fresh one
      // rather than a more damped step along a stale model.
      for (int attempt = 0; attempt < (fresh ? 8 : 1) && !accepted; ++attempt) {
        Eigen::MatrixXd A = H;
        for (int i = 0; i < P; ++i) A(i, i) += mu * std::max(H(i, i), 1e-12);
        const Eigen::VectorXd step = A.ldlt().solve(-g);
        if (!step.allFinite()) {
          mu *= 10;
          continue;
        }
        Eigen::VectorXd c_new = c;
        c_new.head(Kc) += step.head(Kc);
        Eval next = evaluate_at(trial, c_new);
        if (next.cost < cur.cost) {
          const double decrease = (cur.cost - next.cost) / std::max(cur.cost, 1e-300);
          const double moved = (next.placed - cur.placed).rowwise().norm().maxCoeff();
          c = c_new;
          cur = std::move(next);
          std::swap(ws, trial);
          mu = std::max(mu / 3, 1e-9);
          accepted = true;
          if (decrease < tolerance || moved < o.step_tolerance_mm) done = true;
        } else {
          if (fresh) mu *= 4;
        }
      }
      out.summary.history_mean_mm.push_back((cur.placed - Y).rowwise().norm().mean());
      if (!fresh && (!accepted || done)) {
        age = -1;  // only a fresh Jacobian may fail or stop the fit
        continue;
      }
      // No descent along the damped steps: a minimum (to tolerance).
      if (!accepted) return std::string("no step lowers the error: a minimum");
      if (done) return std::string("the last step changed the error or the vertices by less than the tolerances");
    }
    return std::string();  // the cap
  };
  // Converged only when the last stage (all K components) stopped on its own: a fit that runs
  // out of iterations, including one whose continuation stage used them all, says so.
  bool converged = false;
  std::string reason = "no iterations allowed (max_iterations 0): the start is returned";
  int budget = o.max_iterations;
  if (o.continuation_components > 0 && o.continuation_components < K && budget > 0) {
    run(o.continuation_components, o.continuation_tolerance, std::min(budget, o.continuation_iterations));
    budget -= out.summary.iterations;
    if (budget <= 0)
      reason = fmt::format("iteration limit: the {} iterations went to the {}-component start", o.max_iterations,
                           o.continuation_components);
  }
  if (budget > 0) {
    reason = run(K, o.relative_tolerance, budget);
    converged = !reason.empty();
    if (!converged)
      reason = fmt::format("stopped at the iteration limit ({}) before a step met the tolerances", o.max_iterations);
  }
  out.summary.stop_reason = reason;
  out.coefficients = c;
  out.V = cur.placed;
  error_summary(cur.placed, Y, out);
  out.summary.converged = converged;
  out.summary.seconds = std::chrono::duration<double>(Clock::now() - t_start).count();
  report_progress(progress, 1.0, "done");
  return out;
}

}  // namespace bodymodel
