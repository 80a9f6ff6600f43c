// Quantised PCA bases: the bases are nearly all of a model file (D = 15·#F rows, one column per
// component), so a file a user can ship stores them as integers of 2 to 16 bits per column
// (model_file.h; widths other than 8 and 16 bit-packed).
//
// Each column is cut into blocks of `block_rows` consecutive rows; a block's entries are
// q = round(b / s) with s = max|b| / (2^(bits−1) − 1) over the block (symmetric, no offset: a
// basis column is centred on 0), so every entry is off by at most s / 2. One scale per column
// (block_rows ≥ D) lets a component that is large on a few triangles (a hand, the head) set the
// step for all the others' near-zero entries; short blocks keep that step local. The scales are
// float32 (the quantisation uses the rounded scale, so the bound holds for what is stored).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "model/body_model.h"
#include "model/model_file.h"

namespace bodymodel {

struct QuantisedBasis {
  Eigen::VectorXi bits;     // K: 2 to 16 per column
  int block_rows = 64;      // rows per scale within a column
  Eigen::MatrixXi codes;    // D by K, |q| ≤ 2^(bits−1) − 1 of the column
  Eigen::MatrixXd scales;   // ceil(D / block_rows) by K, float32 values, ≥ 0
  Eigen::VectorXd column_norms;  // K: of the basis that was quantised (a check on the scales)

  // Largest possible |b − decoded b| of each column's entries (s / 2 of its largest block) and
  // the largest possible norm of each column's error vector: the stored-scale bounds.
  Eigen::VectorXd max_entry_error() const;
  Eigen::VectorXd max_column_error_norm() const;
};

inline constexpr int kMinBasisBits = 2, kMaxBasisBits = 16;
// The largest code of a column of `bits` bits: codes are symmetric, |q| ≤ 2^(bits−1) − 1.
int max_basis_code(int bits);

// Throws InputError for bits outside 2..16, block_rows < 1 or a non-finite basis.
QuantisedBasis quantise_basis(const Eigen::MatrixXd& basis, const Eigen::VectorXi& column_bits, int block_rows);
QuantisedBasis quantise_basis(const Eigen::MatrixXd& basis, int bits, int block_rows);

// Mixed precision: a decoded body's error from column k grows with the coefficient's size times
// the column's quantisation error, so the columns where that product is largest (the leading,
// high-variance components) get 16 bits, the others 8, until the 8-bit columns' root-sum-square
// is at most `fraction` of all columns' at 8 bits. `spread` (K): the largest |c_k| expected.
Eigen::VectorXi mixed_column_bits(const Eigen::MatrixXd& basis, const Eigen::VectorXd& spread, int block_rows,
                                  double fraction);
// The largest |c_k| over a sub-model's training coefficients (K).
Eigen::VectorXd coefficient_spread(const SubModel& sub);
Eigen::MatrixXd dequantise_basis(const QuantisedBasis& q);

// Bit packing (model file format 4): column k's D codes, each stored as q + max_basis_code(b_k)
// (0 .. 2^b − 2) in b_k bits, least significant bit first; each column starts on a new byte.
std::size_t packed_bytes(Eigen::Index rows, const Eigen::VectorXi& bits);
std::vector<uint8_t> pack_codes(const Eigen::MatrixXi& codes, const Eigen::VectorXi& bits);
// Throws InputError naming `what` and `name` when the byte count is not packed_bytes(rows, bits)
// (a truncated or padded array); a stored value of 2^b − 1 comes back as max_basis_code(b) + 1,
// which validate_quantised_basis refuses.
Eigen::MatrixXi unpack_codes(const std::vector<int64_t>& packed, Eigen::Index rows, const Eigen::VectorXi& bits,
                             const std::string& what, const std::string& name);

// Checks a quantised basis read from a file: shapes, bits (2..16), code range, scales finite and ≥ 0, and each
// dequantised column's norm within max_column_error_norm (+ 1e-6 relative) of column_norms — a
// corrupt scale changes it. Throws InputError with one line naming `what`, the array (`key` is the
// basis's: "shape_basis" → shape_basis_codes, _scales, _block_rows, _column_norms) and the element.
// `codes_name` names the array the codes came from in messages (default: '<key>_codes').
void validate_quantised_basis(const QuantisedBasis& q, const std::string& what, const std::string& key,
                              const std::string& codes_name = "");

// How far decoded bodies move when the model's bases are quantised: `samples` coefficient
// vectors drawn uniformly within each component's range over the training samples (the data's
// spread), decoded by the same decoder through `reference`'s and `other`'s bases (same model
// otherwise), compared vertex by vertex (no alignment: the decoder's placement is part of what
// a user gets). The shape model, and the full model when its basis is not the shape model's.
struct QuantisationError {
  int samples = 0;
  double max_mm = 0, mean_mm = 0;  // over all vertices of all samples (of both sub-models)
  double shape_max_mm = 0, full_max_mm = 0;
  std::string report() const;      // one line
};
QuantisationError decoded_body_difference(const BodyModel& reference, const BodyModel& other, int samples = 20,
                                          uint64_t seed = 1);

// The model with its bases replaced by their quantised-and-decoded values (what a reader of the
// file written with `options` gets): for measuring before writing.
BodyModel with_quantised_bases(const BodyModel& model, const ModelFileOptions& options);

// Bit allocation by each column's effect on decoded bodies (greedy reverse water-filling). A
// decoded body's error comes from the encoding error Σ_k c_k (b_k − b̂_k); with independent
// rounding errors its expected square is Σ_k E[c_k²] ‖b_k − b̂_k‖², where c_k is uniform within
// the training range (as the check draws it) and ‖b_k − b̂_k‖² is measured for every width. Bits
// go one at a time to the column whose extra bit lowers that sum most, until the predicted error
// is below the target (smallest file) or the next bit would not fit the size budget (lowest
// error). The mapping from that sum to the check's largest vertex distance is not linear in
// general: it is calibrated by the check itself (one ratio per sub-model, from an all-8-bit
// check, updated after every check), and the check decides.
struct BitAllocationOptions {
  double max_error_mm = 0.5;  // the check's bound
  double max_bytes = 0;       // > 0: the lowest error within this file size instead of the smallest file
  int min_bits = kMinBasisBits, max_bits = kMaxBasisBits, block_rows = 64, samples = 20, tries = 6;
  uint64_t seed = 1;
  void validate() const;      // InputError naming the bad field
};
struct BitAllocation {
  ModelFileOptions storage;   // per-column bits of both bases
  QuantisationError check;    // of `storage`
  QuantisationError held_out; // of `storage` on other random bodies (a seed of their own): the file must pass it
                              // too (error mode), but the bits are not chosen on it
  double file_bytes = 0;      // the file's size with `storage` (the bases' bytes plus the rest, deflated)
  bool passed = false;        // check.max_mm ≤ max_error_mm and, with a budget, file_bytes ≤ max_bytes
  int checks = 0;             // checks run (each decodes 2 × samples bodies twice)
};
// E[c_k²] of each coefficient drawn uniformly within its training range (K).
Eigen::VectorXd coefficient_second_moment(const SubModel& sub);
// ‖b_k − b̂_k‖² of every column at every width: K by (kMaxBasisBits + 1), columns below min_bits 0.
Eigen::MatrixXd column_error_table(const Eigen::MatrixXd& basis, int block_rows, int min_bits);
// `progress` gets one line per check (allocation, predicted and measured error, size).
BitAllocation allocate_basis_bits(const BodyModel& model, const BitAllocationOptions& options,
                                  const std::function<void(const std::string&)>& progress = {});
// The file's size in bytes when written with `storage`, without writing it: the bases' stored bytes
// (packed codes, scales, tables) plus the other arrays deflated as save_model does.
double estimated_file_bytes(const BodyModel& model, const ModelFileOptions& storage);

}  // namespace bodymodel
