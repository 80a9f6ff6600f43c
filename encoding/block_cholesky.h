// Sparse Cholesky factorisation A = L Lᵀ of a symmetric positive definite matrix made of 3×3
// blocks, with the symbolic analysis (AMD ordering of the block graph, elimination tree, the
// pattern of L) done once and the numeric factorisation per call (up-looking, as CSparse's
// cs_chol, with every scalar operation replaced by a fixed-size 3×3 block operation).
//
// Used by RelativeRotationDecoder for the rotation system of encodings that are not exactly
// realisable (blends, model samples): its block graph is the template's dual graph, fixed, and
// only the values change. On the 26 756-triangle body this is about twice as fast as
// CHOLMOD's simplicial factorisation of the same 3·#F scalar matrix (the block form does the
// same flops without per-entry index work).
//
// The numeric factorisation runs disjoint subtrees of the elimination tree in parallel (TBB);
// the result is bit-identical to the serial order.
//
// Thread safety: the analysis is immutable; factorize() and solve() are const and write only
// to the caller's Factor, so one BlockCholesky3 serves concurrent callers.
#pragma once

#include <Eigen/Core>
#include <utility>
#include <vector>

namespace bodymodel {

class BlockCholesky3 {
 public:
  // n block rows/columns; `lower` lists the off-diagonal blocks (r, c) with r > c, each once.
  BlockCholesky3(int n, const std::vector<std::pair<int, int>>& lower);

  struct Factor {
    std::vector<Eigen::Matrix3d> L;     // blocks of L in the analysis' column order
    std::vector<Eigen::Matrix3d> Dinv;  // inverses of the (lower triangular) diagonal blocks
  };
  // diag: n diagonal blocks; off: one block A(r, c) per entry of `lower`, same order. Returns
  // false if A is not (numerically) positive definite.
  bool factorize(const std::vector<Eigen::Matrix3d>& diag, const std::vector<Eigen::Matrix3d>& off,
                 Factor& factor) const;
  // Solves A X = B in place; B is 3n by any number of columns.
  void solve(const Factor& factor, Eigen::MatrixXd& B) const;

  int block_count() const { return n_; }
  long long factor_blocks() const { return Lp_.empty() ? 0 : Lp_.back(); }

 private:
  struct Entry {
    int row;         // permuted block row i < k of the upper column k
    int off;         // index into `off`
    bool transposed; // C(i, k) = off[...]ᵀ
  };
  int n_ = 0;
  std::vector<int> perm_;                    // perm_[new] = old
  std::vector<int> inverse_;                 // inverse_[old] = new
  std::vector<std::vector<Entry>> upper_;    // per permuted column k: C(i, k), i < k
  std::vector<int> parent_;                  // elimination tree
  std::vector<int> Lp_, Li_;                 // pattern of L (column pointers, row indices)
  std::vector<std::vector<int>> subtree_rows_;  // disjoint etree subtrees (rows ascending)
  std::vector<int> top_rows_;                   // the remaining rows, ascending, done last
};

}  // namespace bodymodel
