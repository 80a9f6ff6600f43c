// Quantised bases (model/quantise.h) and model files written with them (model/model_file.h).
#include <gtest/gtest.h>

#include <random>

#include "core/error.h"
#include "model/model_file.h"
#include "model/quantise.h"
#include "model_test_util.h"

namespace bodymodel {
namespace {

// Orthonormal columns like a PCA basis, the last one large on a few rows only (a component that
// moves one hand): the case one scale per column handles worst.
Eigen::MatrixXd test_basis(int D, int K, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0, 1);
  Eigen::MatrixXd B(D, K);
  for (int k = 0; k < K; ++k)
    for (int i = 0; i < D; ++i) B(i, k) = n(rng) * (k == K - 1 && (i < 200 || i > 240) ? 1e-3 : 1.0);
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(B);
  return qr.householderQ() * Eigen::MatrixXd::Identity(D, K);
}

TEST(Quantise, EveryEntryStaysWithinHalfAStep) {
  const Eigen::MatrixXd B = test_basis(5000, 6, 3);
  for (int bits : {8, 16})
    for (int block : {64, 5000}) {
      const QuantisedBasis q = quantise_basis(B, bits, block);
      const Eigen::MatrixXd E = dequantise_basis(q) - B;
      ASSERT_EQ(q.scales.rows(), (5000 + block - 1) / block);
      for (int k = 0; k < B.cols(); ++k) {
        for (int i = 0; i < B.rows(); ++i)
          ASSERT_LE(std::abs(E(i, k)), 0.5 * q.scales(i / block, k) * (1 + 1e-12) + 1e-300)
              << bits << " bits, block " << block << ", entry " << i << ", " << k;
        EXPECT_LE(E.col(k).norm(), q.max_column_error_norm()(k));
        EXPECT_LE(E.col(k).cwiseAbs().maxCoeff(), q.max_entry_error()(k) * (1 + 1e-12));
        // The step is the block's largest entry over 127 (or 32767): never 0 for a nonzero block.
        EXPECT_GT(q.scales.col(k).minCoeff(), 0);
      }
      EXPECT_NO_THROW(validate_quantised_basis(q, "test", "basis"));
    }
  // Blocks keep a localised component's step local: its error is far smaller than with one scale.
  const int K = static_cast<int>(B.cols());
  const double blocked = (dequantise_basis(quantise_basis(B, 8, 64)) - B).col(K - 1).norm();
  const double per_column = (dequantise_basis(quantise_basis(B, 8, 5000)) - B).col(K - 1).norm();
  EXPECT_LT(blocked, 0.5 * per_column) << blocked << " vs " << per_column;
  // 16 bits are 256 times finer.
  const double e16 = (dequantise_basis(quantise_basis(B, 16, 64)) - B).norm();
  EXPECT_LT(e16, (dequantise_basis(quantise_basis(B, 8, 64)) - B).norm() / 100);
  EXPECT_THROW(quantise_basis(B, 4, 64), InputError);
  EXPECT_THROW(quantise_basis(B, 8, 0), InputError);
}

// A MakeHuman-topology model written with 8-bit bases reads back (format 3, int8 codes) with
// every basis entry within half its step. All 8 bits move random bodies by more than 0.5 mm
// here; with 16 bits for the columns that matter most (mixed_column_bits, the share the 8-bit
// error says) the decoded bodies stay within 0.5 mm of the float32 model's, in a smaller file.
TEST(ModelFile, QuantisedFileReadsBackAndDecodesWithinTheBound) {
  auto model = testing::shape_test_model();
  const std::string f32 = model_to_npz(*model).serialize();
  ModelFileOptions o;
  o.basis_bits = 8;
  const std::string q8 = model_to_npz(*model, o).serialize();
  EXPECT_LT(static_cast<double>(q8.size()), 0.5 * static_cast<double>(f32.size())) << q8.size() << " vs " << f32.size();
  const Npz z8 = Npz::parse(q8, "q8.npz");
  EXPECT_EQ(z8.scalar("format_version"), 3);
  EXPECT_FALSE(z8.has("shape_basis"));
  EXPECT_EQ(z8.arrays().at("shape_basis_codes").dtype, "|i1");
  const BodyModel back = model_from_npz(z8, "q8.npz");
  const Eigen::MatrixXd scales = z8.matrix("shape_basis_scales");
  const Eigen::MatrixXd E = back.shape.pca.basis - model->shape.pca.basis;
  for (Eigen::Index k = 0; k < E.cols(); ++k)
    for (Eigen::Index i = 0; i < E.rows(); ++i)
      ASSERT_LE(std::abs(E(i, k)), 0.5 * scales(i / o.block_rows, k) * (1 + 1e-9) + 1e-15);
  const QuantisationError e8 = decoded_body_difference(*model, back, 20);
  EXPECT_GT(e8.max_mm, 0) << "the bases did change";
  // Mixed: the 8-bit columns' share of the error cut to what 0.25 mm needs (the estimate is not exact).
  const double fraction = std::min(1.0, 0.25 / e8.max_mm);
  o.shape_column_bits = mixed_column_bits(model->shape.pca.basis, coefficient_spread(model->shape), 64, fraction);
  o.full_column_bits = mixed_column_bits(model->full.pca.basis, coefficient_spread(model->full), 64, fraction);
  const int n16 = static_cast<int>((o.shape_column_bits.array() == 16).count());
  const std::string qm = model_to_npz(*model, o).serialize();
  const Npz zm = Npz::parse(qm, "qm.npz");
  const BodyModel mixed = model_from_npz(zm, "qm.npz");
  EXPECT_EQ((mixed.shape.pca.basis - with_quantised_bases(*model, o).shape.pca.basis).cwiseAbs().maxCoeff(), 0);
  const QuantisationError em = decoded_body_difference(*model, mixed, 20);
  EXPECT_LE(em.max_mm, 0.5) << em.report();
  EXPECT_LT(qm.size(), f32.size());
  // 16 bits everywhere: closer still.
  o.basis_bits = 16;
  o.shape_column_bits.resize(0);
  o.full_column_bits.resize(0);
  const BodyModel back16 = model_from_npz(Npz::parse(model_to_npz(*model, o).serialize(), "q16.npz"), "q16.npz");
  EXPECT_LT(decoded_body_difference(*model, back16, 20).max_mm, em.max_mm);
  std::printf("8 bits: %s (%zu bytes)\nmixed, 16 bits for %d of %d shape columns: %s (%zu bytes); float32 %zu bytes\n",
              e8.report().c_str(), q8.size(), n16,
              model->shape.component_count(), em.report().c_str(), qm.size(), f32.size());
}

}  // namespace
}  // namespace bodymodel
