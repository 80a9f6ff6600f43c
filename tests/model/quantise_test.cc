// Quantised bases (model/quantise.h) and model files written with them (model/model_file.h).
#include <gtest/gtest.h>

#include <random>

#include "core/error.h"
#include "model/model_file.h"
#include "model/quantise.h"
#include "model_test_util.h"
#include "support/fixtures.h"
#include "support/run_cli.h"

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
  EXPECT_THROW(quantise_basis(B, 1, 64), InputError);
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

// Every width from 2 to 16 bits, alone and mixed in one basis: each entry within half its block's
// step, codes within ±(2^(b−1) − 1), and column_error_table's squared errors are what
// quantise_basis leaves (the allocation's input), falling with every bit.
TEST(Quantise, EveryWidthStaysWithinItsStep) {
  const Eigen::MatrixXd B = test_basis(3000, 15, 5);
  Eigen::VectorXi bits(15);
  for (int k = 0; k < 15; ++k) bits(k) = 2 + k;  // 2 .. 16
  const QuantisedBasis q = quantise_basis(B, bits, 64);
  const Eigen::MatrixXd E = dequantise_basis(q) - B;
  const Eigen::MatrixXd table = column_error_table(B, 64, kMinBasisBits);
  for (int k = 0; k < 15; ++k) {
    const int top = max_basis_code(bits(k));
    EXPECT_LE(q.codes.col(k).cwiseAbs().maxCoeff(), top);
    EXPECT_EQ(q.codes.col(k).cwiseAbs().maxCoeff(), top) << "the block's largest entry gets the largest code";
    for (int i = 0; i < B.rows(); ++i)
      ASSERT_LE(std::abs(E(i, k)), 0.5 * q.scales(i / 64, k) * (1 + 1e-12)) << bits(k) << " bits, entry " << i;
    // The step is the block's largest |b| over 2^(b−1) − 1.
    EXPECT_NEAR(q.scales(0, k), B.col(k).head(64).cwiseAbs().maxCoeff() / top, 1e-6 * q.scales(0, k));
    EXPECT_NEAR(table(k, bits(k)), E.col(k).squaredNorm(), 1e-9 * E.col(k).squaredNorm() + 1e-300) << bits(k);
    for (int b = kMinBasisBits; b < kMaxBasisBits; ++b) EXPECT_LT(table(k, b + 1), table(k, b)) << k << ", " << b;
  }
  // Each extra bit about halves the step: 4 bits (step max/7) against 5 (max/15), error norm ≈ 15/7 times.
  const double r = std::sqrt(table.col(4).sum() / table.col(5).sum());
  EXPECT_GT(r, 1.9);
  EXPECT_LT(r, 2.6);
  EXPECT_THROW(quantise_basis(B, 1, 64), InputError);
  EXPECT_THROW(quantise_basis(B, 17, 64), InputError);
}

// Bit packing: a known answer, and every width round-trips exactly (the extreme codes included)
// over a row count that does not fill the last byte.
TEST(Quantise, PackingRoundTripsExactlyForEveryWidth) {
  // 3 bits: codes −3, 0, 3 stored as 0, 3, 6 = 000 110 011 (least significant bit first).
  Eigen::MatrixXi c3(3, 1);
  c3 << -3, 0, 3;
  const std::vector<uint8_t> p3 = pack_codes(c3, Eigen::VectorXi::Constant(1, 3));
  ASSERT_EQ(p3.size(), 2u);
  EXPECT_EQ(p3[0], 8 + 16 + 128);
  EXPECT_EQ(p3[1], 1);
  const Eigen::Index D = 1001;
  Eigen::VectorXi bits(15);
  for (int k = 0; k < 15; ++k) bits(k) = 16 - k;
  std::mt19937_64 rng(7);
  Eigen::MatrixXi codes(D, 15);
  for (int k = 0; k < 15; ++k) {
    const int top = max_basis_code(bits(k));
    std::uniform_int_distribution<int> u(-top, top);
    for (Eigen::Index i = 0; i < D; ++i) codes(i, k) = u(rng);
    codes(0, k) = -top;
    codes(D - 1, k) = top;
  }
  const std::vector<uint8_t> packed = pack_codes(codes, bits);
  std::size_t want = 0;
  for (int k = 0; k < 15; ++k) want += static_cast<std::size_t>((D * bits(k) + 7) / 8);
  EXPECT_EQ(packed.size(), want);
  EXPECT_EQ(packed_bytes(D, bits), want);
  const std::vector<int64_t> wide(packed.begin(), packed.end());
  EXPECT_EQ(unpack_codes(wide, D, bits, "test", "codes"), codes);
  // A code that does not fit its width is refused rather than wrapped.
  codes(5, 14) = 2;  // column 14 has 2 bits: ±1
  EXPECT_THROW(pack_codes(codes, bits), InputError);
}

// The allocation on a small MakeHuman-topology model: the file it chooses passes the check it was
// calibrated with and, within the same bound, a second one on other random bodies, is smaller
// than the 8/16-bit mix that passes the same bound, and its size estimate is the written size to a
// few per cent; with a budget the file fits it.
TEST(ModelFile, PerColumnBitsPassTheCheckInASmallerFile) {
  auto model = testing::shape_test_model();
  BitAllocationOptions ao;
  ao.max_error_mm = 0.25;
  ao.samples = 8;  // the verb's 20 made this test take minutes; 8 bodies still exercise every column
  const BitAllocation a = allocate_basis_bits(*model, ao);
  ASSERT_TRUE(a.passed) << a.check.report();
  EXPECT_LE(a.check.max_mm, 0.25);
  const std::string file = model_to_npz(*model, a.storage).serialize();
  EXPECT_NEAR(static_cast<double>(file.size()), a.file_bytes, 0.05 * a.file_bytes);
  const Npz z = Npz::parse(file, "qa.npz");
  EXPECT_EQ(z.scalar("format_version"), kPackedModelFormatVersion);
  EXPECT_EQ(z.arrays().at("shape_basis_packed").dtype, "|u1");
  const BodyModel back = model_from_npz(z, "qa.npz");
  EXPECT_EQ((back.shape.pca.basis - with_quantised_bases(*model, a.storage).shape.pca.basis).cwiseAbs().maxCoeff(), 0);
  const QuantisationError other = decoded_body_difference(*model, back, ao.samples, 99);
  EXPECT_LE(other.max_mm, 0.5) << other.report();
  EXPECT_EQ(a.held_out.samples, ao.samples);  // the confirmation on bodies the bits were not chosen with
  EXPECT_GT(a.held_out.max_mm, 0);
  EXPECT_LE(a.held_out.max_mm, ao.max_error_mm) << a.held_out.report();
  // Leading columns get more bits than trailing ones.
  const Eigen::VectorXi& bits = a.storage.shape_column_bits;
  EXPECT_GT(bits.head(3).sum(), bits.tail(3).sum());
  // The 8/16 mix of `quantise --bits 8` at the same bound (its fraction search, as choose_basis_storage).
  ModelFileOptions o;
  o.basis_bits = 8;
  const Eigen::VectorXd spread = coefficient_spread(model->shape);
  for (double fraction = 1;; fraction /= 2) {
    o.shape_column_bits = mixed_column_bits(model->shape.pca.basis, spread, 64, fraction);
    if (decoded_body_difference(*model, with_quantised_bases(*model, o), ao.samples).max_mm <= 0.25 || fraction < 1e-3) break;
  }
  const std::size_t mixed = model_to_npz(*model, o).serialize().size();
  EXPECT_LT(file.size(), mixed) << file.size() << " vs " << mixed;
  // A budget between the two: the file fits it.
  ao.max_bytes = 0.9 * static_cast<double>(file.size());
  ao.max_error_mm = 100;
  const BitAllocation b = allocate_basis_bits(*model, ao);
  EXPECT_TRUE(b.passed);
  EXPECT_LE(static_cast<double>(model_to_npz(*model, b.storage).serialize().size()), ao.max_bytes);
  EXPECT_GT(b.check.max_mm, 0);
  std::printf("per column: %s, %zu bytes; 8/16 mix: %zu bytes; budget %.0f: %s\n", a.check.report().c_str(),
              file.size(), mixed, ao.max_bytes, b.check.report().c_str());
}

// `quantise --compare` checks a written file on other random bodies: an 8-bit file passes a loose
// bound and fails a bound below its measured error (exit 1, the file named).
TEST(ModelFile, CompareChecksAWrittenFileOnOtherBodies) {
  auto model = testing::shape_test_model();
  fixtures::TempDir dir;
  save_model(dir / "m.npz", *model);
  ModelFileOptions o;
  o.basis_bits = 8;
  save_model(dir / "q8.npz", *model, o);
  const double e8 = decoded_body_difference(*model, load_model(dir / "q8.npz"), 3, 5).max_mm;
  ASSERT_GT(e8, 0);
  const std::string base = "quantise " + (dir / "m.npz").string() + " --compare " + (dir / "q8.npz").string() +
                           " --samples 3 --seed 5 --max-error-mm ";
  const auto pass = fixtures::run_cli(base + std::to_string(2 * e8));
  EXPECT_EQ(pass.exit_code, 0) << pass.output;
  EXPECT_NE(pass.output.find("3 random bodies"), std::string::npos) << pass.output;
  const auto fail = fixtures::run_cli(base + std::to_string(0.5 * e8));
  EXPECT_EQ(fail.exit_code, 1) << fail.output;
  EXPECT_NE(fail.output.find("q8.npz: a decoded vertex moves"), std::string::npos) << fail.output;
  // Checking and writing at once is refused.
  const auto both = fixtures::run_cli(base + "1 --out " + (dir / "q.npz").string());
  EXPECT_EQ(both.exit_code, 2) << both.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "q.npz"));
}

}  // namespace
}  // namespace bodymodel
