#include "encoding/relative_rotation_decoder.h"

#include <tbb/parallel_for.h>

#include <Eigen/CholmodSupport>
#include <Eigen/Sparse>
#include <algorithm>
#include <chrono>
#include <map>
#include <numeric>
#include <string>

#include "core/error.h"
#include "core/geometry.h"
#include "encoding/deformation_gradient.h"

namespace bodymodel {

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// CHOLMOD's simplicial LLᵀ: on this machine (ATLAS BLAS, 2 cores) it factorises the 3·#F
// rotation system faster than the supernodal variant (≈ 190 vs 350 ms CPU for the body) and
// solves small multi-column right-hand sides faster too.
using Cholesky = Eigen::CholmodSimplicialLLT<SparseMatrixd, Eigen::Lower>;
using SimplicialCholesky = Cholesky;

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
  if (!(constraint_weight > 0) || !std::isfinite(constraint_weight))
    throw InputError("decoder options: constraint_weight must be positive and finite, found " +
                     std::to_string(constraint_weight));
}

struct RelativeRotationDecoder::Impl {
  int nf = 0, nv = 0;
  // ---- rotation system ----
  std::vector<int> unknown;            // #F: unknown block index, −1 for a fixed triangle
  std::vector<int> fixed_triangles;    // one per component
  int n_unknown = 0;
  struct Slot {
    int f, g, k;                       // slot k of triangle f, neighbour g
    int value[9];                      // value indices of the lower block, −1 if not stored
    bool transposed;                   // block stored at (g, f): add −R_fgᵀ
  };
  std::vector<Slot> slots;
  SparseMatrixd N;                     // lower triangle of the normal matrix
  Eigen::VectorXd N_base_values;       // diagonal filled, off-diagonal zero
  Cholesky rotation_solver;
  bool rotation_analysed = false;
  bool rotation_factorised = false;    // rotation_solver holds the factor of some N
  // ---- preconditioned CG on the rotation system ----
  std::vector<int> reverse_slot;       // 3#F: k' with TT(g, k') = f for g = TT(f, k), or −1
  std::vector<int> degree;             // #F: diagonal of N (2 per neighbour)
  std::vector<std::pair<int, int>> tree;  // BFS order: (child, slot 3·parent + k) per non-root
  SimplicialCholesky dual_laplacian;             // L_s on the unknown triangles, factorised once
  std::vector<Eigen::Matrix3d> M;      // 3#F: R_fg + R_gfᵀ (off-diagonal block −M)
  // ---- Poisson ----
  SparseMatrixd K;                     // Gᵀ A G, #V by #V (full symmetric)
  SparseMatrixd D;                     // Gᵀ A, #V by 3#F
  std::vector<int> vertex_component;   // #V, −1 for unreferenced vertices
  std::vector<int> component_first_vertex;
  std::unique_ptr<SimplicialCholesky> poisson_solver;
  std::vector<char> poisson_pinned;
  Eigen::VectorXi poisson_key_vertices;  // constraint set of the current factorisation
  Eigen::VectorXd poisson_key_weights;
  bool poisson_ready = false;
};

RelativeRotationDecoder::~RelativeRotationDecoder() = default;

int RelativeRotationDecoder::component_count() const {
  return static_cast<int>(impl_->fixed_triangles.size());
}

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

  // Pattern of the lower triangle of N (block rows/cols = unknown indices).
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<size_t>(m.n_unknown) * 3 + static_cast<size_t>(m.nf) * 27);
  Eigen::VectorXd diag_count = Eigen::VectorXd::Zero(m.n_unknown);
  for (int f = 0; f < m.nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      if (g < 0) continue;
      m.slots.push_back(Impl::Slot{f, g, k, {}, false});
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
  m.N.resize(3 * m.n_unknown, 3 * m.n_unknown);
  m.N.setFromTriplets(trip.begin(), trip.end());
  m.N.makeCompressed();
  m.N_base_values = Eigen::VectorXd::Zero(m.N.nonZeros());
  for (int p = 0; p < m.n_unknown; ++p)
    for (int a = 0; a < 3; ++a)
      m.N_base_values(value_index(m.N, 3 * p + a, 3 * p + a)) = std::max(1.0, diag_count(p));
  for (auto& s : m.slots) {
    const int pf = m.unknown[s.f], pg = m.unknown[s.g];
    std::fill(std::begin(s.value), std::end(s.value), -1);
    if (pf < 0 || pg < 0) continue;
    // Block (f, g) of N gets −R_fg; stored in the lower triangle at (max, min).
    s.transposed = pf < pg;
    const int hi = std::max(pf, pg), lo = std::min(pf, pg);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) s.value[3 * a + b] = value_index(m.N, 3 * hi + a, 3 * lo + b);
  }
  if (options_.reuse_factorisations && m.n_unknown > 0 &&
      options_.rotation_solver == RotationSolver::kCholeskyRefactor)
    analyse_rotation_pattern();

  // CG: reverse slots, degrees, spanning tree and the scalar dual-graph Laplacian.
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
  {
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
    if (m.n_unknown > 0) {
      m.dual_laplacian.compute(Ls);
      if (m.dual_laplacian.info() != Eigen::Success)
        throw NumericalError("rotation system: factorising the dual-graph Laplacian failed");
    }
  }

  // Poisson operators on the rest shape.
  const Eigen::MatrixX3d& V = tmpl_->rest_vertices();
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

void RelativeRotationDecoder::analyse_rotation_pattern() {
  Impl& m = *impl_;
  SparseMatrixd pattern = m.N;
  std::copy(m.N_base_values.data(), m.N_base_values.data() + m.N_base_values.size(),
            pattern.valuePtr());
  m.rotation_solver.analyzePattern(pattern);
  if (m.rotation_solver.info() != Eigen::Success)
    throw NumericalError("rotation system: symbolic analysis failed");
  m.rotation_analysed = true;
}

std::vector<Eigen::Matrix3d> RelativeRotationDecoder::solve_rotations(
    const std::vector<Eigen::Matrix3d>& slot_rotations) {
  Impl& m = *impl_;
  if (static_cast<int>(slot_rotations.size()) != 3 * m.nf)
    throw InputError("decoder: expected " + std::to_string(3 * m.nf) + " slot rotations, found " +
                     std::to_string(slot_rotations.size()));
  auto t0 = Clock::now();
  const Eigen::Matrix3d Rg = Eigen::Matrix3d::Identity();
  std::vector<Eigen::Matrix3d> R(m.nf);
  for (int f : m.fixed_triangles) R[f] = Rg;
  if (m.n_unknown == 0) return R;
  if (options_.rotation_solver == RotationSolver::kPreconditionedCG && options_.reuse_factorisations) {
    Eigen::MatrixXd X;
    if (solve_rotations_cg(slot_rotations, R, X)) {
      t0 = Clock::now();
      parallel_range(m.nf, [&](int f) {
        const int p = m.unknown[f];
        if (p >= 0) R[f] = closest_rotation(X.middleRows<3>(3 * p).transpose());
      });
      timing_.orthonormalise_ms += ms_since(t0);
      return R;
    }
    t0 = Clock::now();  // not converged: fall back to Cholesky
  }

  // Values of N and the right-hand side b (3·#unknown by 3).
  double* val = m.N.valuePtr();
  std::copy(m.N_base_values.data(), m.N_base_values.data() + m.N_base_values.size(), val);
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(3 * m.n_unknown, 3);
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
  timing_.assemble_ms += ms_since(t0);

  t0 = Clock::now();
  Eigen::MatrixXd X;
  if (options_.reuse_factorisations) {
    if (!m.rotation_analysed) analyse_rotation_pattern();
    m.rotation_factorised = false;
    m.rotation_solver.factorize(m.N);
    if (m.rotation_solver.info() != Eigen::Success)
      throw NumericalError("rotation system: numeric factorisation failed");
    m.rotation_factorised = true;
    X = m.rotation_solver.solve(b);
  } else {
    Cholesky fresh;
    fresh.compute(m.N);
    if (fresh.info() != Eigen::Success)
      throw NumericalError("rotation system: factorisation failed");
    X = fresh.solve(b);
  }
  timing_.rotation_solve_ms += ms_since(t0);
  if (!X.allFinite()) throw NumericalError("rotation system: the solve produced NaN");

  t0 = Clock::now();
  parallel_range(m.nf, [&](int f) {
    const int p = m.unknown[f];
    if (p >= 0) R[f] = closest_rotation(X.middleRows<3>(3 * p).transpose());
  });
  timing_.orthonormalise_ms += ms_since(t0);
  return R;
}

Eigen::MatrixX3d RelativeRotationDecoder::solve_positions(const std::vector<Eigen::Matrix3d>& R,
                                                          const std::vector<Eigen::Matrix3d>& S,
                                                          const PositionConstraints* c) {
  Impl& m = *impl_;
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

  // (Re)factorise when needed.
  const bool same_key = m.poisson_ready && key_vertices.size() == m.poisson_key_vertices.size() &&
                        key_vertices == m.poisson_key_vertices &&
                        weights.size() == m.poisson_key_weights.size() &&
                        weights == m.poisson_key_weights;
  if (!same_key || !options_.reuse_factorisations) {
    std::vector<char> has_constraint(m.component_first_vertex.size(), 0);
    SparseMatrixd A = m.K;
    if (constrained) {
      std::vector<Eigen::Triplet<double>> t;
      for (Eigen::Index i = 0; i < key_vertices.size(); ++i) {
        t.emplace_back(key_vertices(i), key_vertices(i), weights(i));
        has_constraint[m.vertex_component[key_vertices(i)]] = 1;
      }
      SparseMatrixd W(m.nv, m.nv);
      W.setFromTriplets(t.begin(), t.end());
      A += W;
    }
    m.poisson_pinned.assign(m.nv, 0);
    for (int v = 0; v < m.nv; ++v)
      if (m.vertex_component[v] < 0) m.poisson_pinned[v] = 1;
    for (size_t comp = 0; comp < m.component_first_vertex.size(); ++comp)
      if (!has_constraint[comp]) m.poisson_pinned[m.component_first_vertex[comp]] = 1;
    const auto& pinned = m.poisson_pinned;
    A.prune([&](Eigen::Index r, Eigen::Index col, double) {
      return r == col || (!pinned[r] && !pinned[col]);
    });
    // Pinned rows: identity (a missing diagonal entry of an unreferenced vertex is inserted).
    std::vector<Eigen::Triplet<double>> diag;
    for (int v = 0; v < m.nv; ++v)
      if (pinned[v]) diag.emplace_back(v, v, 1.0 - A.coeff(v, v));
    SparseMatrixd P(m.nv, m.nv);
    P.setFromTriplets(diag.begin(), diag.end());
    A += P;
    m.poisson_solver = std::make_unique<SimplicialCholesky>();
    m.poisson_solver->compute(A);
    if (m.poisson_solver->info() != Eigen::Success)
      throw NumericalError("Poisson system: factorisation failed");
    m.poisson_key_vertices = key_vertices;
    m.poisson_key_weights = weights;
    m.poisson_ready = true;
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
    if (m.poisson_pinned[v])
      rhs.row(v) = m.vertex_component[v] < 0 ? Eigen::RowVector3d(Vrest.row(v))
                                             : Eigen::RowVector3d::Zero();
  Eigen::MatrixX3d X = m.poisson_solver->solve(rhs);
  timing_.poisson_ms += ms_since(t0);
  if (!X.allFinite()) throw NumericalError("Poisson system: the solve produced NaN");
  return X;
}

// Preconditioned CG on N X = b (X = stacked T_f = R_fᵀ, 3 columns solved together).
// Returns false if it did not converge within cg_max_iterations.
bool RelativeRotationDecoder::solve_rotations_cg(const std::vector<Eigen::Matrix3d>& slot_rotations,
                                                 const std::vector<Eigen::Matrix3d>& R_fixed,
                                                 Eigen::MatrixXd& X) {
  Impl& m = *impl_;
  const Eigen::MatrixX3i& TT = tmpl_->adjacency();
  auto t0 = Clock::now();
  m.M.resize(3 * static_cast<size_t>(m.nf));
  parallel_range(m.nf, [&](int f) {
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      if (g < 0) continue;
      const int kk = m.reverse_slot[3 * f + k];
      m.M[3 * f + k] = slot_rotations[3 * f + k] +
                       (kk >= 0 ? Eigen::Matrix3d(slot_rotations[3 * g + kk].transpose())
                                : Eigen::Matrix3d(slot_rotations[3 * f + k]));
    }
  });
  // Right-hand side from the fixed triangles, and the gauge T̃ along the spanning tree.
  const int n = m.n_unknown;
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(3 * n, 3);
  std::vector<Eigen::Matrix3d> T(m.nf);
  for (int f : m.fixed_triangles) T[f] = R_fixed[f].transpose();
  for (int f = 0; f < m.nf; ++f) {
    const int pf = m.unknown[f];
    if (pf < 0) continue;
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      if (g >= 0 && m.unknown[g] < 0) b.middleRows<3>(3 * pf) += m.M[3 * f + k] * T[g];
    }
  }
  for (const auto& [child, slot] : m.tree)  // R_fg T_g = T_f  →  T_g = R_fgᵀ T_f
    T[child] = slot_rotations[slot].transpose() * T[slot / 3];
  timing_.assemble_ms += ms_since(t0);

  t0 = Clock::now();
  auto apply_N = [&](const Eigen::MatrixXd& Xin, Eigen::MatrixXd& out) {
    out.resize(3 * n, 3);
    parallel_range(m.nf, [&](int f) {
      const int pf = m.unknown[f];
      if (pf < 0) return;
      Eigen::Matrix3d acc = m.degree[f] * Xin.middleRows<3>(3 * pf);
      for (int k = 0; k < 3; ++k) {
        const int g = TT(f, k);
        if (g >= 0 && m.unknown[g] >= 0) acc -= m.M[3 * f + k] * Xin.middleRows<3>(3 * m.unknown[g]);
      }
      out.middleRows<3>(3 * pf) = acc;
    });
  };
  Eigen::MatrixXd Y(n, 9);
  auto apply_P_inverse = [&](const Eigen::MatrixXd& r, Eigen::MatrixXd& z) {
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
  // PCG from X with preconditioner `precondition`; gives up when the relative residual is
  // still above `give_up_above` after `give_up_after` iterations.
  int total_iterations = 0;
  auto pcg = [&](const auto& precondition, double tolerance, int give_up_after, double give_up_above) {
    Eigen::MatrixXd r, z, p, q;
    apply_N(X, q);
    r = b - q;
    precondition(r, z);
    p = z;
    Eigen::RowVector3d rz = (r.cwiseProduct(z)).colwise().sum();
    for (int it = 0; it < options_.cg_max_iterations; ++it) {
      apply_N(p, q);
      ++total_iterations;
      const Eigen::RowVector3d pq = (p.cwiseProduct(q)).colwise().sum();
      Eigen::RowVector3d alpha;
      for (int c = 0; c < 3; ++c) alpha(c) = pq(c) > 0 ? rz(c) / pq(c) : 0.0;
      X += p * alpha.asDiagonal();
      r -= q * alpha.asDiagonal();
      const double relative = (r.colwise().norm().array() / b_norm.array()).maxCoeff();
      if (relative <= tolerance) return true;
      if (it + 1 >= give_up_after && relative > give_up_above) return false;
      precondition(r, z);
      const Eigen::RowVector3d rz_new = (r.cwiseProduct(z)).colwise().sum();
      Eigen::RowVector3d beta;
      for (int c = 0; c < 3; ++c) beta(c) = rz(c) > 0 ? rz_new(c) / rz(c) : 0.0;
      rz = rz_new;
      p = z + p * beta.asDiagonal();
    }
    return false;
  };
  X = Eigen::MatrixXd::Zero(3 * n, 3);
  // Tree-gauge Laplacian preconditioner: exact for consistent encodings. An inconsistent
  // encoding (a blend, a model sample) converges slowly with it: give up after 3 iterations
  // and let the caller use the Cholesky refactorisation. (Preconditioning with the Cholesky
  // factor of a NEARBY encoding was tried: 7 iterations at Δt = 0.01 along a horse blend, 15
  // at Δt = 0.05 — not worth it.)
  bool converged = pcg(apply_P_inverse, options_.cg_tolerance, 3, 1e-4);
  const int it = total_iterations;
  timing_.cg_iterations = it;
  timing_.rotation_solve_ms += ms_since(t0);
  return converged && X.allFinite();
}

Eigen::MatrixX3d RelativeRotationDecoder::decode(const Encoding& e) {
  return decode(e, PositionConstraints{});
}

Eigen::MatrixX3d RelativeRotationDecoder::decode(const Encoding& e,
                                                 const PositionConstraints& constraints) {
  timing_ = DecodeTiming{};
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
  timing_.assemble_ms += ms_since(t0);
  std::vector<Eigen::Matrix3d> R = solve_rotations(slot_rotations);

  Eigen::MatrixX3d X;
  if (constraints.empty()) {
    X = solve_positions(R, S, nullptr);
    t0 = Clock::now();
    if (options_.align_to_template) X = apply(fit_rigid_motion(X, tmpl_->rest_vertices()), X);
    timing_.finish_ms += ms_since(t0);
  } else {
    if (options_.orient_to_constraints && constraints.vertices.size() >= 3) {
      const Eigen::MatrixX3d free = solve_positions(R, S, nullptr);
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
      timing_.finish_ms += ms_since(t0);
    }
    X = solve_positions(R, S, &constraints);
  }
  if (!X.allFinite()) throw NumericalError("decode produced non-finite positions");
  timing_.total_ms = ms_since(start);
  return X;
}

Eigen::MatrixX3d decode(std::shared_ptr<const EncodingTemplate> tmpl, const Encoding& e,
                        const DecoderOptions& options) {
  RelativeRotationDecoder decoder(std::move(tmpl), options);
  return decoder.decode(e);
}

}  // namespace bodymodel
