#include "encoding/block_cholesky.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/OrderingMethods>
#include <Eigen/Sparse>
#include <algorithm>
#include <atomic>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "core/error.h"

namespace bodymodel {

namespace {

// Pattern of row k of L (the reach of column k's upper entries in the elimination tree), in
// topological order in s[top..n); returns top. `flag` marks visited nodes with k.
int ereach(int k, const std::vector<std::vector<int>>& up_rows, const std::vector<int>& parent,
           std::vector<int>& flag, std::vector<int>& s, std::vector<int>& path) {
  const int n = static_cast<int>(parent.size());
  int top = n;
  flag[k] = k;
  for (int i : up_rows[k]) {
    int len = 0;
    for (int j = i; flag[j] != k; j = parent[j]) {
      path[len++] = j;
      flag[j] = k;
    }
    while (len > 0) s[--top] = path[--len];
  }
  return top;
}

}  // namespace

BlockCholesky3::BlockCholesky3(int n, const std::vector<std::pair<int, int>>& lower) : n_(n) {
  // AMD ordering of the block graph.
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
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> perm;
  Eigen::AMDOrdering<int> amd;
  amd(P.selfadjointView<Eigen::Lower>(), perm);
  // Eigen's ordering permutes A as Pᵀ A P: old index perm(new).
  perm_.resize(n);
  inverse_.resize(n);
  for (int i = 0; i < n; ++i) perm_[i] = perm.indices()(i);
  for (int i = 0; i < n; ++i) inverse_[perm_[i]] = i;

  // Upper columns of C = A permuted.
  upper_.assign(n, {});
  std::vector<std::vector<int>> up_rows(n);
  for (size_t e = 0; e < lower.size(); ++e) {
    const int r = inverse_[lower[e].first], c = inverse_[lower[e].second];
    // A(r_old, c_old) = off[e] sits at C(r, c); its mirror at C(c, r) = off[e]ᵀ.
    if (r < c)
      upper_[c].push_back(Entry{r, static_cast<int>(e), false});
    else
      upper_[r].push_back(Entry{c, static_cast<int>(e), true});
  }
  for (int k = 0; k < n; ++k)
    for (const Entry& en : upper_[k]) up_rows[k].push_back(en.row);

  // Elimination tree (Liu's algorithm with path compression).
  parent_.assign(n, -1);
  std::vector<int> ancestor(n, -1);
  for (int k = 0; k < n; ++k)
    for (int i : up_rows[k])
      for (int j = i; j != -1 && j < k;) {
        const int next = ancestor[j];
        ancestor[j] = k;
        if (next == -1) parent_[j] = k;
        j = next;
      }

  // Column counts from the row patterns, then the row indices of L (numeric order).
  std::vector<int> count(n, 1), flag(n, -1), s(n), path(n);
  for (int k = 0; k < n; ++k) {
    const int top = ereach(k, up_rows, parent_, flag, s, path);
    for (int p = top; p < n; ++p) ++count[s[p]];
  }
  Lp_.assign(n + 1, 0);
  for (int k = 0; k < n; ++k) Lp_[k + 1] = Lp_[k] + count[k];
  Li_.assign(Lp_[n], 0);
  std::vector<int> next(Lp_.begin(), Lp_.end() - 1);
  std::fill(flag.begin(), flag.end(), -1);
  for (int k = 0; k < n; ++k) {
    Li_[next[k]++] = k;  // diagonal first
    const int top = ereach(k, up_rows, parent_, flag, s, path);
    for (int p = top; p < n; ++p) Li_[next[s[p]]++] = k;
  }

  // Parallel schedule. Row k of L only reads and writes columns of k's descendants in the
  // elimination tree, so disjoint subtrees can be factorised concurrently: cut the tree into
  // subtrees of at most 1/16 of the work (estimated as Σ column count²), run those in parallel,
  // then the rest (the separators near the roots) in order. Bit-identical to the serial order.
  std::vector<double> work(n);
  for (int k = 0; k < n; ++k) work[k] = static_cast<double>(count[k]) * count[k];
  std::vector<std::vector<int>> children(n);
  std::vector<int> roots;
  for (int k = 0; k < n; ++k) {
    if (parent_[k] >= 0) {
      work[parent_[k]] += work[k];  // parent_[k] > k: accumulates bottom-up
      children[parent_[k]].push_back(k);
    } else {
      roots.push_back(k);
    }
  }
  double total = 0;
  for (int r : roots) total += work[r];
  const double limit = total / 16;
  std::vector<int> stack(roots.begin(), roots.end());
  std::vector<std::pair<double, int>> cuts;
  while (!stack.empty()) {
    const int v = stack.back();
    stack.pop_back();
    if (work[v] <= limit) {
      cuts.emplace_back(work[v], v);
    } else {
      top_rows_.push_back(v);
      for (int c : children[v]) stack.push_back(c);
    }
  }
  std::sort(top_rows_.begin(), top_rows_.end());
  std::sort(cuts.rbegin(), cuts.rend());  // largest first
  for (const auto& [w, v] : cuts) {
    std::vector<int> rows;
    std::vector<int> todo = {v};
    while (!todo.empty()) {
      const int u = todo.back();
      todo.pop_back();
      rows.push_back(u);
      for (int c : children[u]) todo.push_back(c);
    }
    std::sort(rows.begin(), rows.end());
    subtree_rows_.push_back(std::move(rows));
  }
}

bool BlockCholesky3::factorize(const std::vector<Eigen::Matrix3d>& diag,
                               const std::vector<Eigen::Matrix3d>& off, Factor& factor) const {
  const int n = n_;
  if (static_cast<int>(diag.size()) != n)
    throw NumericalError("block Cholesky: wrong number of diagonal blocks (internal error)");
  factor.L.resize(Lp_[n]);
  factor.Dinv.resize(n);
  std::vector<Eigen::Matrix3d>& Lx = factor.L;
  // next[i]: next free entry of column i (each column is only touched by one task at a time).
  std::vector<int> next(Lp_.begin(), Lp_.end() - 1);
  struct Workspace {
    std::vector<Eigen::Matrix3d> x;  // dense block row, zero between rows
    std::vector<int> flag, s, path;
  };
  auto make_workspace = [n] {
    return Workspace{std::vector<Eigen::Matrix3d>(n, Eigen::Matrix3d::Zero()),
                     std::vector<int>(n, -1), std::vector<int>(n), std::vector<int>(n)};
  };
  std::atomic<bool> ok{true};
  auto row = [&](int k, Workspace& w) {
    // Scatter C(:, k) (upper part) into x, and find the pattern of row k of L.
    int top = n;
    w.flag[k] = k;
    for (const Entry& en : upper_[k]) {
      w.x[en.row] = en.transposed ? Eigen::Matrix3d(off[en.off].transpose()) : off[en.off];
      int len = 0;
      for (int j = en.row; w.flag[j] != k; j = parent_[j]) {
        w.path[len++] = j;
        w.flag[j] = k;
      }
      while (len > 0) w.s[--top] = w.path[--len];
    }
    Eigen::Matrix3d d = diag[perm_[k]];
    for (int p = top; p < n; ++p) {
      const int i = w.s[p];
      // x_i = C(i, k) − Σ_j L(i, j) L(k, j)ᵀ;  L(k, i)ᵀ = L(i, i)⁻¹ x_i.
      const Eigen::Matrix3d Y = factor.Dinv[i] * w.x[i];
      w.x[i].setZero();
      for (int q = Lp_[i] + 1; q < next[i]; ++q) w.x[Li_[q]].noalias() -= Lx[q] * Y;
      d.noalias() -= Y.transpose() * Y;
      Lx[next[i]++] = Y.transpose();
    }
    const Eigen::LLT<Eigen::Matrix3d> llt(d);
    if (llt.info() != Eigen::Success || !(d.diagonal().array() > 0).all()) {
      ok = false;
      Lx[next[k]++].setIdentity();
      factor.Dinv[k].setIdentity();
      return;
    }
    Lx[next[k]++] = llt.matrixL();
    factor.Dinv[k] = Lx[Lp_[k]].inverse();
  };
  tbb::enumerable_thread_specific<Workspace> workspaces(make_workspace);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, subtree_rows_.size(), 1),
                    [&](const tbb::blocked_range<size_t>& r) {
                      Workspace& w = workspaces.local();
                      for (size_t t = r.begin(); t < r.end(); ++t)
                        for (int k : subtree_rows_[t]) row(k, w);
                    });
  Workspace& w = workspaces.local();
  for (int k : top_rows_) row(k, w);
  return ok;
}

void BlockCholesky3::solve(const Factor& factor, Eigen::MatrixXd& B) const {
  const int n = n_;
  const std::vector<Eigen::Matrix3d>& Lx = factor.L;
  // Three right-hand sides at a time, as 3×3 blocks per block row (zero-padded).
  std::vector<Eigen::Matrix3d> z(n);
  for (Eigen::Index c0 = 0; c0 < B.cols(); c0 += 3) {
    const Eigen::Index w = std::min<Eigen::Index>(3, B.cols() - c0);
    for (int i = 0; i < n; ++i) {
      z[i].setZero();
      z[i].leftCols(w) = B.block(3 * perm_[i], c0, 3, w);
    }
    for (int j = 0; j < n; ++j) {
      z[j] = factor.Dinv[j] * z[j];
      for (int q = Lp_[j] + 1; q < Lp_[j + 1]; ++q) z[Li_[q]].noalias() -= Lx[q] * z[j];
    }
    for (int j = n - 1; j >= 0; --j) {
      for (int q = Lp_[j] + 1; q < Lp_[j + 1]; ++q) z[j].noalias() -= Lx[q].transpose() * z[Li_[q]];
      z[j] = factor.Dinv[j].transpose() * z[j];
    }
    for (int i = 0; i < n; ++i) B.block(3 * perm_[i], c0, 3, w) = z[i].leftCols(w);
  }
}

}  // namespace bodymodel
