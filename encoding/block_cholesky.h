// Sparse Cholesky factorisation A = L Lᵀ of a symmetric positive definite matrix made of 3×3
// blocks, with the symbolic analysis done once and the numeric factorisation per call.
//
// Used by RelativeRotationDecoder for the rotation system of encodings that are not exactly
// realisable (blends, model samples): its block graph is the template's dual graph, fixed, and
// only the values change, so everything that depends on the pattern is computed once:
//   - AMD ordering of the block graph (on the dual graph of the body it gives ~25 % fewer flops
//     than METIS or CHOLMOD's nested dissection: 9.2 M block operations against 12.2 / 11.5 M),
//     then a postorder of the elimination tree, so subtrees and supernodes are column ranges;
//   - fundamental supernodes (runs of block columns whose row patterns nest exactly), each
//     stored as one dense column-major panel of 3·rows by 3·columns doubles;
//   - for every supernode the list of earlier supernodes that update it, and where each of
//     its A entries goes in its panel.
// The numeric factorisation is left-looking supernodal: per supernode, assemble A, subtract
// the products L_K L_Kᵀ of its descendants (3×3 block products for thin ones, a register-tiled
// GEMM kernel for wider ones), a dense Cholesky of the diagonal block and the rows below times
// its inverse. Disjoint subtrees of the supernodal elimination tree run in parallel (TBB); the
// result is bit-identical to the serial order (each panel is always computed by the same
// operations in the same order). The solve for three right-hand sides has an AVX2/FMA variant
// (run-time dispatch, like the GEMM kernel). It replaced a 3×3-block up-looking factorisation
// and CHOLMOD in the decoder because it takes less CPU than either on the body's system
// (bench/encoding_bench; figures in docs/results.md#encoding-speed and docs/benchmarks.md).
//
// Thread safety: the analysis is immutable; factorize() and solve() are const and write only
// to the caller's Factor / right-hand side, so one BlockCholesky3 serves concurrent callers.
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
    std::vector<double> values;  // the supernodal panels, one after the other
  };
  // diag: n diagonal blocks; off: one block A(r, c) per entry of `lower`, same order. Returns
  // false if A is not (numerically) positive definite.
  bool factorize(const std::vector<Eigen::Matrix3d>& diag, const std::vector<Eigen::Matrix3d>& off,
                 Factor& factor) const;
  // Solves A X = B in place; B is 3n by any number of columns.
  void solve(const Factor& factor, Eigen::MatrixXd& B) const;
  // The same for kPanel right-hand sides already in the solver's layout, for callers that
  // assemble them there (the model fit's Jacobian: no copies in and out): z is row-major
  // 3n by kPanel, its block row i (rows 3i..3i+2) holding block permutation()[i] of B.
  static constexpr int kPanel = 12;
  void solve_panel(const Factor& factor, double* z) const;
  const std::vector<int>& permutation() const { return perm_; }  // [solver order] = block

  int block_count() const { return n_; }
  // Number of 3×3 blocks stored in L (lower triangle of the panels, explicit zeros included).
  long long factor_blocks() const { return factor_blocks_; }
  int supernode_count() const { return static_cast<int>(super_first_.size()) - 1; }
  // Floating-point operations of one numeric factorisation (dense kernels, as executed).
  double factor_flops() const { return flops_; }

 private:
  struct Update {
    int source;  // supernode K that updates this one
    int start;   // first row (index into K's row list) inside this supernode's columns
    int count;   // number of K's rows inside this supernode's columns
  };
  struct Assembly {
    int position;    // index in the panel of the block's top-left entry (column-major)
    int off;         // index into `off`, or −1 − column for a diagonal block
    bool transposed; // panel block = off[...]ᵀ
  };
  void factor_supernode(int s, const std::vector<Eigen::Matrix3d>& diag,
                        const std::vector<Eigen::Matrix3d>& off, double* values,
                        std::vector<int>& map, Eigen::MatrixXd& work, bool& ok) const;

  int n_ = 0;
  std::vector<int> perm_;                    // perm_[new] = old (block indices)
  std::vector<int> super_first_;             // supernode s: block columns [first[s], first[s+1])
  std::vector<int> rows_begin_, rows_;       // supernode s: rows_[rows_begin_[s] .. +1) ascending
  std::vector<long long> value_offset_;      // supernode s: panel at values[value_offset_[s]]
  std::vector<std::vector<Update>> updates_; // per supernode, in ascending source order
  std::vector<std::vector<Assembly>> assembly_;
  std::vector<std::vector<int>> subtree_supernodes_;  // disjoint subtrees (ascending), in parallel
  std::vector<int> top_supernodes_;                   // the rest, ascending, done last
  long long factor_blocks_ = 0;
  double flops_ = 0;
};

}  // namespace bodymodel
