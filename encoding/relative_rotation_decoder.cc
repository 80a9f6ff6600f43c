#include "encoding/relative_rotation_decoder.h"

#include <tbb/parallel_for.h>

#include <Eigen/CholmodSupport>
#include <Eigen/LU>
#include <Eigen/Sparse>
#include <algorithm>
#include <chrono>
#include <map>
#include <mutex>
#include <numeric>
#include <string>

#include "core/error.h"
#include "core/geometry.h"
#include "encoding/block_cholesky.h"
#include "encoding/deformation_gradient.h"

namespace bodymodel {

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// CHOLMOD's simplicial LLᵀ for the per-decode refactorisation of the rotation system: on this
// machine (ATLAS BLAS, 2 cores) it factorises the 3·#F system faster than the supernodal
// variant (docs/benchmarks.md#figures-behind-code-comments). Its solve uses workspace inside the object, so
// each concurrent caller gets its own (RotationPool).
using Cholesky = Eigen::CholmodSimplicialLLT<SparseMatrixd, Eigen::Lower>;
// Factorisations shared by concurrent callers: Eigen's own simplicial Cholesky, whose solve is
// const and allocates its own temporaries.
using SharedCholesky = Eigen::SimplicialLLT<SparseMatrixd, Eigen::Lower>;

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(int n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  }
  void unite(int a, int b) {
    a = find(a), b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);  // root = smallest index
  }
};

template <typename Fn>
void parallel_range(int n, Fn&& fn) {
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 1024), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i < r.end(); ++i) fn(i);
  });
}

// Index of entry (row, col) in a compressed column-major matrix (the entry must exist).
int value_index(const SparseMatrixd& M, int row, int col) {
  const int* inner = M.innerIndexPtr();
  const int begin = M.outerIndexPtr()[col], end = M.outerIndexPtr()[col + 1];
  const int* it = std::lower_bound(inner + begin, inner + end, row);
  if (it == inner + end || *it != row)
    throw NumericalError("rotation system: pattern entry missing (internal error)");
  return static_cast<int>(it - inner);
}

}  // namespace

void DecoderOptions::validate() const {
  if (!(cg_tolerance > 0) || cg_max_iterations < 1)
    throw InputError("decoder options: cg_tolerance must be positive and cg_max_iterations >= 1");
  if (!(consistency_tolerance >= 0) || !(cg_start_residual >= 0))
    throw InputError("decoder options: consistency_tolerance and cg_start_residual must be >= 0");
  if (!(constraint_weight > 0) || !std::isfinite(constraint_weight))
    throw InputError("decoder options: constraint_weight must be positive and finite, found " +
                     std::to_string(constraint_weight));
}

// A Poisson factorisation for one set of constrained vertices (immutable once built).
struct PoissonFactor {
  SharedCholesky solver;
  std::vector<char> pinned;            // #V: row replaced by identity
  Eigen::VectorXi key_vertices;        // the constraint set it was built for
  Eigen::VectorXd key_weights;
};

struct RelativeRotationDecoder::Impl {
  int nf = 0, nv = 0;
  // ---- rotation system (read-only after construction) ----
  std::vector<int> unknown;            // #F: unknown block index, −1 for a fixed triangle
  std::vector<int> fixed_triangles;    // one per component
  int n_unknown = 0;
  struct Slot {
    int f, g, k;                       // slot k of triangle f, neighbour g
    int value[9];                      // value indices of the lower block, −1 if not stored
    bool transposed;                   // block stored at (g, f): add −R_fgᵀ
  };
  std::vector<Slot> slots;
  SparseMatrixd N_pattern;             // lower triangle of the normal matrix, base values
  std::vector<int> reverse_slot;       // 3#F: k' with TT(g, k') = f for g = TT(f, k), or −1
  std::vector<int> degree;             // #F: diagonal of N (2 per neighbour)
  std::vector<std::pair<int, int>> tree;  // BFS order: (child, slot 3·parent + k) per non-root
  SharedCholesky dual_laplacian;       // L_s on the unknown triangles, factorised once
  // Block Cholesky (default path c): analysed once; per edge between unknown triangles the slot
  // 3f + k with unknown[f] > unknown[g] (its block is −(R_fg + R_gfᵀ)); diagonal per unknown.
  std::unique_ptr<BlockCholesky3> block_solver;
  std::vector<int> edge_slot;
  std::vector<double> diag_value;
  // ---- Poisson (read-only after construction) ----
  SparseMatrixd K;                     // Gᵀ A G, #V by #V (full symmetric)
  SparseMatrixd D;                     // Gᵀ A, #V by 3#F
  std::vector<int> vertex_component;   // #V, −1 for unreferenced vertices
  std::vector<int> component_first_vertex;
  std::shared_ptr<const PoissonFactor> free_poisson;  // no constraints (built once if reused)
  // ---- shared mutable state, guarded by `mutex` ----
  mutable std::mutex mutex;
  mutable std::vector<std::unique_ptr<Cholesky>> rotation_pool;  // analysed, idle
  mutable std::shared_ptr<const PoissonFactor> constrained_poisson;  // last constraint set
  // Block-Cholesky factors of earlier calls, idle: a factor is tens of MB, and a fresh one is
  // zero-filled page by page (memset and page faults showed in a population crowd's profile),
  // while factorize() overwrites every panel anyway.
  mutable std::vector<BlockCholesky3::Factor> factor_pool;
  mutable DecodeTiming last;

  std::unique_ptr<Cholesky> analysed_rotation_solver() const {
    auto solver = std::make_unique<Cholesky>();
    solver->analyzePattern(N_pattern);
    if (solver->info() != Eigen::Success)
      throw NumericalError("rotation system: symbolic analysis failed");
    return solver;
  }
  std::shared_ptr<const PoissonFactor> build_poisson(const Eigen::VectorXi& vertices,
                                                     const Eigen::VectorXd& weights) const;
};

namespace {

// Borrows an analysed rotation solver from the decoder's pool for one call (a new one is
// analysed when every pooled solver is in use) and returns it afterwards.
class PooledRotationSolver {
 public:
  explicit PooledRotationSolver(const RelativeRotationDecoder::Impl& m) : m_(m) {
    {
      std::lock_guard<std::mutex> lock(m_.mutex);
      if (!m_.rotation_pool.empty()) {
        solver_ = std::move(m_.rotation_pool.back());
        m_.rotation_pool.pop_back();
      }
    }
    if (!solver_) solver_ = m_.analysed_rotation_solver();
  }
  ~PooledRotationSolver() {
    std::lock_guard<std::mutex> lock(m_.mutex);
    m_.rotation_pool.push_back(std::move(solver_));
  }
  PooledRotationSolver(const PooledRotationSolver&) = delete;
  PooledRotationSolver& operator=(const PooledRotationSolver&) = delete;
  Cholesky& operator*() { return *solver_; }

 private:
  const RelativeRotationDecoder::Impl& m_;
  std::unique_ptr<Cholesky> solver_;
};

// Closest rotation; one Newton step of the polar iteration (R ← (X + X⁻ᵀ)/2, error ε → ε²/2)
// when X is already orthonormal to 1e-8 (the realisable case), else the SVD.
Eigen::Matrix3d orthonormalise(const Eigen::Matrix3d& X) {
  const double e = (X.transpose() * X - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (e < 1e-8 && X.determinant() > 0) return 0.5 * (X + X.inverse().transpose());
  return closest_rotation(X);
}

}  // namespace

std::shared_ptr<const PoissonFactor> RelativeRotationDecoder::Impl::build_poisson(
    const Eigen::VectorXi& vertices, const Eigen::VectorXd& weights) const {
  auto out = std::make_shared<PoissonFactor>();
  std::vector<char> has_constraint(component_first_vertex.size(), 0);
  SparseMatrixd A = K;
  if (vertices.size() > 0) {
    std::vector<Eigen::Triplet<double>> t;
    for (Eigen::Index i = 0; i < vertices.size(); ++i) {
      t.emplace_back(vertices(i), vertices(i), weights(i));
      has_constraint[vertex_component[vertices(i)]] = 1;
    }
    SparseMatrixd W(nv, nv);
    W.setFromTriplets(t.begin(), t.end());
    A += W;
  }
  out->pinned.assign(nv, 0);
  for (int v = 0; v < nv; ++v)
    if (vertex_component[v] < 0) out->pinned[v] = 1;
  for (size_t comp = 0; comp < component_first_vertex.size(); ++comp)
    if (!has_constraint[comp]) out->pinned[component_first_vertex[comp]] = 1;
  const auto& pinned = out->pinned;
  A.prune([&](Eigen::Index r, Eigen::Index col, double) {
    return r == col || (!pinned[r] && !pinned[col]);
  });
  // Pinned rows: identity (a missing diagonal entry of an unreferenced vertex is inserted).
  std::vector<Eigen::Triplet<double>> diag;
  for (int v = 0; v < nv; ++v)
    if (pinned[v]) diag.emplace_back(v, v, 1.0 - A.coeff(v, v));
  SparseMatrixd P(nv, nv);
  P.setFromTriplets(diag.begin(), diag.end());
  A += P;
  out->solver.compute(A);
  if (out->solver.info() != Eigen::Success)
    throw NumericalError("Poisson system: factorisation failed");
  out->key_vertices = vertices;
  out->key_weights = weights;
  return out;
}

RelativeRotationDecoder::~RelativeRotationDecoder() = default;

int RelativeRotationDecoder::component_count() const {
  return static_cast<int>(impl_->fixed_triangles.size());
}

DecodeTiming RelativeRotationDecoder::last_timing() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->last;
}

void RelativeRotationDecoder::set_last_timing(const DecodeTiming& t) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->last = t;
}

namespace {

using DecoderImpl = RelativeRotationDecoder::Impl;

// Components of the dual graph: the first triangle of each is fixed (identity rotation), the
// others are numbered as the rotation system's unknowns.
void number_unknowns(DecoderImpl& m, const Eigen::MatrixX3i& TT) {
  UnionFind uf(m.nf);
  for (int f = 0; f < m.nf; ++f)
    for (int k = 0; k < 3; ++k)
      if (TT(f, k) >= 0) uf.unite(f, TT(f, k));
  m.unknown.assign(m.nf, -1);
  for (int f = 0; f < m.nf; ++f) {
    if (uf.find(f) == f)
      m.fixed_triangles.push_back(f);
    else
      m.unknown[f] = m.n_unknown++;
  }
}

// The slots (one per triangle side with a neighbour), the pattern of the lower triangle of N with
// its base diagonal, and where each slot's block sits in it; returns the number of neighbours of
// each unknown (N's diagonal before the max with 1).
Eigen::VectorXd rotation_pattern(DecoderImpl& m, const Eigen::MatrixX3i& TT) {
  // Pattern of the lower triangle of N (block rows/cols = unknown indices).
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<size_t>(m.n_unknown) * 3 + static_cast<size_t>(m.nf) * 27);
  Eigen::VectorXd diag_count = Eigen::VectorXd::Zero(m.n_unknown);
  for (int f = 0; f < m.nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      if (g < 0) continue;
      m.slots.push_back(DecoderImpl::Slot{f, g, k, {}, false});
      const int pf = m.unknown[f], pg = m.unknown[g];
      if (pf >= 0) diag_count(pf) += 1;
      if (pg >= 0) diag_count(pg) += 1;
      if (pf >= 0 && pg >= 0) {
        const int hi = std::max(pf, pg), lo = std::min(pf, pg);
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) trip.emplace_back(3 * hi + a, 3 * lo + b, 0.0);
      }
    }
  for (int p = 0; p < m.n_unknown; ++p)
    for (int a = 0; a < 3; ++a) trip.emplace_back(3 * p + a, 3 * p + a, 0.0);
  m.N_pattern.resize(3 * m.n_unknown, 3 * m.n_unknown);
  m.N_pattern.setFromTriplets(trip.begin(), trip.end());
  m.N_pattern.makeCompressed();
  for (int p = 0; p < m.n_unknown; ++p)
    for (int a = 0; a < 3; ++a)
      m.N_pattern.valuePtr()[value_index(m.N_pattern, 3 * p + a, 3 * p + a)] =
          std::max(1.0, diag_count(p));
  for (auto& s : m.slots) {
    const int pf = m.unknown[s.f], pg = m.unknown[s.g];
    std::fill(std::begin(s.value), std::end(s.value), -1);
    if (pf < 0 || pg < 0) continue;
    // Block (f, g) of N gets −R_fg; stored in the lower triangle at (max, min).
    s.transposed = pf < pg;
    const int hi = std::max(pf, pg), lo = std::min(pf, pg);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        s.value[3 * a + b] = value_index(m.N_pattern, 3 * hi + a, 3 * lo + b);
  }
  return diag_count;
}

// The block Cholesky of path c, analysed once over the edges between unknown triangles, with the
// diagonal values it is factorised with.
void analyse_block_solver(DecoderImpl& m, const Eigen::VectorXd& diag_count) {
  std::vector<std::pair<int, int>> lower;
  for (const auto& s : m.slots) {
    const int pf = m.unknown[s.f], pg = m.unknown[s.g];
    if (pf < 0 || pg < 0 || pf < pg) continue;
    lower.emplace_back(pf, pg);
    m.edge_slot.push_back(3 * s.f + s.k);
  }
  m.block_solver = std::make_unique<BlockCholesky3>(m.n_unknown, lower);
  m.diag_value.resize(m.n_unknown);
  for (int p = 0; p < m.n_unknown; ++p) m.diag_value[p] = std::max(1.0, diag_count(p));
}

// Reverse slots, degrees and the breadth-first spanning tree from the fixed triangles, which
// path a integrates the rotations along.
void spanning_tree(DecoderImpl& m, const Eigen::MatrixX3i& TT) {
  m.reverse_slot.assign(3 * static_cast<size_t>(m.nf), -1);
  m.degree.assign(m.nf, 0);
  for (int f = 0; f < m.nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      if (g < 0) continue;
      m.degree[f] += 2;
      for (int kk = 0; kk < 3; ++kk)
        if (TT(g, kk) == f) m.reverse_slot[3 * f + k] = kk;
    }
  std::vector<char> seen(m.nf, 0);
  std::vector<int> queue;
  queue.reserve(m.nf);
  for (int root : m.fixed_triangles) {
    seen[root] = 1;
    queue.push_back(root);
  }
  for (size_t q = 0; q < queue.size(); ++q) {
    const int f = queue[q];
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      if (g < 0 || seen[g]) continue;
      seen[g] = 1;
      queue.push_back(g);
      m.tree.emplace_back(g, 3 * f + k);
    }
  }
}

// The scalar dual-graph Laplacian L_s on the unknown triangles, factorised once: the
// preconditioner of path b.
void factor_dual_laplacian(DecoderImpl& m, const Eigen::MatrixX3i& TT) {
  std::vector<Eigen::Triplet<double>> t;
  for (int f = 0; f < m.nf; ++f) {
    const int pf = m.unknown[f];
    if (pf < 0) continue;
    t.emplace_back(pf, pf, std::max(1, m.degree[f]));
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      if (g >= 0 && m.unknown[g] >= 0) t.emplace_back(pf, m.unknown[g], -2.0);
    }
  }
  SparseMatrixd Ls(m.n_unknown, m.n_unknown);
  Ls.setFromTriplets(t.begin(), t.end());
  m.dual_laplacian.compute(Ls);
  if (m.dual_laplacian.info() != Eigen::Success)
    throw NumericalError("rotation system: factorising the dual-graph Laplacian failed");
}

// Poisson operators on the rest shape (D = Gᵀ A, K = Gᵀ A G) and the vertex components, each
// with its first vertex (pinned when the component has no constraint).
void poisson_operators(DecoderImpl& m, const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  const SparseMatrixd G = gradient_operator(V, F);
  const Eigen::VectorXd area = face_areas(V, F);
  Eigen::VectorXd a3(3 * m.nf);
  a3 << area, area, area;
  m.D = SparseMatrixd(G.transpose()) * a3.asDiagonal();
  m.K = (m.D * G).pruned();
  UnionFind vf(m.nv);
  for (int f = 0; f < m.nf; ++f) {
    vf.unite(F(f, 0), F(f, 1));
    vf.unite(F(f, 0), F(f, 2));
  }
  std::vector<char> referenced(m.nv, 0);
  for (int f = 0; f < m.nf; ++f)
    for (int k = 0; k < 3; ++k) referenced[F(f, k)] = 1;
  m.vertex_component.assign(m.nv, -1);
  std::map<int, int> root_to_component;
  for (int v = 0; v < m.nv; ++v) {
    if (!referenced[v]) continue;
    auto [it, inserted] = root_to_component.emplace(vf.find(v), static_cast<int>(root_to_component.size()));
    if (inserted) m.component_first_vertex.push_back(v);
    m.vertex_component[v] = it->second;
  }
}

// Path a: the rotations integrated along the spanning tree (R_fg T_g = T_f → T_g = R_fgᵀ T_f),
// with the largest equation residual over every slot in *residual.
std::vector<Eigen::Matrix3d> integrate_tree(const DecoderImpl& m, const Eigen::MatrixX3i& TT,
                                            const std::vector<Eigen::Matrix3d>& slot_rotations,
                                            const std::vector<Eigen::Matrix3d>& R, double* residual) {
  std::vector<Eigen::Matrix3d> T(m.nf);
  for (int f : m.fixed_triangles) T[f] = R[f].transpose();
  for (const auto& [child, slot] : m.tree) T[child] = slot_rotations[slot].transpose() * T[slot / 3];
  // Largest equation residual over every slot.
  std::vector<double> worst(m.nf, 0.0);
  parallel_range(m.nf, [&](int f) {
    double w = 0;
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      if (g >= 0) w = std::max(w, (slot_rotations[3 * f + k] * T[g] - T[f]).norm());
    }
    worst[f] = w;
  });
  *residual = 0;
  for (double w : worst) *residual = std::max(*residual, std::isnan(w) ? 1e300 : w);
  return T;
}

// Path b's right-hand side: the terms of the fixed neighbours at their tree-integrated T.
Eigen::MatrixXd cg_right_hand_side(const DecoderImpl& m, const Eigen::MatrixX3i& TT,
                                   const std::vector<Eigen::Matrix3d>& slot_rotations,
                                   const std::vector<Eigen::Matrix3d>& T) {
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(3 * m.n_unknown, 3);
  for (int f = 0; f < m.nf; ++f) {
    const int pf = m.unknown[f];
    if (pf < 0) continue;
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      if (g < 0 || m.unknown[g] >= 0) continue;
      const int kk = m.reverse_slot[3 * f + k];
      const Eigen::Matrix3d M = slot_rotations[3 * f + k] +
                                (kk >= 0 ? Eigen::Matrix3d(slot_rotations[3 * g + kk].transpose())
                                         : Eigen::Matrix3d(slot_rotations[3 * f + k]));
      b.middleRows<3>(3 * pf) += M * T[g];
    }
  }
  return b;
}

// The closest rotations of the solved unknown blocks X into R (fixed triangles untouched).
void orthonormalise_unknowns(const DecoderImpl& m, const Eigen::MatrixXd& X, std::vector<Eigen::Matrix3d>& R) {
  parallel_range(m.nf, [&](int f) {
    const int p = m.unknown[f];
    if (p >= 0) R[f] = orthonormalise(X.middleRows<3>(3 * p).transpose());
  });
}

// Path c with the block Cholesky: the blocks of N and the right-hand side, then the numeric
// factorisation (with a pooled factor) and the solve; returns the unknown blocks X.
Eigen::MatrixXd block_cholesky_rotations(const DecoderImpl& m, const Eigen::MatrixX3i& TT,
                                         const std::vector<Eigen::Matrix3d>& slot_rotations,
                                         const std::vector<Eigen::Matrix3d>& R, DecodeTiming& timing,
                                         Clock::time_point& t0) {
  std::vector<Eigen::Matrix3d> diag(m.n_unknown), off(m.edge_slot.size());
  for (int p = 0; p < m.n_unknown; ++p) diag[p] = m.diag_value[p] * Eigen::Matrix3d::Identity();
  parallel_range(static_cast<int>(off.size()), [&](int e) {
    const int slot = m.edge_slot[e], f = slot / 3, k = slot % 3, g = TT(f, k);
    const int kk = m.reverse_slot[slot];
    off[e] = -(slot_rotations[slot] + (kk >= 0 ? Eigen::Matrix3d(slot_rotations[3 * g + kk].transpose())
                                                : Eigen::Matrix3d(slot_rotations[slot])));
  });
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(3 * m.n_unknown, 3);
  for (const auto& s : m.slots) {
    const int pf = m.unknown[s.f], pg = m.unknown[s.g];
    const Eigen::Matrix3d& Rfg = slot_rotations[3 * s.f + s.k];
    if (pf < 0 && pg >= 0)
      b.middleRows<3>(3 * pg) += Rfg.transpose() * R[s.f].transpose();  // f fixed: T_f = R_fᵀ
    else if (pg < 0 && pf >= 0)
      b.middleRows<3>(3 * pf) += Rfg * R[s.g].transpose();              // g fixed
  }
  timing.assemble_ms += ms_since(t0);
  t0 = Clock::now();
  BlockCholesky3::Factor factor;
  {
    std::lock_guard<std::mutex> lock(m.mutex);
    if (!m.factor_pool.empty()) {
      factor = std::move(m.factor_pool.back());
      m.factor_pool.pop_back();
    }
  }
  const bool factorised = m.block_solver->factorize(diag, off, factor);
  if (factorised) m.block_solver->solve(factor, b);
  {
    std::lock_guard<std::mutex> lock(m.mutex);
    m.factor_pool.push_back(std::move(factor));
  }
  if (!factorised)
    throw NumericalError("rotation system: numeric factorisation failed (not positive definite)");
  Eigen::MatrixXd X = std::move(b);
  timing.rotation_solve_ms += ms_since(t0);
  return X;
}

// Path c with a sparse Cholesky: N (the pattern's base values minus the slot rotations) and the
// right-hand side of the fixed neighbours.
struct RotationSystem {
  SparseMatrixd N;
  Eigen::MatrixXd b;
};

RotationSystem rotation_system(const DecoderImpl& m, const std::vector<Eigen::Matrix3d>& slot_rotations,
                               const std::vector<Eigen::Matrix3d>& R) {
  RotationSystem sys{m.N_pattern, Eigen::MatrixXd::Zero(3 * m.n_unknown, 3)};
  double* val = sys.N.valuePtr();
  Eigen::MatrixXd& b = sys.b;
  for (const auto& s : m.slots) {
    const Eigen::Matrix3d& Rfg = slot_rotations[3 * s.f + s.k];
    const int pf = m.unknown[s.f], pg = m.unknown[s.g];
    if (s.value[0] >= 0) {
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) val[s.value[3 * a + c]] -= s.transposed ? Rfg(c, a) : Rfg(a, c);
    } else if (pf < 0 && pg >= 0) {
      b.middleRows<3>(3 * pg) += Rfg.transpose() * R[s.f].transpose();   // f fixed: T_f = R_fᵀ
    } else if (pg < 0 && pf >= 0) {
      b.middleRows<3>(3 * pf) += Rfg * R[s.g].transpose();               // g fixed
    }
  }
  return sys;
}

}  // namespace

RelativeRotationDecoder::RelativeRotationDecoder(std::shared_ptr<const EncodingTemplate> tmpl,
                                                 DecoderOptions options)
    : tmpl_(std::move(tmpl)), options_(options), impl_(std::make_unique<Impl>()) {
  if (!tmpl_) throw InputError("decoder: no template given");
  options_.validate();
  Impl& m = *impl_;
  const Eigen::MatrixX3i& F = tmpl_->faces();
  const Eigen::MatrixX3i& TT = tmpl_->adjacency();
  m.nf = tmpl_->triangle_count();
  m.nv = tmpl_->vertex_count();

  // Components of the dual graph: the first triangle of each is fixed.
  number_unknowns(m, TT);
  const Eigen::VectorXd diag_count = rotation_pattern(m, TT);
  if (options_.reuse_factorisations && m.n_unknown > 0 &&
      options_.rotation_solver == RotationSolver::kCholeskyRefactor)
    m.rotation_pool.push_back(m.analysed_rotation_solver());
  if (options_.reuse_factorisations && m.n_unknown > 0 &&
      options_.rotation_solver == RotationSolver::kPreconditionedCG)
    analyse_block_solver(m, diag_count);

  // Reverse slots, degrees, spanning tree and the scalar dual-graph Laplacian.
  spanning_tree(m, TT);
  if (options_.rotation_solver == RotationSolver::kPreconditionedCG && m.n_unknown > 0) factor_dual_laplacian(m, TT);

  // Poisson operators on the rest shape.
  poisson_operators(m, tmpl_->rest_vertices(), F);
  if (options_.reuse_factorisations)
    m.free_poisson = m.build_poisson(Eigen::VectorXi(), Eigen::VectorXd());
}

std::vector<Eigen::Matrix3d> RelativeRotationDecoder::solve_rotations(
    const std::vector<Eigen::Matrix3d>& slot_rotations) const {
  DecodeTiming timing;
  std::vector<Eigen::Matrix3d> R = rotations(slot_rotations, timing);
  set_last_timing(timing);
  return R;
}

std::vector<Eigen::Matrix3d> RelativeRotationDecoder::rotations(
    const std::vector<Eigen::Matrix3d>& slot_rotations, DecodeTiming& timing) const {
  const Impl& m = *impl_;
  const Eigen::MatrixX3i& TT = tmpl_->adjacency();
  if (static_cast<int>(slot_rotations.size()) != 3 * m.nf)
    throw InputError("decoder: expected " + std::to_string(3 * m.nf) + " slot rotations, found " +
                     std::to_string(slot_rotations.size()));
  auto t0 = Clock::now();
  std::vector<Eigen::Matrix3d> R(m.nf);
  for (int f : m.fixed_triangles) R[f].setIdentity();
  if (m.n_unknown == 0) return R;
  const bool use_tree = options_.rotation_solver == RotationSolver::kPreconditionedCG &&
                        options_.reuse_factorisations;

  Eigen::MatrixXd X;
  if (use_tree) {
    // a. Integrate along the spanning tree: R_fg T_g = T_f  →  T_g = R_fgᵀ T_f.
    double residual = 0;
    const std::vector<Eigen::Matrix3d> T = integrate_tree(m, TT, slot_rotations, R, &residual);
    timing.assemble_ms += ms_since(t0);
    if (residual <= options_.consistency_tolerance) {
      timing.rotation_path = 0;
      t0 = Clock::now();
      parallel_range(m.nf, [&](int f) {
        if (m.unknown[f] >= 0) R[f] = orthonormalise(T[f].transpose());
      });
      timing.orthonormalise_ms += ms_since(t0);
      return R;
    }
    if (residual <= options_.cg_start_residual) {
      // b. Nearly consistent: conjugate gradients from T.
      t0 = Clock::now();
      const Eigen::MatrixXd b = cg_right_hand_side(m, TT, slot_rotations, T);
      X.resize(3 * m.n_unknown, 3);
      for (int f = 0; f < m.nf; ++f)
        if (m.unknown[f] >= 0) X.middleRows<3>(3 * m.unknown[f]) = T[f];
      timing.assemble_ms += ms_since(t0);
      if (rotations_cg(slot_rotations, T, b, X, timing)) {
        timing.rotation_path = 1;
        t0 = Clock::now();
        orthonormalise_unknowns(m, X, R);
        timing.orthonormalise_ms += ms_since(t0);
        return R;
      }
    }
    t0 = Clock::now();
  }

  // c. Cholesky: values of N and the right-hand side b (3·#unknown by 3).
  timing.rotation_path = 2;
  if (m.block_solver) {
    X = block_cholesky_rotations(m, TT, slot_rotations, R, timing, t0);
    if (!X.allFinite()) throw NumericalError("rotation system: the solve produced NaN");
    t0 = Clock::now();
    orthonormalise_unknowns(m, X, R);
    timing.orthonormalise_ms += ms_since(t0);
    return R;
  }
  RotationSystem sys = rotation_system(m, slot_rotations, R);
  const SparseMatrixd& N = sys.N;
  const Eigen::MatrixXd& b = sys.b;
  timing.assemble_ms += ms_since(t0);

  t0 = Clock::now();
  if (options_.reuse_factorisations) {
    PooledRotationSolver solver(m);
    (*solver).factorize(N);
    if ((*solver).info() != Eigen::Success)
      throw NumericalError("rotation system: numeric factorisation failed");
    X = (*solver).solve(b);
  } else {
    Cholesky fresh;
    fresh.compute(N);
    if (fresh.info() != Eigen::Success)
      throw NumericalError("rotation system: factorisation failed");
    X = fresh.solve(b);
  }
  timing.rotation_solve_ms += ms_since(t0);
  if (!X.allFinite()) throw NumericalError("rotation system: the solve produced NaN");

  t0 = Clock::now();
  orthonormalise_unknowns(m, X, R);
  timing.orthonormalise_ms += ms_since(t0);
  return R;
}

Eigen::MatrixX3d RelativeRotationDecoder::solve_positions(const std::vector<Eigen::Matrix3d>& R,
                                                          const std::vector<Eigen::Matrix3d>& S,
                                                          const PositionConstraints* c) const {
  DecodeTiming timing;
  Eigen::MatrixX3d X = positions(R, S, c, timing);
  set_last_timing(timing);
  return X;
}

namespace {

// L Lᵀ z = z in place for a row-major panel z (n by w) through Eigen's simplicial factor L
// (compressed columns, the diagonal first in each): every entry of L is read once for all w
// columns, where Eigen's own sparse triangular solve walks L once per column. W = w when known
// at compile time (the inner loops then vectorise fully), else 0.
template <int W>
void llt_solve_panel(const SparseMatrixd& L, double* z, int w_runtime) {
  const int w = W > 0 ? W : w_runtime;
  const int n = static_cast<int>(L.cols());
  const int* outer = L.outerIndexPtr();
  const int* inner = L.innerIndexPtr();
  const double* value = L.valuePtr();
  for (int j = 0; j < n; ++j) {
    double* xj = z + static_cast<size_t>(j) * w;
    const double d = 1.0 / value[outer[j]];
    for (int c = 0; c < w; ++c) xj[c] *= d;
    for (int p = outer[j] + 1; p < outer[j + 1]; ++p) {
      double* xi = z + static_cast<size_t>(inner[p]) * w;
      const double l = value[p];
      for (int c = 0; c < w; ++c) xi[c] -= l * xj[c];
    }
  }
  for (int j = n - 1; j >= 0; --j) {
    double* xj = z + static_cast<size_t>(j) * w;
    for (int p = outer[j] + 1; p < outer[j + 1]; ++p) {
      const double* xi = z + static_cast<size_t>(inner[p]) * w;
      const double l = value[p];
      for (int c = 0; c < w; ++c) xj[c] -= l * xi[c];
    }
    const double d = 1.0 / value[outer[j]];
    for (int c = 0; c < w; ++c) xj[c] *= d;
  }
}

// The Poisson solve K X = rhs for every column of rhs through one pass over the factor
// (llt_solve_panel; the decoder's own three columns too), or Eigen's solve if the factor is not
// laid out as llt_solve_panel expects.
Eigen::MatrixXd panel_solve(const PoissonFactor& factor, const Eigen::MatrixXd& rhs) {
  const SparseMatrixd& L = factor.solver.matrixL().nestedExpression();
  for (int j = 0; j < L.cols(); ++j)  // the layout llt_solve_panel relies on
    if (L.outerIndexPtr()[j] == L.outerIndexPtr()[j + 1] || L.innerIndexPtr()[L.outerIndexPtr()[j]] != j)
      return factor.solver.solve(rhs);
  // Row-major panel in the factor's order: row i = row P⁻¹(i) of rhs.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> z = factor.solver.permutationP() * rhs;
  const int w = static_cast<int>(rhs.cols());
  if (w == 12)
    llt_solve_panel<12>(L, z.data(), w);
  else if (w == 3)
    llt_solve_panel<3>(L, z.data(), w);
  else
    llt_solve_panel<0>(L, z.data(), w);
  return factor.solver.permutationPinv() * z;
}

}  // namespace

Eigen::MatrixXd RelativeRotationDecoder::solve_positions_many(const std::vector<Eigen::Matrix3d>& U,
                                                              int fields) const {
  const Impl& m = *impl_;
  if (fields < 1 || U.size() != static_cast<size_t>(fields) * m.nf)
    throw InputError("decoder: expected " + std::to_string(m.nf) + " gradients per field");
  const std::shared_ptr<const PoissonFactor> factor =
      options_.reuse_factorisations ? m.free_poisson : m.build_poisson(Eigen::VectorXi(), Eigen::VectorXd());
  const int w = 3 * fields;
  Eigen::MatrixXd B(3 * m.nf, w);
  parallel_range(m.nf, [&](int f) {
    for (int j = 0; j < fields; ++j) {
      const Eigen::Matrix3d& u = U[static_cast<size_t>(j) * m.nf + f];
      for (int d = 0; d < 3; ++d)
        for (int col = 0; col < 3; ++col) B(d * m.nf + f, 3 * j + col) = u(col, d);
    }
  });
  Eigen::MatrixXd rhs = m.D * B;
  const Eigen::MatrixX3d& Vrest = tmpl_->rest_vertices();
  for (int v = 0; v < m.nv; ++v)
    if (factor->pinned[v])
      for (int j = 0; j < fields; ++j)
        rhs.block<1, 3>(v, 3 * j) = m.vertex_component[v] < 0 ? Eigen::RowVector3d(Vrest.row(v))
                                                                 : Eigen::RowVector3d::Zero();
  Eigen::MatrixXd X = panel_solve(*factor, rhs);
  if (!X.allFinite()) throw NumericalError("Poisson system: the solve produced NaN");
  return X;
}

Eigen::MatrixX3d RelativeRotationDecoder::positions(const std::vector<Eigen::Matrix3d>& R,
                                                    const std::vector<Eigen::Matrix3d>& S,
                                                    const PositionConstraints* c,
                                                    DecodeTiming& timing) const {
  const Impl& m = *impl_;
  if (static_cast<int>(R.size()) != m.nf || static_cast<int>(S.size()) != m.nf)
    throw InputError("decoder: expected " + std::to_string(m.nf) + " rotations and stretches");
  const bool constrained = c && !c->empty();
  Eigen::VectorXd weights;
  if (constrained) {
    const Eigen::Index nc = c->vertices.size();
    if (c->targets.rows() != nc)
      throw InputError("positional constraints: expected " + std::to_string(nc) +
                       " targets (one per vertex), found " + std::to_string(c->targets.rows()));
    if (c->weights.size() != 0 && c->weights.size() != nc)
      throw InputError("positional constraints: expected " + std::to_string(nc) +
                       " weights or none, found " + std::to_string(c->weights.size()));
    if (!c->targets.allFinite()) throw InputError("positional constraints: targets contain NaN");
    for (Eigen::Index i = 0; i < nc; ++i)
      if (c->vertices(i) < 0 || c->vertices(i) >= m.nv || m.vertex_component[c->vertices(i)] < 0)
        throw InputError("positional constraints: vertex " + std::to_string(c->vertices(i)) +
                         " is not a vertex of the template's triangles (" +
                         std::to_string(m.nv) + " vertices)");
    weights = c->weights.size() ? c->weights
                                : Eigen::VectorXd::Constant(nc, options_.constraint_weight);
    if (!(weights.array() > 0).all() || !weights.allFinite())
      throw InputError("positional constraints: weights must be positive and finite");
  }
  const Eigen::VectorXi key_vertices = constrained ? c->vertices : Eigen::VectorXi();
  auto t0 = Clock::now();

  // The factorisation for this constraint set: the unconstrained one built at set-up, the
  // cached constrained one if the set and weights match, else a new one (then cached).
  std::shared_ptr<const PoissonFactor> factor;
  if (!options_.reuse_factorisations) {
    factor = m.build_poisson(key_vertices, weights);
  } else if (!constrained) {
    factor = m.free_poisson;
  } else {
    {
      std::lock_guard<std::mutex> lock(m.mutex);
      factor = m.constrained_poisson;
    }
    const bool same = factor && factor->key_vertices.size() == key_vertices.size() &&
                      factor->key_vertices == key_vertices &&
                      factor->key_weights.size() == weights.size() && factor->key_weights == weights;
    if (!same) {
      factor = m.build_poisson(key_vertices, weights);
      std::lock_guard<std::mutex> lock(m.mutex);
      m.constrained_poisson = factor;
    }
  }

  // Right-hand side: divergence of the target gradients (+ constraint terms).
  Eigen::MatrixXd B(3 * m.nf, 3);
  parallel_range(m.nf, [&](int f) {
    const Eigen::Matrix3d U = R[f] * S[f];
    for (int d = 0; d < 3; ++d)
      for (int col = 0; col < 3; ++col) B(d * m.nf + f, col) = U(col, d);
  });
  Eigen::MatrixXd rhs = m.D * B;
  if (constrained)
    for (Eigen::Index i = 0; i < key_vertices.size(); ++i)
      rhs.row(key_vertices(i)) += weights(i) * c->targets.row(i);
  const Eigen::MatrixX3d& Vrest = tmpl_->rest_vertices();
  for (int v = 0; v < m.nv; ++v)
    if (factor->pinned[v])
      rhs.row(v) = m.vertex_component[v] < 0 ? Eigen::RowVector3d(Vrest.row(v))
                                             : Eigen::RowVector3d::Zero();
  Eigen::MatrixX3d X = panel_solve(*factor, rhs);
  timing.poisson_ms += ms_since(t0);
  if (!X.allFinite()) throw NumericalError("Poisson system: the solve produced NaN");
  return X;
}

// Preconditioned CG on N X = b (X = stacked T_f = R_fᵀ, 3 columns solved together), from the
// X given, with the dual-graph Laplacian in the gauge T as preconditioner. Returns false if it
// did not converge within cg_max_iterations (or stalls: see below).
bool RelativeRotationDecoder::rotations_cg(const std::vector<Eigen::Matrix3d>& slot_rotations,
                                           const std::vector<Eigen::Matrix3d>& T,
                                           const Eigen::MatrixXd& b, Eigen::MatrixXd& X,
                                           DecodeTiming& timing) const {
  const Impl& m = *impl_;
  const Eigen::MatrixX3i& TT = tmpl_->adjacency();
  auto t0 = Clock::now();
  std::vector<Eigen::Matrix3d> M(3 * static_cast<size_t>(m.nf));  // R_fg + R_gfᵀ per slot
  parallel_range(m.nf, [&](int f) {
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      if (g < 0) continue;
      const int kk = m.reverse_slot[3 * f + k];
      M[3 * f + k] = slot_rotations[3 * f + k] +
                     (kk >= 0 ? Eigen::Matrix3d(slot_rotations[3 * g + kk].transpose())
                              : Eigen::Matrix3d(slot_rotations[3 * f + k]));
    }
  });
  timing.assemble_ms += ms_since(t0);

  t0 = Clock::now();
  const int n = m.n_unknown;
  auto apply_N = [&](const Eigen::MatrixXd& Xin, Eigen::MatrixXd& out) {
    out.resize(3 * n, 3);
    parallel_range(m.nf, [&](int f) {
      const int pf = m.unknown[f];
      if (pf < 0) return;
      Eigen::Matrix3d acc = m.degree[f] * Xin.middleRows<3>(3 * pf);
      for (int k = 0; k < 3; ++k) {
        const int g = TT(f, k);
        if (g >= 0 && m.unknown[g] >= 0) acc -= M[3 * f + k] * Xin.middleRows<3>(3 * m.unknown[g]);
      }
      out.middleRows<3>(3 * pf) = acc;
    });
  };
  Eigen::MatrixXd Y(n, 9);
  auto precondition = [&](const Eigen::MatrixXd& r, Eigen::MatrixXd& z) {
    parallel_range(m.nf, [&](int f) {
      const int pf = m.unknown[f];
      if (pf < 0) return;
      const Eigen::Matrix3d y = T[f].transpose() * r.middleRows<3>(3 * pf);
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) Y(pf, 3 * a + c) = y(a, c);
    });
    const Eigen::MatrixXd Z = m.dual_laplacian.solve(Y);
    z.resize(3 * n, 3);
    parallel_range(m.nf, [&](int f) {
      const int pf = m.unknown[f];
      if (pf < 0) return;
      Eigen::Matrix3d y;
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) y(a, c) = Z(pf, 3 * a + c);
      z.middleRows<3>(3 * pf) = T[f] * y;
    });
  };
  const Eigen::RowVector3d b_norm = b.colwise().norm().cwiseMax(1e-300);
  Eigen::MatrixXd r, z, p, q;
  apply_N(X, q);
  r = b - q;
  bool converged = (r.colwise().norm().array() / b_norm.array()).maxCoeff() <= options_.cg_tolerance;
  if (!converged) {
    precondition(r, z);
    p = z;
    Eigen::RowVector3d rz = (r.cwiseProduct(z)).colwise().sum();
    double previous = 1e300;
    for (int it = 0; it < options_.cg_max_iterations; ++it) {
      apply_N(p, q);
      ++timing.cg_iterations;
      const Eigen::RowVector3d pq = (p.cwiseProduct(q)).colwise().sum();
      Eigen::RowVector3d alpha;
      for (int c = 0; c < 3; ++c) alpha(c) = pq(c) > 0 ? rz(c) / pq(c) : 0.0;
      X += p * alpha.asDiagonal();
      r -= q * alpha.asDiagonal();
      const double relative = (r.colwise().norm().array() / b_norm.array()).maxCoeff();
      if (relative <= options_.cg_tolerance) {
        converged = true;
        break;
      }
      // Stalling (less than a halving per two iterations): the encoding has holonomy this
      // preconditioner cannot see; leave it to the Cholesky solve.
      if (it % 2 == 1) {
        if (relative > 0.5 * previous) break;
        previous = relative;
      }
      precondition(r, z);
      const Eigen::RowVector3d rz_new = (r.cwiseProduct(z)).colwise().sum();
      Eigen::RowVector3d beta;
      for (int c = 0; c < 3; ++c) beta(c) = rz(c) > 0 ? rz_new(c) / rz(c) : 0.0;
      rz = rz_new;
      p = z + p * beta.asDiagonal();
    }
  }
  timing.rotation_solve_ms += ms_since(t0);
  return converged && X.allFinite();
}

Eigen::MatrixX3d RelativeRotationDecoder::decode(const Encoding& e) const {
  return decode(e, PositionConstraints{}, nullptr);
}

Eigen::MatrixX3d RelativeRotationDecoder::decode(const Encoding& e,
                                                 const PositionConstraints& constraints,
                                                 DecodeTiming* timing_out) const {
  DecodeTiming timing;
  const auto start = Clock::now();
  if (e.values.size() != tmpl_->encoding_size())
    throw InputError("decode: expected an encoding of " + std::to_string(tmpl_->encoding_size()) +
                     " values (15 per template triangle), found " +
                     std::to_string(e.values.size()));
  if (e.mean && e.mean->values.size() != e.values.size())
    throw InputError("decode: the encoding's mean has " + std::to_string(e.mean->values.size()) +
                     " values, expected " + std::to_string(e.values.size()));
  if (!e.values.allFinite()) throw InputError("decode: the encoding has NaN or infinite values");

  auto t0 = Clock::now();
  std::vector<Eigen::Matrix3d> slot_rotations, S;
  encoding_matrices(e, slot_rotations, S);
  timing.assemble_ms += ms_since(t0);
  std::vector<Eigen::Matrix3d> R = rotations(slot_rotations, timing);

  Eigen::MatrixX3d X;
  if (constraints.empty()) {
    X = positions(R, S, nullptr, timing);
    t0 = Clock::now();
    if (options_.align_to_template) X = apply(fit_rigid_motion(X, tmpl_->rest_vertices()), X);
    timing.finish_ms += ms_since(t0);
  } else {
    if (options_.orient_to_constraints && constraints.vertices.size() >= 3) {
      const Eigen::MatrixX3d free = positions(R, S, nullptr, timing);
      t0 = Clock::now();
      if (constraints.targets.rows() == constraints.vertices.size()) {
        Eigen::MatrixX3d A(constraints.vertices.size(), 3);
        for (Eigen::Index i = 0; i < A.rows(); ++i) {
          const int v = constraints.vertices(i);
          if (v < 0 || v >= free.rows())
            throw InputError("positional constraints: vertex " + std::to_string(v) +
                             " is out of range (" + std::to_string(free.rows()) + " vertices)");
          A.row(i) = free.row(v);
        }
        const RigidMotion fit = fit_rigid_motion(A, constraints.targets, constraints.weights);
        for (auto& r : R) r = fit.R * r;
      }
      timing.finish_ms += ms_since(t0);
    }
    X = positions(R, S, &constraints, timing);
  }
  if (!X.allFinite()) throw NumericalError("decode produced non-finite positions");
  timing.total_ms = ms_since(start);
  set_last_timing(timing);
  if (timing_out) *timing_out = timing;
  return X;
}

Eigen::MatrixX3d decode(std::shared_ptr<const EncodingTemplate> tmpl, const Encoding& e,
                        const DecoderOptions& options) {
  RelativeRotationDecoder decoder(std::move(tmpl), options);
  return decoder.decode(e);
}

}  // namespace bodymodel
