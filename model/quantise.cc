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

bool bases_shared(const BodyModel& m) {
  return m.full.pca.basis.cols() == m.shape.pca.basis.cols() && m.full.pca.basis == m.shape.pca.basis;
}

int blocks_of(Eigen::Index rows, int block_rows) {
  return static_cast<int>((rows + block_rows - 1) / block_rows);
}

}  // namespace

int max_basis_code(int bits) { return (1 << (bits - 1)) - 1; }

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
    if (bits(k) < kMinBasisBits || bits(k) > kMaxBasisBits)
      throw InputError(fmt::format("quantised bases have {} to {} bits per column, got {}", kMinBasisBits,
                                   kMaxBasisBits, bits(k)));
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
    for (int b = 0, top = max_basis_code(bits(k)); b < nb; ++b) {
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

std::size_t packed_bytes(Eigen::Index rows, const Eigen::VectorXi& bits) {
  std::size_t n = 0;
  for (Eigen::Index k = 0; k < bits.size(); ++k) n += (static_cast<std::size_t>(rows) * bits(k) + 7) / 8;
  return n;
}

std::vector<uint8_t> pack_codes(const Eigen::MatrixXi& codes, const Eigen::VectorXi& bits) {
  if (bits.size() != codes.cols())
    throw InputError(fmt::format("quantisation: {} column bit counts for {} columns", bits.size(), codes.cols()));
  std::vector<uint8_t> out(packed_bytes(codes.rows(), bits), 0);
  std::size_t byte0 = 0;
  for (Eigen::Index k = 0; k < codes.cols(); ++k) {
    const int b = bits(k), top = max_basis_code(b);
    std::size_t bit = byte0 * 8;
    for (Eigen::Index i = 0; i < codes.rows(); ++i, bit += b) {
      const int q = codes(i, k);
      if (q < -top || q > top)
        throw InputError(fmt::format("quantisation: code {} of column {} does not fit {} bits", q, k, b));
      const uint32_t u = static_cast<uint32_t>(q + top);
      for (int j = 0; j < b; ++j)
        if (u >> j & 1u) out[(bit + j) / 8] |= static_cast<uint8_t>(1u << ((bit + j) % 8));
    }
    byte0 += (static_cast<std::size_t>(codes.rows()) * b + 7) / 8;
  }
  return out;
}

Eigen::MatrixXi unpack_codes(const std::vector<int64_t>& packed, Eigen::Index rows, const Eigen::VectorXi& bits,
                             const std::string& what, const std::string& name) {
  for (Eigen::Index k = 0; k < bits.size(); ++k)
    if (bits(k) < kMinBasisBits || bits(k) > kMaxBasisBits)
      throw InputError(fmt::format("{}: column {} of '{}' has {} bits, expected {} to {}", what, k, name, bits(k),
                                   kMinBasisBits, kMaxBasisBits));
  const std::size_t want = packed_bytes(rows, bits);
  if (packed.size() != want)
    throw InputError(fmt::format("{}: '{}' has {} bytes, expected {} ({} rows of {} columns at their column bits): "
                                 "truncated or inconsistent",
                                 what, name, packed.size(), want, rows, bits.size()));
  Eigen::MatrixXi codes(rows, bits.size());
  std::size_t byte0 = 0;
  for (Eigen::Index k = 0; k < bits.size(); ++k) {
    const int b = bits(k), top = max_basis_code(b);
    std::size_t bit = byte0 * 8;
    for (Eigen::Index i = 0; i < rows; ++i, bit += b) {
      uint32_t u = 0;
      for (int j = 0; j < b; ++j) u |= static_cast<uint32_t>(packed[(bit + j) / 8] >> ((bit + j) % 8) & 1) << j;
      codes(i, k) = static_cast<int>(u) - top;
    }
    byte0 += (static_cast<std::size_t>(rows) * b + 7) / 8;
  }
  return codes;
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

void validate_quantised_basis(const QuantisedBasis& q, const std::string& what, const std::string& key,
                              const std::string& codes_name) {
  if (q.bits.size() != q.codes.cols())
    throw InputError(fmt::format("{}: '{}_column_bits' has {} values for {} columns", what, key, q.bits.size(),
                                 q.codes.cols()));
  for (Eigen::Index k = 0; k < q.bits.size(); ++k)
    if (q.bits(k) < kMinBasisBits || q.bits(k) > kMaxBasisBits)
      throw InputError(fmt::format("{}: '{}_column_bits' element {} is {}, expected {} to {}", what, key, k, q.bits(k),
                                   kMinBasisBits, kMaxBasisBits));
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
    const int top = max_basis_code(q.bits(k));
    if (q.codes.rows() > 0 && (q.codes.col(k).maxCoeff() > top || q.codes.col(k).minCoeff() < -top))
      throw InputError(fmt::format("{}: '{}' holds codes outside ±{} in column {} ({} bits)", what,
                                   !codes_name.empty() ? codes_name : key + (q.bits(k) == 16 ? "_codes16" : "_codes"),
                                   top, k, q.bits(k)));
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

Eigen::VectorXd coefficient_second_moment(const SubModel& sub) {
  const Eigen::MatrixXd& C = sub.pca.coefficients;
  if (C.rows() == 0) return sub.pca.eigenvalues.cwiseMax(0) * 3;  // uniform on ±3σ: variance 3σ²
  const Eigen::ArrayXd lo = C.colwise().minCoeff().transpose().array(), hi = C.colwise().maxCoeff().transpose().array();
  return ((lo * lo + lo * hi + hi * hi) / 3).matrix();
}

Eigen::MatrixXd column_error_table(const Eigen::MatrixXd& B, int block_rows, int min_bits) {
  if (block_rows < 1) throw InputError(fmt::format("quantisation block rows must be ≥ 1, got {}", block_rows));
  if (min_bits < kMinBasisBits || min_bits > kMaxBasisBits)
    throw InputError(fmt::format("quantisation: minimum bits {} outside {} to {}", min_bits, kMinBasisBits, kMaxBasisBits));
  Eigen::MatrixXd T = Eigen::MatrixXd::Zero(B.cols(), kMaxBasisBits + 1);
  const Eigen::Index D = B.rows();
  tbb::parallel_for(Eigen::Index(0), B.cols(), [&](Eigen::Index k) {
    for (Eigen::Index r0 = 0; r0 < D; r0 += block_rows) {
      const Eigen::Index n = std::min<Eigen::Index>(block_rows, D - r0);
      const auto x = B.col(k).segment(r0, n);
      const double m = x.cwiseAbs().maxCoeff();
      for (int b = min_bits; b <= kMaxBasisBits; ++b) {
        const double step = static_cast<double>(static_cast<float>(m / max_basis_code(b)));  // as quantise_basis
        if (step <= 0) continue;
        double e2 = 0;
        for (Eigen::Index i = 0; i < n; ++i) {
          const double e = x(i) - step * std::nearbyint(x(i) / step);
          e2 += e * e;
        }
        T(k, b) += e2;
      }
    }
  });
  return T;
}

double estimated_file_bytes(const BodyModel& model, const ModelFileOptions& o) {
  ModelFileOptions rest = o;
  rest.omit_bases = true;
  double bytes = static_cast<double>(model_to_npz(model, rest).serialize().size());
  if (o.basis_bits == 32 && o.shape_column_bits.size() == 0)
    return bytes + 4.0 * static_cast<double>(model.shape.pca.basis.size() + model.full.pca.basis.size());
  auto basis_bytes = [&](const SubModel& sub, const Eigen::VectorXi& given) {
    const Eigen::VectorXi bits =
        given.size() > 0 ? given : Eigen::VectorXi(Eigen::VectorXi::Constant(sub.component_count(), o.basis_bits));
    const Eigen::Index K = bits.size(), D = sub.pca.basis.rows();
    // Packed codes (8 and 16 bits: the same bytes unpacked), float32 scales, bits, norms, headers.
    return static_cast<double>(packed_bytes(D, bits)) + 4.0 * static_cast<double>(blocks_of(D, o.block_rows) * K) +
           12.0 * static_cast<double>(K) + 2048;
  };
  bytes += basis_bytes(model.shape, o.shape_column_bits);
  if (!bases_shared(model)) bytes += basis_bytes(model.full, o.full_column_bits);
  return bytes;
}

namespace {

constexpr double kAimFraction = 0.5;   // of the bound: the predicted error the allocation aims at

// One basis being allocated: its error table, weights, bits and calibration (mm per unit of the
// predicted error).
struct ColumnBits {
  Eigen::MatrixXd e2;  // K by 17
  Eigen::VectorXd w;   // K
  Eigen::VectorXi bits;
  double mm_per_unit = 1;
  double predicted() const {
    double s = 0;
    for (Eigen::Index k = 0; k < w.size(); ++k) s += w(k) * e2(k, bits(k));
    return std::sqrt(s);
  }
  double predicted_mm() const { return mm_per_unit * predicted(); }
  // The column whose next bit lowers the predicted error most (−1: all at max_bits).
  Eigen::Index best(int max_bits) const {
    Eigen::Index best = -1;
    double gain = -1;
    for (Eigen::Index k = 0; k < w.size(); ++k)
      if (bits(k) < max_bits) {
        const double g = w(k) * (e2(k, bits(k)) - e2(k, bits(k) + 1));
        if (g > gain) gain = g, best = k;
      }
    return best;
  }
};

// Greedy allocation from min_bits: error mode adds bits to each basis until its predicted error is
// below `target_mm`; budget mode adds bits to the basis with the larger predicted error while the
// file stays within max_bytes (each bit of a column costs D / 8 bytes).
void greedy_bits(std::vector<ColumnBits>& subs, const BitAllocationOptions& o, double target_mm, double fixed_bytes,
                 double D) {
  double bytes = fixed_bytes;
  for (auto& s : subs) {
    s.bits.setConstant(s.w.size(), o.min_bits);
    bytes += s.w.size() * std::ceil(D * o.min_bits / 8);
  }
  for (;;) {
    ColumnBits* worst = nullptr;
    for (auto& s : subs)
      if (s.best(o.max_bits) >= 0 && (!worst || s.predicted_mm() > worst->predicted_mm())) worst = &s;
    if (!worst) return;
    if (o.max_bytes > 0 ? bytes + D / 8 > o.max_bytes : worst->predicted_mm() <= target_mm) return;
    ++worst->bits(worst->best(o.max_bits));
    bytes += D / 8;
  }
}

std::string bits_summary(const Eigen::VectorXi& bits) {
  std::string s;
  for (int b = kMinBasisBits; b <= kMaxBasisBits; ++b)
    if (const auto n = (bits.array() == b).count(); n > 0) s += fmt::format("{}{}×{}", s.empty() ? "" : " ", n, b);
  return s;
}

}  // namespace

void BitAllocationOptions::validate() const {
  if (!(max_error_mm > 0)) throw InputError(fmt::format("the error bound must be > 0 mm, got {}", max_error_mm));
  if (!(max_bytes >= 0)) throw InputError(fmt::format("the size budget must be ≥ 0, got {}", max_bytes));
  if (min_bits < kMinBasisBits || max_bits > kMaxBasisBits || min_bits > max_bits)
    throw InputError(fmt::format("bits per column {} to {}: expected {} ≤ min ≤ max ≤ {}", min_bits, max_bits,
                                 kMinBasisBits, kMaxBasisBits));
  if (block_rows < 1 || samples < 1 || tries < 1)
    throw InputError(fmt::format("block rows, samples and tries must be ≥ 1, got {}, {}, {}", block_rows, samples, tries));
}

BitAllocation allocate_basis_bits(const BodyModel& model, const BitAllocationOptions& o,
                                  const std::function<void(const std::string&)>& progress) {
  o.validate();
  const bool shared = bases_shared(model);
  std::vector<ColumnBits> subs(shared ? 1 : 2);
  subs[0].w = coefficient_second_moment(model.shape);
  if (shared) subs[0].w = subs[0].w.cwiseMax(coefficient_second_moment(model.full));
  subs[0].e2 = column_error_table(model.shape.pca.basis, o.block_rows, o.min_bits);
  if (!shared) {
    subs[1].w = coefficient_second_moment(model.full);
    subs[1].e2 = column_error_table(model.full.pca.basis, o.block_rows, o.min_bits);
  }
  const double D = static_cast<double>(model.shape.pca.basis.rows());
  BitAllocation a;
  a.storage.basis_bits = 8;
  a.storage.block_rows = o.block_rows;
  const double codes_bytes = 8 * D / 8 * static_cast<double>(model.shape.component_count() +
                                                             (shared ? 0 : model.full.component_count()));
  const double fixed_bytes = estimated_file_bytes(model, a.storage) - codes_bytes;  // all but the codes
  auto apply = [&] {
    a.storage.shape_column_bits = subs[0].bits;
    a.storage.full_column_bits = shared ? subs[0].bits : subs[1].bits;
  };
  for (auto& s : subs) s.bits = Eigen::VectorXi::Constant(s.w.size(), 8);  // the first check calibrates
  BitAllocation best;
  for (int attempt = 0; attempt <= o.tries; ++attempt) {
    // The largest distance over a few random bodies varies by about 1.5× from one set of bodies to
    // another, so the allocation aims well below the bound (docs/model.md §6).
    if (attempt > 0) greedy_bits(subs, o, kAimFraction * o.max_error_mm, fixed_bytes, D);
    apply();
    const BodyModel quantised = with_quantised_bases(model, a.storage);
    a.check = decoded_body_difference(model, quantised, o.samples, o.seed);
    a.file_bytes = estimated_file_bytes(model, a.storage);
    a.checks = attempt + 1;
    const double measured[2] = {shared ? a.check.max_mm : a.check.shape_max_mm, a.check.full_max_mm};
    for (size_t i = 0; i < subs.size(); ++i)
      if (const double p = subs[i].predicted(); p > 0 && measured[i] > 0) subs[i].mm_per_unit = measured[i] / p;
    a.passed = a.check.max_mm <= o.max_error_mm && (o.max_bytes <= 0 || a.file_bytes <= o.max_bytes);
    // Error mode: the maximum over a few random bodies is a noisy statistic, so a file that passes
    // must also pass on other bodies (a new seed per attempt); if it does not, their error
    // recalibrates the prediction and the allocation goes on.
    a.held_out = {};
    if (attempt > 0 && a.passed && o.max_bytes <= 0) {
      a.held_out = decoded_body_difference(model, quantised, o.samples, o.seed + 100 + static_cast<uint64_t>(attempt));
      const double confirmed[2] = {shared ? a.held_out.max_mm : a.held_out.shape_max_mm, a.held_out.full_max_mm};
      for (size_t i = 0; i < subs.size(); ++i)
        if (const double p = subs[i].predicted(); p > 0)
          subs[i].mm_per_unit = std::max(subs[i].mm_per_unit, confirmed[i] / p);
      a.passed = a.held_out.max_mm <= o.max_error_mm;
    }
    if (progress)
      progress(fmt::format("{}bits per column: shape {}{}{}; {:.2f} MB; {}", attempt == 0 ? "calibration, " : "",
                           bits_summary(subs[0].bits), shared ? "" : ", full ",
                           shared ? "" : bits_summary(subs[1].bits), a.file_bytes / 1e6, a.check.report()) +
               (a.held_out.samples > 0 ? fmt::format("; on {} other bodies max {:.4f} mm{}", a.held_out.samples,
                                                     a.held_out.max_mm, a.passed ? "" : " (over: recalibrated)")
                                       : std::string()));
    // Kept: the smallest passing file (error mode) or the lowest passing error (budget mode).
    if (attempt > 0 && a.passed &&
        (!best.passed || (o.max_bytes > 0 ? a.check.max_mm < best.check.max_mm : a.file_bytes < best.file_bytes)))
      best = a;
    best.checks = a.checks;
    // Error mode stops at the first pass unless it is far below the aim (the calibrated ratio
    // then allows a smaller file); budget mode refines the split once.
    const bool done = o.max_bytes > 0 ? attempt >= 2 : a.passed && a.check.max_mm > 0.65 * kAimFraction * o.max_error_mm;
    if (attempt > 0 && done) break;
  }
  if (best.passed) {
    if (best.held_out.samples == 0)
      best.held_out = decoded_body_difference(model, with_quantised_bases(model, best.storage), o.samples, o.seed + 100);
    return best;
  }
  return a;
}

}  // namespace bodymodel
