#include "model/quantise.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <random>

#include "core/error.h"
#include "encoding/relative_rotation_decoder.h"
#include "model/format.h"

namespace bodymodel {
namespace {

int blocks_of(Eigen::Index rows, int block_rows) {
  return static_cast<int>((rows + block_rows - 1) / block_rows);
}

int max_code(int bits) { return bits == 8 ? 127 : 32767; }

}  // namespace

Eigen::VectorXd QuantisedBasis::max_entry_error() const {
  Eigen::VectorXd e(scales.cols());
  for (Eigen::Index k = 0; k < scales.cols(); ++k) e(k) = scales.col(k).size() ? scales.col(k).maxCoeff() / 2 : 0.0;
  return e;
}

Eigen::VectorXd QuantisedBasis::max_column_error_norm() const {
  Eigen::VectorXd e(scales.cols());
  for (Eigen::Index k = 0; k < scales.cols(); ++k) {
    double s2 = 0;
    for (Eigen::Index b = 0; b < scales.rows(); ++b) {
      const Eigen::Index rows = std::min<Eigen::Index>(block_rows, codes.rows() - b * block_rows);
      s2 += static_cast<double>(rows) * 0.25 * scales(b, k) * scales(b, k);
    }
    e(k) = std::sqrt(s2);
  }
  return e;
}

QuantisedBasis quantise_basis(const Eigen::MatrixXd& B, int bits, int block_rows) {
  return quantise_basis(B, Eigen::VectorXi::Constant(B.cols(), bits), block_rows);
}

QuantisedBasis quantise_basis(const Eigen::MatrixXd& B, const Eigen::VectorXi& bits, int block_rows) {
  if (bits.size() != B.cols())
    throw InputError(fmt::format("quantisation: {} column bit counts for {} columns", bits.size(), B.cols()));
  for (Eigen::Index k = 0; k < bits.size(); ++k)
    if (bits(k) != 8 && bits(k) != 16)
      throw InputError(fmt::format("quantised bases have 8 or 16 bits, got {}", bits(k)));
  if (block_rows < 1) throw InputError(fmt::format("quantisation block rows must be ≥ 1, got {}", block_rows));
  if (!B.allFinite()) throw InputError("cannot quantise a basis with NaN or infinite entries");
  QuantisedBasis q;
  q.bits = bits;
  q.block_rows = block_rows;
  const Eigen::Index D = B.rows(), K = B.cols();
  const int nb = blocks_of(D, block_rows);
  q.codes.resize(D, K);
  q.scales.resize(nb, K);
  q.column_norms = B.colwise().norm().transpose();
  for (Eigen::Index k = 0; k < K; ++k)
    for (int b = 0, top = max_code(bits(k)); b < nb; ++b) {
      const Eigen::Index r0 = static_cast<Eigen::Index>(b) * block_rows;
      const Eigen::Index n = std::min<Eigen::Index>(block_rows, D - r0);
      const double m = B.col(k).segment(r0, n).cwiseAbs().maxCoeff();
      // Stored as float32: quantise with the rounded scale so |b − s·q| ≤ s/2 holds for the file.
      const double s = static_cast<double>(static_cast<float>(m / top));
      q.scales(b, k) = s;
      for (Eigen::Index i = r0; i < r0 + n; ++i) {
        const long v = s > 0 ? std::lround(B(i, k) / s) : 0;
        q.codes(i, k) = static_cast<int>(std::clamp<long>(v, -top, top));
      }
    }
  return q;
}

Eigen::MatrixXd dequantise_basis(const QuantisedBasis& q) {
  Eigen::MatrixXd B(q.codes.rows(), q.codes.cols());
  for (Eigen::Index k = 0; k < B.cols(); ++k)
    for (Eigen::Index i = 0; i < B.rows(); ++i) B(i, k) = q.scales(i / q.block_rows, k) * q.codes(i, k);
  return B;
}

Eigen::VectorXd coefficient_spread(const SubModel& sub) {
  const Eigen::MatrixXd& C = sub.pca.coefficients;
  if (C.rows() == 0) return sub.pca.eigenvalues.cwiseMax(0).cwiseSqrt() * 3;
  return C.cwiseAbs().colwise().maxCoeff().transpose();
}

Eigen::VectorXi mixed_column_bits(const Eigen::MatrixXd& B, const Eigen::VectorXd& spread, int block_rows,
                                  double fraction) {
  if (spread.size() != B.cols())
    throw InputError(fmt::format("quantisation: {} coefficient spreads for {} columns", spread.size(), B.cols()));
  const Eigen::MatrixXd E = dequantise_basis(quantise_basis(B, 8, block_rows)) - B;
  std::vector<std::pair<double, Eigen::Index>> a;
  double total = 0;
  for (Eigen::Index k = 0; k < B.cols(); ++k) {
    const double ak = spread(k) * E.col(k).norm();
    a.emplace_back(ak * ak, k);
    total += ak * ak;
  }
  std::sort(a.begin(), a.end(), [](const auto& x, const auto& y) { return x.first > y.first; });
  Eigen::VectorXi bits = Eigen::VectorXi::Constant(B.cols(), 8);
  double rest = total;
  for (const auto& [a2, k] : a) {
    if (rest <= fraction * fraction * total) break;
    bits(k) = 16;
    rest -= a2;
  }
  return bits;
}

void validate_quantised_basis(const QuantisedBasis& q, const std::string& what, const std::string& key) {
  if (q.bits.size() != q.codes.cols())
    throw InputError(fmt::format("{}: '{}_column_bits' has {} values for {} columns", what, key, q.bits.size(),
                                 q.codes.cols()));
  for (Eigen::Index k = 0; k < q.bits.size(); ++k)
    if (q.bits(k) != 8 && q.bits(k) != 16)
      throw InputError(fmt::format("{}: '{}_column_bits' element {} is {}, expected 8 or 16", what, key, k, q.bits(k)));
  if (q.block_rows < 1)
    throw InputError(fmt::format("{}: '{}_block_rows' is {}, expected ≥ 1", what, key, q.block_rows));
  const Eigen::Index K = q.codes.cols();
  if (q.scales.rows() != blocks_of(q.codes.rows(), q.block_rows) || q.scales.cols() != K ||
      q.column_norms.size() != K)
    throw InputError(fmt::format("{}: '{}_scales' is {}×{} and '{}_column_norms' has {} values, expected {}×{} "
                                 "and {} ({} rows of '{}_codes' in blocks of {})",
                                 what, key, q.scales.rows(), q.scales.cols(), key, q.column_norms.size(),
                                 blocks_of(q.codes.rows(), q.block_rows), K, K, q.codes.rows(), key, q.block_rows));
  for (Eigen::Index k = 0; k < K; ++k)
    for (Eigen::Index b = 0; b < q.scales.rows(); ++b)
      if (!std::isfinite(q.scales(b, k)) || q.scales(b, k) < 0)
        throw InputError(fmt::format("{}: '{}_scales' row {}, column {} is {}, expected a finite scale ≥ 0", what,
                                     key, b, k, q.scales(b, k)));
  for (Eigen::Index k = 0; k < K; ++k) {
    const int top = max_code(q.bits(k));
    if (q.codes.rows() > 0 && (q.codes.col(k).maxCoeff() > top || q.codes.col(k).minCoeff() < -top))
      throw InputError(fmt::format("{}: '{}_codes{}' holds codes outside ±{} in column {} ({} bits)", what, key,
                                   q.bits(k) == 8 ? "" : "16", top, k, q.bits(k)));
  }
  const Eigen::VectorXd bound = q.max_column_error_norm();
  for (Eigen::Index k = 0; k < K; ++k) {
    double n2 = 0;
    for (Eigen::Index i = 0; i < q.codes.rows(); ++i) {
      const double v = q.scales(i / q.block_rows, k) * q.codes(i, k);
      n2 += v * v;
    }
    const double norm = std::sqrt(n2), expected = q.column_norms(k);
    if (!(std::abs(norm - expected) <= bound(k) + 1e-6 * std::max(1.0, std::abs(expected))))
      throw InputError(fmt::format("{}: '{}_codes' column {} decodes to norm {:.6g}, '{}_column_norms' says {:.6g} "
                                   "(at most {:.3g} apart): a corrupt scale in '{}_scales'",
                                   what, key, k, norm, key, expected, bound(k), key));
  }
}

std::string QuantisationError::report() const {
  return fmt::format("{} random bodies per model decoded through both bases: max vertex distance {:.4f} mm "
                     "(shape model {:.4f}, full model {:.4f}), mean {:.5f} mm",
                     samples, max_mm, shape_max_mm, full_max_mm, mean_mm);
}

namespace {

// Max and sum of vertex distances between bodies decoded from the same random coefficients.
void compare_sub_models(const BodyModel& a, const SubModel& sa, const SubModel& sb, int samples, uint64_t seed,
                        double& max_mm, double& sum_mm, long& count) {
  const Pca& pa = sa.pca;
  const int K = pa.component_count();
  Eigen::VectorXd lo = Eigen::VectorXd::Zero(K), hi = Eigen::VectorXd::Zero(K);
  if (pa.coefficients.rows() > 0) {
    lo = pa.coefficients.colwise().minCoeff().transpose();
    hi = pa.coefficients.colwise().maxCoeff().transpose();
  }
  std::vector<Eigen::VectorXd> cs(samples, Eigen::VectorXd(K));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (auto& c : cs)
    for (int k = 0; k < K; ++k) c(k) = lo(k) + (hi(k) - lo(k)) * u(rng);
  RelativeRotationDecoder decoder(a.tmpl);
  std::mutex mtx;
  tbb::parallel_for(0, samples, [&](int s) {
    const Eigen::MatrixX3d Va = decoder.decode(a.encoding_of(pa.reconstruct(cs[s])));
    const Eigen::MatrixX3d Vb = decoder.decode(a.encoding_of(sb.pca.reconstruct(cs[s])));
    const Eigen::VectorXd d = (Va - Vb).rowwise().norm();
    std::lock_guard<std::mutex> lock(mtx);
    max_mm = std::max(max_mm, d.maxCoeff());
    sum_mm += d.sum();
    count += d.size();
  });
}

}  // namespace

QuantisationError decoded_body_difference(const BodyModel& ref, const BodyModel& other, int samples, uint64_t seed) {
  if (samples < 1) throw InputError(fmt::format("quantisation check: samples must be ≥ 1, got {}", samples));
  auto same_shape = [](const SubModel& x, const SubModel& y) {
    return x.pca.basis.rows() == y.pca.basis.rows() && x.pca.basis.cols() == y.pca.basis.cols();
  };
  if (!same_shape(ref.shape, other.shape) || !same_shape(ref.full, other.full))
    throw InputError("quantisation check: the two models' bases differ in size");
  QuantisationError e;
  e.samples = samples;
  double sum = 0;
  long count = 0;
  compare_sub_models(ref, ref.shape, other.shape, samples, seed, e.shape_max_mm, sum, count);
  const bool shared = ref.full.pca.basis.cols() == ref.shape.pca.basis.cols() &&
                      ref.full.pca.basis == ref.shape.pca.basis && ref.full.pca.mean == ref.shape.pca.mean;
  if (shared)
    e.full_max_mm = e.shape_max_mm;
  else
    compare_sub_models(ref, ref.full, other.full, samples, seed + 1, e.full_max_mm, sum, count);
  e.max_mm = std::max(e.shape_max_mm, e.full_max_mm);
  e.mean_mm = count > 0 ? sum / static_cast<double>(count) : 0.0;
  return e;
}

BodyModel with_quantised_bases(const BodyModel& model, const ModelFileOptions& o) {
  o.validate();
  BodyModel q = model;
  if (o.basis_bits == 32) {  // float32
    q.shape.pca.basis = model.shape.pca.basis.cast<float>().cast<double>();
    q.full.pca.basis = model.full.pca.basis.cast<float>().cast<double>();
    return q;
  }
  auto bits_of = [&](const Eigen::VectorXi& given, const SubModel& sub) {
    return given.size() > 0 ? given : Eigen::VectorXi(Eigen::VectorXi::Constant(sub.component_count(), o.basis_bits));
  };
  const bool shared = model.full.pca.basis.cols() == model.shape.pca.basis.cols() &&
                      model.full.pca.basis == model.shape.pca.basis;
  const Eigen::VectorXi shape_bits = bits_of(o.shape_column_bits, model.shape);
  q.shape.pca.basis = dequantise_basis(quantise_basis(model.shape.pca.basis, shape_bits, o.block_rows));
  q.full.pca.basis = shared ? q.shape.pca.basis
                            : dequantise_basis(quantise_basis(model.full.pca.basis,
                                                              bits_of(o.full_column_bits, model.full), o.block_rows));
  return q;
}

}  // namespace bodymodel
