#include "encoding/block_cholesky.h"

#include <Eigen/Cholesky>
#include <Eigen/OrderingMethods>
#include <Eigen/Sparse>
#include <algorithm>
#include <atomic>
#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "core/error.h"

namespace bodymodel {

namespace {

// Upper part of the permuted block graph per column (rows i < k) and its elimination tree.
struct PermutedGraph {
  std::vector<std::vector<int>> up_rows;  // per column k: rows i < k with C(i, k) ≠ 0
  std::vector<int> parent;                // elimination tree, −1 for roots
};

PermutedGraph permuted_graph(int n, const std::vector<std::pair<int, int>>& lower,
                             const std::vector<int>& inverse) {
  PermutedGraph g;
  g.up_rows.assign(n, {});
  for (const auto& [r0, c0] : lower) {
    const int r = inverse[r0], c = inverse[c0];
    if (r < c)
      g.up_rows[c].push_back(r);
    else
      g.up_rows[r].push_back(c);
  }
  // Liu's algorithm with path compression.
  g.parent.assign(n, -1);
  std::vector<int> ancestor(n, -1);
  for (int k = 0; k < n; ++k)
    for (int i : g.up_rows[k])
      for (int j = i; j != -1 && j < k;) {
        const int next = ancestor[j];
        ancestor[j] = k;
        if (next == -1) g.parent[j] = k;
        j = next;
      }
  return g;
}

// Pattern of row k of L (the reach of column k's upper entries in the elimination tree), in
// s[top..n); returns top. `flag` marks visited nodes with k.
int ereach(int k, const std::vector<int>& up_rows, const std::vector<int>& parent,
           std::vector<int>& flag, std::vector<int>& s, std::vector<int>& path) {
  const int n = static_cast<int>(parent.size());
  int top = n;
  flag[k] = k;
  for (int i : up_rows) {
    int len = 0;
    for (int j = i; flag[j] != k; j = parent[j]) {
      path[len++] = j;
      flag[j] = k;
    }
    while (len > 0) s[--top] = path[--len];
  }
  return top;
}


// C (m by n, leading dimension ldc) = A Bᵀ with A m by k (lda) and B n by k (ldb), all
// column-major: the update product of the wider supernodes. The portable version is Eigen's
// GEMM; where the CPU has AVX2 and FMA (checked once at run time; the rest of the project is
// built for plain x86-64) a 12×4 register-tiled kernel computes the same products. The two
// round differently, but one machine always takes the same path, so results are reproducible.
void gemm_nt_portable(int m, int n, int k, const double* A, long lda, const double* B, long ldb,
                      double* C, long ldc) {
  using Strided = Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>>;
  Eigen::Map<Eigen::MatrixXd, 0, Eigen::OuterStride<>> out(C, m, n, Eigen::OuterStride<>(ldc));
  out.noalias() = Strided(A, m, k, Eigen::OuterStride<>(lda)) *
                  Strided(B, n, k, Eigen::OuterStride<>(ldb)).transpose();
}

#if defined(__x86_64__) && defined(__GNUC__)
#define BODYMODEL_HAVE_AVX2_KERNEL 1
__attribute__((target("avx2,fma"))) void gemm_nt_avx2(int m, int n, int k, const double* A,
                                                      long lda, const double* B, long ldb,
                                                      double* C, long ldc) {
  int j = 0;
  for (; j + 4 <= n; j += 4) {
    int i = 0;
    for (; i + 12 <= m; i += 12) {
      __m256d c00 = _mm256_setzero_pd(), c01 = c00, c02 = c00, c10 = c00, c11 = c00, c12 = c00,
              c20 = c00, c21 = c00, c22 = c00, c30 = c00, c31 = c00, c32 = c00;
      const double* a = A + i;
      const double* b = B + j;
      for (int p = 0; p < k; ++p, a += lda, b += ldb) {
        const __m256d a0 = _mm256_loadu_pd(a), a1 = _mm256_loadu_pd(a + 4),
                      a2 = _mm256_loadu_pd(a + 8);
        __m256d bb = _mm256_broadcast_sd(b);
        c00 = _mm256_fmadd_pd(a0, bb, c00), c01 = _mm256_fmadd_pd(a1, bb, c01), c02 = _mm256_fmadd_pd(a2, bb, c02);
        bb = _mm256_broadcast_sd(b + 1);
        c10 = _mm256_fmadd_pd(a0, bb, c10), c11 = _mm256_fmadd_pd(a1, bb, c11), c12 = _mm256_fmadd_pd(a2, bb, c12);
        bb = _mm256_broadcast_sd(b + 2);
        c20 = _mm256_fmadd_pd(a0, bb, c20), c21 = _mm256_fmadd_pd(a1, bb, c21), c22 = _mm256_fmadd_pd(a2, bb, c22);
        bb = _mm256_broadcast_sd(b + 3);
        c30 = _mm256_fmadd_pd(a0, bb, c30), c31 = _mm256_fmadd_pd(a1, bb, c31), c32 = _mm256_fmadd_pd(a2, bb, c32);
      }
      double* c = C + i + j * ldc;
      _mm256_storeu_pd(c, c00), _mm256_storeu_pd(c + 4, c01), _mm256_storeu_pd(c + 8, c02);
      c += ldc;
      _mm256_storeu_pd(c, c10), _mm256_storeu_pd(c + 4, c11), _mm256_storeu_pd(c + 8, c12);
      c += ldc;
      _mm256_storeu_pd(c, c20), _mm256_storeu_pd(c + 4, c21), _mm256_storeu_pd(c + 8, c22);
      c += ldc;
      _mm256_storeu_pd(c, c30), _mm256_storeu_pd(c + 4, c31), _mm256_storeu_pd(c + 8, c32);
    }
    for (; i + 4 <= m; i += 4) {
      __m256d c0 = _mm256_setzero_pd(), c1 = c0, c2 = c0, c3 = c0;
      const double* a = A + i;
      const double* b = B + j;
      for (int p = 0; p < k; ++p, a += lda, b += ldb) {
        const __m256d a0 = _mm256_loadu_pd(a);
        c0 = _mm256_fmadd_pd(a0, _mm256_broadcast_sd(b), c0);
        c1 = _mm256_fmadd_pd(a0, _mm256_broadcast_sd(b + 1), c1);
        c2 = _mm256_fmadd_pd(a0, _mm256_broadcast_sd(b + 2), c2);
        c3 = _mm256_fmadd_pd(a0, _mm256_broadcast_sd(b + 3), c3);
      }
      double* c = C + i + j * ldc;
      _mm256_storeu_pd(c, c0), _mm256_storeu_pd(c + ldc, c1), _mm256_storeu_pd(c + 2 * ldc, c2),
          _mm256_storeu_pd(c + 3 * ldc, c3);
    }
    for (; i < m; ++i)
      for (int jj = j; jj < j + 4; ++jj) {
        double sum = 0;
        for (int p = 0; p < k; ++p) sum += A[i + p * lda] * B[jj + p * ldb];
        C[i + jj * ldc] = sum;
      }
  }
  for (; j < n; ++j) {
    int i = 0;
    for (; i + 4 <= m; i += 4) {
      __m256d c0 = _mm256_setzero_pd();
      for (int p = 0; p < k; ++p)
        c0 = _mm256_fmadd_pd(_mm256_loadu_pd(A + i + p * lda), _mm256_broadcast_sd(B + j + p * ldb), c0);
      _mm256_storeu_pd(C + i + j * ldc, c0);
    }
    for (; i < m; ++i) {
      double sum = 0;
      for (int p = 0; p < k; ++p) sum += A[i + p * lda] * B[j + p * ldb];
      C[i + j * ldc] = sum;
    }
  }
}
#endif

using GemmKernel = void (*)(int, int, int, const double*, long, const double*, long, double*, long);
GemmKernel gemm_nt_kernel() {
#ifdef BODYMODEL_HAVE_AVX2_KERNEL
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return gemm_nt_avx2;
#endif
  return gemm_nt_portable;
}
const GemmKernel gemm_nt = gemm_nt_kernel();

using Panel = Eigen::Map<Eigen::MatrixXd>;
using ConstPanel = Eigen::Map<const Eigen::MatrixXd>;

// AMD ordering of the block graph, then a postorder of its elimination tree (so every subtree,
// and every supernode, is a contiguous range of columns); returns perm[new] = old.
std::vector<int> fill_reducing_order(int n, const std::vector<std::pair<int, int>>& lower) {
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(static_cast<size_t>(n) + 2 * lower.size());
  for (int i = 0; i < n; ++i) t.emplace_back(i, i, 1.0);
  for (const auto& [r, c] : lower) {
    if (r <= c || r >= n || c < 0) throw NumericalError("block Cholesky: bad block (internal error)");
    t.emplace_back(r, c, 1.0);
    t.emplace_back(c, r, 1.0);
  }
  Eigen::SparseMatrix<double> P(n, n);
  P.setFromTriplets(t.begin(), t.end());
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> amd_perm;
  Eigen::AMDOrdering<int> amd;
  amd(P.selfadjointView<Eigen::Lower>(), amd_perm);
  std::vector<int> amd_order(n), inverse(n);  // amd_order[new] = old
  for (int i = 0; i < n; ++i) amd_order[i] = amd_perm.indices()(i);
  for (int i = 0; i < n; ++i) inverse[amd_order[i]] = i;
  const PermutedGraph g = permuted_graph(n, lower, inverse);
  std::vector<std::vector<int>> children(n);
  std::vector<int> roots;
  for (int k = n - 1; k >= 0; --k)  // reversed, so the stack below visits children ascending
    (g.parent[k] >= 0 ? children[g.parent[k]] : roots).push_back(k);
  std::vector<int> post;
  post.reserve(n);
  std::vector<std::pair<int, size_t>> stack;
  for (auto r = roots.rbegin(); r != roots.rend(); ++r) {
    stack.emplace_back(*r, 0);
    while (!stack.empty()) {
      auto& [v, next] = stack.back();
      if (next < children[v].size()) {
        const int c = children[v][children[v].size() - 1 - next];
        ++next;
        stack.emplace_back(c, 0);
      } else {
        post.push_back(v);
        stack.pop_back();
      }
    }
  }
  std::vector<int> perm(n);
  for (int i = 0; i < n; ++i) perm[i] = amd_order[post[i]];
  return perm;
}

// Row patterns of the columns of L (Lp/Li, rows ascending, diagonal first) and the column counts.
struct ColumnPatterns {
  std::vector<int> count;
  std::vector<long long> Lp;
  std::vector<int> Li;
};

ColumnPatterns column_patterns(int n, const PermutedGraph& g) {
  const std::vector<int>& parent = g.parent;
  ColumnPatterns cp;
  std::vector<int>& count = cp.count;
  count.assign(n, 1);
  std::vector<int> flag(n, -1), s(n), path(n);
  for (int k = 0; k < n; ++k) {
    const int top = ereach(k, g.up_rows[k], parent, flag, s, path);
    for (int p = top; p < n; ++p) ++count[s[p]];
  }
  std::vector<long long>& Lp = cp.Lp;
  Lp.assign(n + 1, 0);
  for (int k = 0; k < n; ++k) Lp[k + 1] = Lp[k] + count[k];
  cp.Li.resize(Lp[n]);
  {
    std::vector<long long> next(Lp.begin(), Lp.end() - 1);
    std::fill(flag.begin(), flag.end(), -1);
    for (int k = 0; k < n; ++k) {
      cp.Li[next[k]++] = k;
      const int top = ereach(k, g.up_rows[k], parent, flag, s, path);
      for (int p = top; p < n; ++p) cp.Li[next[s[p]]++] = k;
    }
  }
  return cp;
}

// Fundamental supernodes: column j joins j − 1's when j − 1's only parent is j, j has no other
// child, and the patterns nest exactly. Returns each supernode's first column, then n.
std::vector<int> fundamental_supernodes(const std::vector<int>& parent, const std::vector<int>& count) {
  const int n = static_cast<int>(parent.size());
  std::vector<int> child_count(n, 0);
  for (int k = 0; k < n; ++k)
    if (parent[k] >= 0) ++child_count[parent[k]];
  std::vector<int> fund_first;
  for (int j = 0; j < n; ++j)
    if (j == 0 || !(parent[j - 1] == j && count[j - 1] == count[j] + 1 && child_count[j] == 1))
      fund_first.push_back(j);
  fund_first.push_back(n);
  return fund_first;
}

// Per supernode its row list (its own columns, then the union of its columns' rows below), where
// its panel starts in the values, and the number of 3×3 blocks stored.
struct SupernodeRows {
  std::vector<int> rows_begin, rows;
  std::vector<long long> value_offset;
  long long factor_blocks = 0;
};

SupernodeRows supernode_rows(int n, const std::vector<int>& super_first, const ColumnPatterns& cp) {
  const int ns = static_cast<int>(super_first.size()) - 1;
  const std::vector<long long>& Lp = cp.Lp;
  const std::vector<int>& Li = cp.Li;
  SupernodeRows sr;
  std::vector<int>& rows = sr.rows;
  sr.rows_begin.assign(ns + 1, 0);
  std::vector<int> flag(n, -1);
  sr.value_offset.assign(ns + 1, 0);
  for (int sn = 0; sn < ns; ++sn) {
    const int first = super_first[sn], last = super_first[sn + 1] - 1;
    sr.rows_begin[sn] = static_cast<int>(rows.size());
    for (int j = first; j <= last; ++j) rows.push_back(j);
    std::vector<int> below;
    for (int j = first; j <= last; ++j)
      for (long long q = Lp[j]; q < Lp[j + 1]; ++q)
        if (Li[q] > last && flag[Li[q]] != sn) {
          flag[Li[q]] = sn;
          below.push_back(Li[q]);
        }
    std::sort(below.begin(), below.end());
    rows.insert(rows.end(), below.begin(), below.end());
    const long long w = last - first + 1, r = static_cast<long long>(rows.size()) - sr.rows_begin[sn];
    sr.value_offset[sn + 1] = sr.value_offset[sn] + 9 * w * r;
    sr.factor_blocks += w * r - w * (w - 1) / 2;
  }
  sr.rows_begin[ns] = static_cast<int>(rows.size());
  return sr;
}

// Parallel schedule: disjoint subtrees of the supernodal tree of at most 1/16 of the work each
// (largest first, supernodes ascending) run concurrently, then the rest (the separators near the
// roots, ascending) in order.
struct Schedule {
  std::vector<int> top;
  std::vector<std::vector<int>> subtrees;
};

Schedule parallel_schedule(const std::vector<int>& parent, const std::vector<int>& super_first,
                           const std::vector<int>& rows_begin, const std::vector<int>& super_of) {
  const int ns = static_cast<int>(super_first.size()) - 1;
  std::vector<int> sparent(ns, -1);
  for (int sn = 0; sn < ns; ++sn) {
    const int last = super_first[sn + 1] - 1;
    if (parent[last] >= 0) sparent[sn] = super_of[parent[last]];
  }
  std::vector<double> work(ns);
  for (int sn = 0; sn < ns; ++sn) {
    const double w = super_first[sn + 1] - super_first[sn];
    const double r = rows_begin[sn + 1] - rows_begin[sn];
    work[sn] = w * r * r;
  }
  std::vector<std::vector<int>> children(ns);
  std::vector<int> roots;
  for (int sn = 0; sn < ns; ++sn) {
    if (sparent[sn] >= 0) {
      work[sparent[sn]] += work[sn];  // sparent > sn: accumulates bottom-up
      children[sparent[sn]].push_back(sn);
    } else {
      roots.push_back(sn);
    }
  }
  double total = 0;
  for (int r : roots) total += work[r];
  const double limit = total / 16;
  std::vector<int> stack(roots.begin(), roots.end());
  std::vector<std::pair<double, int>> cuts;
  Schedule sched;
  while (!stack.empty()) {
    const int v = stack.back();
    stack.pop_back();
    if (work[v] <= limit) {
      cuts.emplace_back(work[v], v);
    } else {
      sched.top.push_back(v);
      for (int c : children[v]) stack.push_back(c);
    }
  }
  std::sort(sched.top.begin(), sched.top.end());
  std::sort(cuts.rbegin(), cuts.rend());  // largest first
  for (const auto& [w, v] : cuts) {
    std::vector<int> members;
    std::vector<int> todo = {v};
    while (!todo.empty()) {
      const int u = todo.back();
      todo.pop_back();
      members.push_back(u);
      for (int c : children[u]) todo.push_back(c);
    }
    std::sort(members.begin(), members.end());
    sched.subtrees.push_back(std::move(members));
  }
  return sched;
}

}  // namespace

BlockCholesky3::BlockCholesky3(int n, const std::vector<std::pair<int, int>>& lower) : n_(n) {
  // ---- AMD ordering of the block graph, then a postorder of its elimination tree (so every
  // subtree, and every supernode, is a contiguous range of columns).
  perm_ = fill_reducing_order(n, lower);
  std::vector<int> inverse(n);
  for (int i = 0; i < n; ++i) inverse[perm_[i]] = i;
  const PermutedGraph g = permuted_graph(n, lower, inverse);
  const std::vector<int>& parent = g.parent;

  // ---- Row patterns of the columns of L (Lp/Li, rows ascending, diagonal first).
  const ColumnPatterns cp = column_patterns(n, g);

  // ---- Fundamental supernodes.
  // (Relaxed amalgamation, CHOLMOD-style merging with explicit zeros, was measured on the body:
  // more flops and a slower solve for no faster factorisation, so supernodes stay
  // fundamental.)
  super_first_ = fundamental_supernodes(parent, cp.count);
  const int ns = static_cast<int>(super_first_.size()) - 1;
  std::vector<int> super_of(n);
  for (int sn = 0; sn < ns; ++sn)
    for (int j = super_first_[sn]; j < super_first_[sn + 1]; ++j) super_of[j] = sn;

  // ---- Row lists: the supernode's own columns, then the union of its columns' rows below.
  SupernodeRows sr = supernode_rows(n, super_first_, cp);
  rows_begin_ = std::move(sr.rows_begin);
  rows_ = std::move(sr.rows);
  value_offset_ = std::move(sr.value_offset);
  factor_blocks_ = sr.factor_blocks;

  // ---- Update lists: supernode K updates every supernode J owning one of its rows below.
  updates_.assign(ns, {});
  flops_ = 0;
  for (int K = 0; K < ns; ++K) {
    const int wK = super_first_[K + 1] - super_first_[K];
    const int rb = rows_begin_[K], re = rows_begin_[K + 1];
    int i = rb + wK;
    while (i < re) {
      const int J = super_of[rows_[i]];
      int j = i;
      while (j < re && super_of[rows_[j]] == J) ++j;
      updates_[J].push_back(Update{K, i - rb, j - i});
      flops_ += 2.0 * 27 * wK * double(re - i) * (j - i);
      i = j;
    }
  }
  for (int sn = 0; sn < ns; ++sn) {
    const double w = 3.0 * (super_first_[sn + 1] - super_first_[sn]);
    const double below = 3.0 * (rows_begin_[sn + 1] - rows_begin_[sn]) - w;
    flops_ += w * w * w / 3 + below * w * w;
  }

  // ---- Where each A entry goes: diagonal blocks and the lower blocks C(r, c), r > c.
  assembly_.assign(ns, {});
  {
    std::vector<int> local(n, -1);
    for (int sn = 0; sn < ns; ++sn) {
      const int first = super_first_[sn], last = super_first_[sn + 1] - 1;
      const int rb = rows_begin_[sn], nr = rows_begin_[sn + 1] - rb;
      for (int i = 0; i < nr; ++i) local[rows_[rb + i]] = i;
      const int ld = 3 * nr;
      for (int c = first; c <= last; ++c) {
        const int col = c - first;
        assembly_[sn].push_back(Assembly{3 * col * ld + 3 * local[c], -1 - c, false});
      }
      for (int i = 0; i < nr; ++i) local[rows_[rb + i]] = -1;
    }
    // Lower entries: every `lower` block sits at (max, min) of its permuted indices.
    for (size_t e = 0; e < lower.size(); ++e) {
      const int r = inverse[lower[e].first], c = inverse[lower[e].second];
      const int hi = std::max(r, c), lo = std::min(r, c);
      const bool transposed = r < c;  // A(r_old, c_old) = off[e] sits at C(r, c)
      const int sn = super_of[lo];
      const int rb = rows_begin_[sn], re = rows_begin_[sn + 1];
      const int i = static_cast<int>(std::lower_bound(rows_.begin() + rb, rows_.begin() + re, hi) -
                                     rows_.begin()) - rb;
      if (rb + i >= re || rows_[rb + i] != hi)
        throw NumericalError("block Cholesky: entry outside the pattern (internal error)");
      const int ld = 3 * (re - rb), col = lo - super_first_[sn];
      assembly_[sn].push_back(Assembly{3 * col * ld + 3 * i, static_cast<int>(e), transposed});
    }
  }

  // ---- Parallel schedule: disjoint subtrees of the supernodal tree of at most 1/16 of the
  // work each run concurrently, then the rest (the separators near the roots) in order.
  Schedule sched = parallel_schedule(parent, super_first_, rows_begin_, super_of);
  top_supernodes_ = std::move(sched.top);
  subtree_supernodes_ = std::move(sched.subtrees);
}

void BlockCholesky3::factor_supernode(int sn, const std::vector<Eigen::Matrix3d>& diag,
                                      const std::vector<Eigen::Matrix3d>& off, double* values,
                                      std::vector<int>& map, Eigen::MatrixXd& work,
                                      bool& ok) const {
  const int first = super_first_[sn];
  const int w = super_first_[sn + 1] - first;
  const int rb = rows_begin_[sn], nr = rows_begin_[sn + 1] - rb;
  const int ld = 3 * nr;
  Panel panel(values + value_offset_[sn], ld, 3 * w);
  panel.setZero();
  // A's entries.
  for (const Assembly& a : assembly_[sn]) {
    double* dst = panel.data() + a.position;
    const Eigen::Matrix3d& B = a.off < 0 ? diag[perm_[-1 - a.off]] : off[a.off];
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) dst[c * ld + r] = a.transposed ? B(c, r) : B(r, c);
  }
  // Updates from descendants: panel(rows, cols) −= L_K(rows ≥ J, :) L_K(rows in J, :)ᵀ.
  for (int i = 0; i < nr; ++i) map[rows_[rb + i]] = i;
  for (const Update& u : updates_[sn]) {
    const int K = u.source;
    const int wK = super_first_[K + 1] - super_first_[K];
    const int kb = rows_begin_[K], kr = rows_begin_[K + 1] - kb;
    const ConstPanel LK(values + value_offset_[K], 3 * kr, 3 * wK);
    const int m = kr - u.start;  // rows of K from the first one in J to the end
    const int* krows = rows_.data() + kb + u.start;
    const long long ldK = 3LL * kr;
    if (wK <= 2) {
      // Thin source (most supernodes of a dual graph): 3×3 block products straight into the
      // panel, as the up-looking factorisation does; no buffer.
      using Block = Eigen::Map<const Eigen::Matrix3d, 0, Eigen::OuterStride<>>;
      for (int cj = 0; cj < u.count; ++cj) {
        const int col = krows[cj] - first;
        double* dst_col = panel.data() + static_cast<long long>(3 * col) * ld;
        for (int i = cj; i < m; ++i) {
          Eigen::Map<Eigen::Matrix3d, 0, Eigen::OuterStride<>> dst(dst_col + 3 * map[krows[i]], 3, 3,
                                                                   Eigen::OuterStride<>(ld));
          for (int b = 0; b < wK; ++b) {
            const double* base = LK.data() + 3 * b * ldK;
            dst.noalias() -= Block(base + 3 * (u.start + i), 3, 3, Eigen::OuterStride<>(ldK)) *
                             Block(base + 3 * (u.start + cj), 3, 3, Eigen::OuterStride<>(ldK)).transpose();
          }
        }
      }
      continue;
    }
    if (work.size() < 9LL * m * u.count) work.resize(9LL * m * u.count, 1);
    gemm_nt(3 * m, 3 * u.count, 3 * wK, LK.data() + 3 * u.start, 3 * kr, LK.data() + 3 * u.start,
            3 * kr, work.data(), 3 * m);
    const Eigen::Map<const Eigen::MatrixXd> C(work.data(), 3 * m, 3 * u.count);
    for (int cj = 0; cj < u.count; ++cj) {
      const int col = krows[cj] - first;
      double* dst_col = panel.data() + static_cast<long long>(3 * col) * ld;
      for (int i = cj; i < m; ++i) {
        const int r = map[krows[i]];
        for (int c = 0; c < 3; ++c)
          for (int rr = 0; rr < 3; ++rr)
            dst_col[c * ld + 3 * r + rr] -= C(3 * i + rr, 3 * cj + c);
      }
    }
  }
  // Dense Cholesky of the diagonal block, then the rows below: L21 = A21 L11⁻ᵀ.
  Eigen::Ref<Eigen::MatrixXd> top = panel.topRows(3 * w);
  Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt(top);
  if (llt.info() != Eigen::Success || !top.diagonal().allFinite() ||
      !(top.diagonal().array() > 0).all()) {
    ok = false;
    top.setIdentity();
  }
  if (nr > w) {
    // L21 = A21 L11⁻ᵀ as one product with the (small) explicit inverse: the GEMM kernel is
    // several times faster than a triangular solve on these sizes.
    const int mb = 3 * (nr - w), wb = 3 * w;
    const Eigen::MatrixXd inverse =
        top.triangularView<Eigen::Lower>().solve(Eigen::MatrixXd::Identity(wb, wb));
    if (work.size() < static_cast<Eigen::Index>(mb) * wb) work.resize(static_cast<Eigen::Index>(mb) * wb, 1);
    gemm_nt(mb, wb, wb, panel.data() + wb, ld, inverse.data(), wb, work.data(), mb);
    for (int c = 0; c < wb; ++c)
      std::copy(work.data() + static_cast<long long>(c) * mb, work.data() + static_cast<long long>(c + 1) * mb,
                panel.data() + static_cast<long long>(c) * ld + wb);
  }
}

bool BlockCholesky3::factorize(const std::vector<Eigen::Matrix3d>& diag,
                               const std::vector<Eigen::Matrix3d>& off, Factor& factor) const {
  if (static_cast<int>(diag.size()) != n_)
    throw NumericalError("block Cholesky: wrong number of diagonal blocks (internal error)");
  factor.values.resize(value_offset_.back());
  double* values = factor.values.data();
  struct Workspace {
    std::vector<int> map;
    Eigen::MatrixXd work;
    bool ok = true;
  };
  const int n = n_;
  tbb::enumerable_thread_specific<Workspace> workspaces([n] {
    return Workspace{std::vector<int>(n, -1), Eigen::MatrixXd(), true};
  });
  tbb::parallel_for(tbb::blocked_range<size_t>(0, subtree_supernodes_.size(), 1),
                    [&](const tbb::blocked_range<size_t>& r) {
                      Workspace& w = workspaces.local();
                      for (size_t t = r.begin(); t < r.end(); ++t)
                        for (int sn : subtree_supernodes_[t])
                          factor_supernode(sn, diag, off, values, w.map, w.work, w.ok);
                    });
  Workspace& w = workspaces.local();
  for (int sn : top_supernodes_) factor_supernode(sn, diag, off, values, w.map, w.work, w.ok);
  bool ok = true;
  for (const Workspace& ws : workspaces) ok = ok && ws.ok;
  return ok;
}

namespace {

// Forward and backward substitution through the supernodal panels, z row-major (3n by K) in the
// permuted order. K is a template parameter so the decoder's three columns unroll.
template <int K>
void substitute(int ns, const std::vector<int>& super_first, const std::vector<int>& rows_begin,
                const std::vector<int>& rows, const std::vector<long long>& value_offset,
                const double* values, int k_runtime, double* z) {
  const int k = K > 0 ? K : k_runtime;
  using Block = Eigen::Map<const Eigen::Matrix3d, 0, Eigen::OuterStride<>>;
  using Rhs = Eigen::Map<Eigen::Matrix<double, 3, K, K == 1 ? Eigen::ColMajor : Eigen::RowMajor>>;
  // Row-major panels for wide K, so the 3×3-block products vectorise along the columns.
  using Panel = Eigen::Matrix<double, 3, K, K <= 3 ? Eigen::ColMajor : Eigen::RowMajor>;
  for (int sn = 0; sn < ns; ++sn) {
    const int first = super_first[sn], wb = 3 * (super_first[sn + 1] - first);
    const int rb = rows_begin[sn], ld = 3 * (rows_begin[sn + 1] - rb);
    const double* L = values + value_offset[sn];
    double* x = z + 3 * static_cast<size_t>(first) * k;
    for (int j = 0; j < wb; ++j) {  // the diagonal block (dense lower triangle)
      const double* col = L + static_cast<long long>(j) * ld;
      double* xj = x + j * k;
      const double d = 1.0 / col[j];
      for (int c = 0; c < k; ++c) xj[c] *= d;
      for (int i = j + 1; i < wb; ++i)
        for (int c = 0; c < k; ++c) x[i * k + c] -= col[i] * xj[c];
    }
    for (int jb = 0; jb < wb / 3; ++jb) {  // the rows below, 3×3 blocks
      const double* col = L + static_cast<long long>(3 * jb) * ld;
      if constexpr (K > 0) {
        const Panel X = Rhs(x + 3 * jb * K);
        for (int bi = wb / 3; bi < ld / 3; ++bi)
          Rhs(z + 3 * static_cast<size_t>(rows[rb + bi]) * K).noalias() -=
              Block(col + 3 * bi, 3, 3, Eigen::OuterStride<>(ld)) * X;
      } else {
        for (int jj = 0; jj < 3; ++jj) {
          const double* cj = col + static_cast<long long>(jj) * ld;
          const double* xj = x + (3 * jb + jj) * k;
          for (int bi = wb / 3; bi < ld / 3; ++bi) {
            double* zr = z + 3 * static_cast<size_t>(rows[rb + bi]) * k;
            for (int r = 0; r < 3; ++r)
              for (int c = 0; c < k; ++c) zr[r * k + c] -= cj[3 * bi + r] * xj[c];
          }
        }
      }
    }
  }
  for (int sn = ns - 1; sn >= 0; --sn) {
    const int first = super_first[sn], wb = 3 * (super_first[sn + 1] - first);
    const int rb = rows_begin[sn], ld = 3 * (rows_begin[sn + 1] - rb);
    const double* L = values + value_offset[sn];
    double* x = z + 3 * static_cast<size_t>(first) * k;
    for (int jb = 0; jb < wb / 3; ++jb) {
      const double* col = L + static_cast<long long>(3 * jb) * ld;
      if constexpr (K > 0) {
        Panel acc = Panel::Zero();
        for (int bi = wb / 3; bi < ld / 3; ++bi)
          acc.noalias() += Block(col + 3 * bi, 3, 3, Eigen::OuterStride<>(ld)).transpose() *
                           Rhs(z + 3 * static_cast<size_t>(rows[rb + bi]) * K);
        Rhs(x + 3 * jb * K) -= acc;
      } else {
        for (int jj = 0; jj < 3; ++jj) {
          const double* cj = col + static_cast<long long>(jj) * ld;
          double* xj = x + (3 * jb + jj) * k;
          for (int bi = wb / 3; bi < ld / 3; ++bi) {
            const double* zr = z + 3 * static_cast<size_t>(rows[rb + bi]) * k;
            for (int r = 0; r < 3; ++r)
              for (int c = 0; c < k; ++c) xj[c] -= cj[3 * bi + r] * zr[r * k + c];
          }
        }
      }
    }
    for (int j = wb - 1; j >= 0; --j) {
      const double* col = L + static_cast<long long>(j) * ld;
      double* xj = x + j * k;
      for (int i = j + 1; i < wb; ++i)
        for (int c = 0; c < k; ++c) xj[c] -= col[i] * x[i * k + c];
      const double d = 1.0 / col[j];
      for (int c = 0; c < k; ++c) xj[c] *= d;
    }
  }
}

#ifdef BODYMODEL_HAVE_AVX2_KERNEL
// The same substitution for three right-hand sides with AVX2/FMA: z is row-major 3n by 4 (the
// fourth column is padding), so one row is one register and a 3×3 block update is nine
// fused multiply-adds of a broadcast L entry with a row.
__attribute__((target("avx2,fma"))) void substitute3_avx2(
    int ns, const std::vector<int>& super_first, const std::vector<int>& rows_begin,
    const std::vector<int>& rows, const std::vector<long long>& value_offset,
    const double* values, double* z) {
  for (int sn = 0; sn < ns; ++sn) {
    const int first = super_first[sn], wb = 3 * (super_first[sn + 1] - first);
    const int rb = rows_begin[sn], ld = 3 * (rows_begin[sn + 1] - rb);
    const double* L = values + value_offset[sn];
    double* x = z + 12 * static_cast<size_t>(first);
    for (int j = 0; j < wb; ++j) {  // the diagonal block (dense lower triangle)
      const double* col = L + static_cast<long long>(j) * ld;
      const __m256d xj = _mm256_mul_pd(_mm256_loadu_pd(x + 4 * j), _mm256_set1_pd(1.0 / col[j]));
      _mm256_storeu_pd(x + 4 * j, xj);
      for (int i = j + 1; i < wb; ++i)
        _mm256_storeu_pd(x + 4 * i, _mm256_fnmadd_pd(_mm256_set1_pd(col[i]), xj, _mm256_loadu_pd(x + 4 * i)));
    }
    for (int jb = 0; jb < wb / 3; ++jb) {  // the rows below, 3×3 blocks
      const double* c0 = L + static_cast<long long>(3 * jb) * ld;
      const double* c1 = c0 + ld;
      const double* c2 = c1 + ld;
      const __m256d x0 = _mm256_loadu_pd(x + 12 * jb), x1 = _mm256_loadu_pd(x + 12 * jb + 4),
                    x2 = _mm256_loadu_pd(x + 12 * jb + 8);
      for (int bi = wb / 3; bi < ld / 3; ++bi) {
        double* zr = z + 12 * static_cast<size_t>(rows[rb + bi]);
        for (int r = 0; r < 3; ++r) {
          __m256d acc = _mm256_loadu_pd(zr + 4 * r);
          acc = _mm256_fnmadd_pd(_mm256_set1_pd(c0[3 * bi + r]), x0, acc);
          acc = _mm256_fnmadd_pd(_mm256_set1_pd(c1[3 * bi + r]), x1, acc);
          acc = _mm256_fnmadd_pd(_mm256_set1_pd(c2[3 * bi + r]), x2, acc);
          _mm256_storeu_pd(zr + 4 * r, acc);
        }
      }
    }
  }
  for (int sn = ns - 1; sn >= 0; --sn) {
    const int first = super_first[sn], wb = 3 * (super_first[sn + 1] - first);
    const int rb = rows_begin[sn], ld = 3 * (rows_begin[sn + 1] - rb);
    const double* L = values + value_offset[sn];
    double* x = z + 12 * static_cast<size_t>(first);
    for (int jb = 0; jb < wb / 3; ++jb) {
      const double* c0 = L + static_cast<long long>(3 * jb) * ld;
      const double* c1 = c0 + ld;
      const double* c2 = c1 + ld;
      __m256d a0 = _mm256_setzero_pd(), a1 = a0, a2 = a0;
      for (int bi = wb / 3; bi < ld / 3; ++bi) {
        const double* zr = z + 12 * static_cast<size_t>(rows[rb + bi]);
        for (int r = 0; r < 3; ++r) {
          const __m256d row = _mm256_loadu_pd(zr + 4 * r);
          a0 = _mm256_fmadd_pd(_mm256_set1_pd(c0[3 * bi + r]), row, a0);
          a1 = _mm256_fmadd_pd(_mm256_set1_pd(c1[3 * bi + r]), row, a1);
          a2 = _mm256_fmadd_pd(_mm256_set1_pd(c2[3 * bi + r]), row, a2);
        }
      }
      double* xb = x + 12 * jb;
      _mm256_storeu_pd(xb, _mm256_sub_pd(_mm256_loadu_pd(xb), a0));
      _mm256_storeu_pd(xb + 4, _mm256_sub_pd(_mm256_loadu_pd(xb + 4), a1));
      _mm256_storeu_pd(xb + 8, _mm256_sub_pd(_mm256_loadu_pd(xb + 8), a2));
    }
    for (int j = wb - 1; j >= 0; --j) {
      const double* col = L + static_cast<long long>(j) * ld;
      __m256d xj = _mm256_loadu_pd(x + 4 * j);
      for (int i = j + 1; i < wb; ++i)
        xj = _mm256_fnmadd_pd(_mm256_set1_pd(col[i]), _mm256_loadu_pd(x + 4 * i), xj);
      _mm256_storeu_pd(x + 4 * j, _mm256_mul_pd(xj, _mm256_set1_pd(1.0 / col[j])));
    }
  }
}

// The same for a panel of twelve right-hand sides (BlockCholesky3::kPanel): one row of z is
// three registers, so a 3×3 block update is 27 fused multiply-adds with no padding.
__attribute__((target("avx2,fma"), always_inline)) inline void load12(const double* p, __m256d* r) {
  r[0] = _mm256_loadu_pd(p), r[1] = _mm256_loadu_pd(p + 4), r[2] = _mm256_loadu_pd(p + 8);
}
__attribute__((target("avx2,fma"), always_inline)) inline void store12(double* p, const __m256d* r) {
  _mm256_storeu_pd(p, r[0]), _mm256_storeu_pd(p + 4, r[1]), _mm256_storeu_pd(p + 8, r[2]);
}
__attribute__((target("avx2,fma"))) void substitute12_avx2(
    int ns, const std::vector<int>& super_first, const std::vector<int>& rows_begin,
    const std::vector<int>& rows, const std::vector<long long>& value_offset,
    const double* values, double* z) {
  for (int sn = 0; sn < ns; ++sn) {
    const int first = super_first[sn], wb = 3 * (super_first[sn + 1] - first);
    const int rb = rows_begin[sn], ld = 3 * (rows_begin[sn + 1] - rb);
    const double* L = values + value_offset[sn];
    double* x = z + 36 * static_cast<size_t>(first);
    for (int j = 0; j < wb; ++j) {  // the diagonal block (dense lower triangle)
      const double* col = L + static_cast<long long>(j) * ld;
      __m256d xj[3];
      load12(x + 12 * j, xj);
      const __m256d d = _mm256_set1_pd(1.0 / col[j]);
      for (int q = 0; q < 3; ++q) xj[q] = _mm256_mul_pd(xj[q], d);
      store12(x + 12 * j, xj);
      for (int i = j + 1; i < wb; ++i) {
        const __m256d l = _mm256_set1_pd(col[i]);
        double* xi = x + 12 * i;
        for (int q = 0; q < 3; ++q)
          _mm256_storeu_pd(xi + 4 * q, _mm256_fnmadd_pd(l, xj[q], _mm256_loadu_pd(xi + 4 * q)));
      }
    }
    for (int jb = 0; jb < wb / 3; ++jb) {  // the rows below, 3×3 blocks
      const double* c[3] = {L + static_cast<long long>(3 * jb) * ld, L + static_cast<long long>(3 * jb + 1) * ld,
                            L + static_cast<long long>(3 * jb + 2) * ld};
      __m256d xs[3][3];
      for (int t = 0; t < 3; ++t) load12(x + 12 * (3 * jb + t), xs[t]);
      for (int bi = wb / 3; bi < ld / 3; ++bi) {
        double* zr = z + 36 * static_cast<size_t>(rows[rb + bi]);
        for (int r = 0; r < 3; ++r) {
          __m256d acc[3];
          load12(zr + 12 * r, acc);
          for (int t = 0; t < 3; ++t) {
            const __m256d l = _mm256_set1_pd(c[t][3 * bi + r]);
            for (int q = 0; q < 3; ++q) acc[q] = _mm256_fnmadd_pd(l, xs[t][q], acc[q]);
          }
          store12(zr + 12 * r, acc);
        }
      }
    }
  }
  for (int sn = ns - 1; sn >= 0; --sn) {
    const int first = super_first[sn], wb = 3 * (super_first[sn + 1] - first);
    const int rb = rows_begin[sn], ld = 3 * (rows_begin[sn + 1] - rb);
    const double* L = values + value_offset[sn];
    double* x = z + 36 * static_cast<size_t>(first);
    for (int jb = 0; jb < wb / 3; ++jb) {
      const double* c[3] = {L + static_cast<long long>(3 * jb) * ld, L + static_cast<long long>(3 * jb + 1) * ld,
                            L + static_cast<long long>(3 * jb + 2) * ld};
      __m256d a[3][3];
      for (int t = 0; t < 3; ++t)
        for (int q = 0; q < 3; ++q) a[t][q] = _mm256_setzero_pd();
      for (int bi = wb / 3; bi < ld / 3; ++bi) {
        const double* zr = z + 36 * static_cast<size_t>(rows[rb + bi]);
        for (int r = 0; r < 3; ++r) {
          __m256d row[3];
          load12(zr + 12 * r, row);
          for (int t = 0; t < 3; ++t) {
            const __m256d l = _mm256_set1_pd(c[t][3 * bi + r]);
            for (int q = 0; q < 3; ++q) a[t][q] = _mm256_fmadd_pd(l, row[q], a[t][q]);
          }
        }
      }
      for (int t = 0; t < 3; ++t) {
        double* xb = x + 12 * (3 * jb + t);
        for (int q = 0; q < 3; ++q) _mm256_storeu_pd(xb + 4 * q, _mm256_sub_pd(_mm256_loadu_pd(xb + 4 * q), a[t][q]));
      }
    }
    for (int j = wb - 1; j >= 0; --j) {
      const double* col = L + static_cast<long long>(j) * ld;
      __m256d xj[3];
      load12(x + 12 * j, xj);
      for (int i = j + 1; i < wb; ++i) {
        const __m256d l = _mm256_set1_pd(col[i]);
        for (int q = 0; q < 3; ++q) xj[q] = _mm256_fnmadd_pd(l, _mm256_loadu_pd(x + 12 * i + 4 * q), xj[q]);
      }
      const __m256d d = _mm256_set1_pd(1.0 / col[j]);
      for (int q = 0; q < 3; ++q) xj[q] = _mm256_mul_pd(xj[q], d);
      store12(x + 12 * j, xj);
    }
  }
}
const bool kUseAvx2Substitution = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#endif

}  // namespace

void BlockCholesky3::solve(const Factor& factor, Eigen::MatrixXd& B) const {
  const int n = n_, ns = supernode_count();
  const int k = static_cast<int>(B.cols());
#ifdef BODYMODEL_HAVE_AVX2_KERNEL
  if (k == 3 && kUseAvx2Substitution) {
    std::vector<double> z(12 * static_cast<size_t>(n), 0.0);
    for (int i = 0; i < n; ++i)
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) z[12 * static_cast<size_t>(i) + 4 * r + c] = B(3 * perm_[i] + r, c);
    substitute3_avx2(ns, super_first_, rows_begin_, rows_, value_offset_, factor.values.data(), z.data());
    for (int i = 0; i < n; ++i)
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) B(3 * perm_[i] + r, c) = z[12 * static_cast<size_t>(i) + 4 * r + c];
    return;
  }
#endif
  if (k > 3) {
    // Many right-hand sides: panels of kPanel columns (solve_panel), the last zero-padded.
    constexpr int W = kPanel;
    std::vector<double> z(3 * static_cast<size_t>(n) * W);
    for (int c0 = 0; c0 < k; c0 += W) {
      const int kc = std::min(W, k - c0);
      if (kc < W) std::fill(z.begin(), z.end(), 0.0);
      for (int i = 0; i < n; ++i)
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < kc; ++c) z[(3 * static_cast<size_t>(i) + r) * W + c] = B(3 * perm_[i] + r, c0 + c);
      solve_panel(factor, z.data());
      for (int i = 0; i < n; ++i)
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < kc; ++c) B(3 * perm_[i] + r, c0 + c) = z[(3 * static_cast<size_t>(i) + r) * W + c];
    }
    return;
  }
  std::vector<double> z(3 * static_cast<size_t>(n) * k);
  for (int i = 0; i < n; ++i)
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < k; ++c) z[(3 * static_cast<size_t>(i) + r) * k + c] = B(3 * perm_[i] + r, c);
  if (k == 3)
    substitute<3>(ns, super_first_, rows_begin_, rows_, value_offset_, factor.values.data(), k, z.data());
  else
    substitute<0>(ns, super_first_, rows_begin_, rows_, value_offset_, factor.values.data(), k, z.data());
  for (int i = 0; i < n; ++i)
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < k; ++c) B(3 * perm_[i] + r, c) = z[(3 * static_cast<size_t>(i) + r) * k + c];
}

void BlockCholesky3::solve_panel(const Factor& factor, double* z) const {
#ifdef BODYMODEL_HAVE_AVX2_KERNEL
  if (kUseAvx2Substitution) {
    substitute12_avx2(supernode_count(), super_first_, rows_begin_, rows_, value_offset_, factor.values.data(), z);
    return;
  }
#endif
  // The fixed width lets the compiler keep a block row of the panel in registers (the
  // run-time-width substitution is several times slower per column).
  substitute<kPanel>(supernode_count(), super_first_, rows_begin_, rows_, value_offset_, factor.values.data(),
                     kPanel, z);
}

}  // namespace bodymodel
