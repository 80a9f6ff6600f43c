// Quantised PCA bases: the bases are nearly all of a model file (D = 15·#F rows, one column per
// component), so a file a user can ship stores them as 8- or 16-bit integers (model_file.h).
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
#include <string>

#include "model/body_model.h"
#include "model/model_file.h"

namespace bodymodel {

struct QuantisedBasis {
  Eigen::VectorXi bits;     // K: 8 or 16 per column (16 where 8 bits would move bodies too far)
  int block_rows = 64;      // rows per scale within a column
  Eigen::MatrixXi codes;    // D by K, |q| ≤ 2^(bits−1) − 1 of the column
  Eigen::MatrixXd scales;   // ceil(D / block_rows) by K, float32 values, ≥ 0
  Eigen::VectorXd column_norms;  // K: of the basis that was quantised (a check on the scales)

  // Largest possible |b − decoded b| of each column's entries (s / 2 of its largest block) and
  // the largest possible norm of each column's error vector: the stored-scale bounds.
  Eigen::VectorXd max_entry_error() const;
  Eigen::VectorXd max_column_error_norm() const;
};

// Throws InputError for bits other than 8 or 16, block_rows < 1 or a non-finite basis.
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

// Checks a quantised basis read from a file: shapes, code range, scales finite and ≥ 0, and each
// dequantised column's norm within max_column_error_norm (+ 1e-6 relative) of column_norms — a
// corrupt scale changes it. Throws InputError with one line naming `what`, the array (`key` is the
// basis's: "shape_basis" → shape_basis_codes, _scales, _block_rows, _column_norms) and the element.
void validate_quantised_basis(const QuantisedBasis& q, const std::string& what, const std::string& key);

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

}  // namespace bodymodel
