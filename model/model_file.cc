#include "model/model_file.h"

#include "core/io/json_text.h"
#include "model/format.h"
#include "model/quantise.h"

#include "core/error.h"
#include "core/io/file_names.h"

#include <algorithm>
#include <cmath>

namespace bodymodel {
namespace {

std::string json_list(const std::vector<std::string>& v) { return json_text(nlohmann::json(v)); }

// A NaN or infinity in a model array would reach every body decoded from it: refused on load,
// naming the array and the first bad element.
// `missing_ok`: NaN is a missing value (a subject's label table may have gaps, e.g. a
// population subject's unrecorded NHANES value; the regression uses the known ones).
template <typename Derived>
void check_finite(const Eigen::DenseBase<Derived>& M, const std::string& key, const std::string& what,
                  bool missing_ok = false) {
  if (M.allFinite()) return;
  for (Eigen::Index r = 0; r < M.rows(); ++r)
    for (Eigen::Index c = 0; c < M.cols(); ++c)
      if (!std::isfinite(M(r, c)) && !(missing_ok && std::isnan(M(r, c))))
        throw InputError(fmt::format("{}: '{}' holds {} at {}, expected finite values", what, key,
                                     std::isnan(M(r, c)) ? "NaN" : "infinity", M.cols() == 1 ? fmt::format("element {}", r)
                                                            : fmt::format("row {}, column {}", r, c)));
}

std::vector<std::string> read_list(const Npz& z, const std::string& key, const std::string& what) {
  try {
    auto j = nlohmann::json::parse(z.text(key));
    return j.get<std::vector<std::string>>();
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("{}: '{}' is not a JSON list of strings ({})", what, key, e.what()));
  }
}

void put_sparse(Npz& z, const std::string& key, const Eigen::SparseMatrix<double, Eigen::RowMajor>& M) {
  Eigen::MatrixXd T(M.nonZeros(), 3);
  int k = 0;
  for (int r = 0; r < M.outerSize(); ++r)
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(M, r); it; ++it, ++k)
      T.row(k) << it.row(), it.col(), it.value();
  z.put(key, T);
  Eigen::VectorXi shape(2);
  shape << static_cast<int>(M.rows()), static_cast<int>(M.cols());
  z.put(key + "_shape", shape);
}

// A sparse matrix stored as (row, column, value) triplets and a 2-element shape, which must be
// rows × cols (the caller's expectation: a wrong shape is refused before anything is allocated).
Eigen::SparseMatrix<double, Eigen::RowMajor> get_sparse(const Npz& z, const std::string& key,
                                                        const std::string& what, int rows, int cols) {
  Eigen::MatrixXd T = z.matrix(key);
  Eigen::VectorXi shape = z.int_vector(key + "_shape");
  if (shape.size() != 2 || T.cols() != 3)
    throw InputError(fmt::format("{}: '{}' must be #nonzeros by 3 triplets with a 2-element shape", what, key));
  if (shape(0) != rows || shape(1) != cols)
    throw InputError(fmt::format("{}: '{}_shape' is {}×{}, expected {}×{} (bones × template vertices, "
                                 "or template vertices × bones for the weights)",
                                 what, key, shape(0), shape(1), rows, cols));
  check_finite(T, key, what);
  std::vector<Eigen::Triplet<double>> trip;
  for (int i = 0; i < T.rows(); ++i) {
    const double r = T(i, 0), c = T(i, 1);
    if (!(r >= 0 && r < rows && c >= 0 && c < cols) || r != std::floor(r) || c != std::floor(c))
      throw InputError(fmt::format("{}: '{}' triplet {} is at ({}, {}), outside the {}×{} matrix", what, key, i,
                                   r, c, rows, cols));
    trip.emplace_back(static_cast<int>(r), static_cast<int>(c), T(i, 2));
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> M(rows, cols);
  M.setFromTriplets(trip.begin(), trip.end());
  return M;
}

// Per-column bits of a basis stored with `o` (empty `given`: all o.basis_bits).
Eigen::VectorXi column_bits_of(const ModelFileOptions& o, const Eigen::VectorXi& given, Eigen::Index K) {
  return given.size() > 0 ? given : Eigen::VectorXi(Eigen::VectorXi::Constant(K, o.basis_bits));
}

bool byte_aligned(const Eigen::VectorXi& bits) { return ((bits.array() == 8) || (bits.array() == 16)).all(); }

// The bases are most of the file (D by K): float32 (relative precision 6e-8, far below what
// decoding resolves; see model_file.h) or quantised codes with their scales: int8 / int16 arrays
// when every column is 8 or 16 bits (format 3), otherwise one bit-packed uint8 array (format 4).
void put_basis(Npz& z, const std::string& key, const Eigen::MatrixXd& B, const ModelFileOptions& o,
               const Eigen::VectorXi& column_bits) {
  if (o.omit_bases) return;
  if (o.basis_bits == 32) {
    z.put_float32(key, B);
    return;
  }
  const Eigen::VectorXi bits = column_bits_of(o, column_bits, B.cols());
  QuantisedBasis q = quantise_basis(B, bits, o.block_rows);
  if (byte_aligned(bits)) {
    for (int b : {8, 16}) {
      std::vector<Eigen::Index> cols;
      for (Eigen::Index k = 0; k < bits.size(); ++k)
        if (bits(k) == b) cols.push_back(k);
      if (cols.empty()) continue;
      Eigen::MatrixXi C(q.codes.rows(), static_cast<Eigen::Index>(cols.size()));
      for (size_t j = 0; j < cols.size(); ++j) C.col(static_cast<Eigen::Index>(j)) = q.codes.col(cols[j]);
      z.put_small_int(key + (b == 8 ? "_codes" : "_codes16"), C, b / 8);
    }
  } else {
    z.put_bytes(key + "_packed", pack_codes(q.codes, bits));
  }
  z.put(key + "_column_bits", bits);
  z.put_float32(key + "_scales", q.scales);
  z.put_int(key + "_block_rows", q.block_rows);
  z.put(key + "_column_norms", q.column_norms);
}

// The width of an array as read ('|i1', '<i2') or, for an archive made in memory, as it will be written.
std::string dtype_of(const Npz& z, const std::string& name) {
  if (!z.has(name)) return "missing";
  const NpyArray& a = z.arrays().at(name);
  return !a.dtype.empty()           ? a.dtype
         : a.is_float               ? "<f8"
         : a.store_uint8            ? "|u1"
         : a.store_int_bytes == 1   ? "|i1"
         : a.store_int_bytes == 2   ? "<i2"
                                    : "<i4";
}

// Format 3: the 8-bit and the 16-bit columns in two arrays, in column order.
Eigen::MatrixXi get_byte_codes(const Npz& z, const std::string& key, const std::string& what,
                               const Eigen::VectorXi& bits) {
  for (Eigen::Index k = 0; k < bits.size(); ++k)
    if (bits(k) != 8 && bits(k) != 16)
      throw InputError(fmt::format("{}: '{}_column_bits' element {} is {} bits and there is no '{}_packed' "
                                   "(only 8 and 16 bits are stored unpacked)",
                                   what, key, k, bits(k), key));
  Eigen::MatrixXi parts[2];
  Eigen::Index rows = -1, used[2] = {0, 0};
  for (int p = 0; p < 2; ++p) {
    const std::string name = key + (p == 0 ? "_codes" : "_codes16");
    const Eigen::Index want = (bits.array() == (p == 0 ? 8 : 16)).count();
    if (want == 0) continue;
    const std::string dtype = dtype_of(z, name);
    if (dtype != (p == 0 ? "|i1" : "<i2"))
      throw InputError(fmt::format("{}: '{}' is '{}', expected {} ({} columns of '{}_column_bits' say {} bits)", what,
                                   name, dtype, p == 0 ? "int8 ('|i1')" : "int16 ('<i2')",
                                   want, key, p == 0 ? 8 : 16));
    parts[p] = z.int_matrix(name);
    if (parts[p].cols() != want || (rows >= 0 && parts[p].rows() != rows))
      throw InputError(fmt::format("{}: '{}' is {}×{}, expected {} columns ('{}_column_bits') and the other codes' rows",
                                   what, name, parts[p].rows(), parts[p].cols(), want, key));
    rows = parts[p].rows();
  }
  Eigen::MatrixXi codes(std::max<Eigen::Index>(rows, 0), bits.size());
  for (Eigen::Index k = 0; k < bits.size(); ++k) {
    const int p = bits(k) == 8 ? 0 : 1;
    if (bits(k) == 8 || bits(k) == 16) codes.col(k) = parts[p].col(used[p]++);
  }
  return codes;
}

// A basis stored either way; quantised ones are checked (model/quantise.h) before decoding. D:
// the template's encoding size (the rows of a packed basis).
Eigen::MatrixXd get_basis(const Npz& z, const std::string& key, const std::string& what, int D) {
  if (!z.has(key + "_column_bits")) return z.matrix(key);
  QuantisedBasis q;
  q.bits = z.int_vector(key + "_column_bits");
  std::string codes_name;
  if (z.has(key + "_packed")) {
    codes_name = key + "_packed";
    if (const std::string dtype = dtype_of(z, codes_name); dtype != "|u1")
      throw InputError(fmt::format("{}: '{}' is '{}', expected uint8 ('|u1') bit-packed codes", what, codes_name, dtype));
    q.codes = unpack_codes(z.arrays().at(codes_name).i64, D, q.bits, what, codes_name);
  } else {
    q.codes = get_byte_codes(z, key, what, q.bits);
  }
  q.scales = z.matrix(key + "_scales");
  const double block_rows = z.scalar(key + "_block_rows");
  q.block_rows = std::isfinite(block_rows) ? static_cast<int>(std::clamp(block_rows, -1.0, 1e9)) : -1;
  q.column_norms = z.vector(key + "_column_norms");
  validate_quantised_basis(q, what, key, codes_name);
  return dequantise_basis(q);
}

void put_sub_model(Npz& z, const std::string& p, const SubModel& m, bool shape, const ModelFileOptions& o,
                   bool store_basis = true) {
  z.put(p + "_mean", m.pca.mean);
  if (store_basis) put_basis(z, p + "_basis", m.pca.basis, o, shape ? o.shape_column_bits : o.full_column_bits);
  z.put(p + "_eigenvalues", m.pca.eigenvalues);
  z.put(p + "_coefficients", m.pca.coefficients);
  std::vector<std::string> names, units, sem;
  Eigen::MatrixXd stats(m.regression.label_count(), 4);
  for (int i = 0; i < m.regression.label_count(); ++i) {
    const LabelInfo& l = m.regression.labels[i];
    names.push_back(l.name);
    units.push_back(l.unit);
    stats.row(i) << l.mean, l.stddev, l.min, l.max;
  }
  const std::string lp = shape ? "" : p + "_";
  z.put(lp + "labels", m.labels);
  z.put_text(lp + "label_names", json_list(names));
  z.put_text(lp + "label_units", json_list(units));
  z.put(lp + "label_statistics", stats);
  z.put_text(shape ? "subject_ids" : p + "_sample_ids", json_list(m.sample_ids));
  z.put(p + "_label_offsets", m.regression.offsets);
  z.put(p + "_label_gradients", m.regression.gradients);
  z.put(p + "_semantic_basis", m.semantic_basis.basis);
  z.put(p + "_semantic_variances", m.semantic_basis.variances);
  z.put_text(p + "_semantic_labels", json_list(m.semantic_basis.semantic_labels));
}

SubModel get_sub_model(const Npz& z, const std::string& p, bool shape, int D, const std::string& what) {
  SubModel m;
  m.pca.mean = z.vector(p + "_mean");
  // A full model that is the shape model (one person, or one standard-pose mesh per subject)
  // shares its basis instead of storing it twice.
  const bool shared = !shape && !z.has(p + "_basis") && z.has("full_basis_is_shape_basis") &&
                      z.scalar("full_basis_is_shape_basis") == 1.0;
  m.pca.basis = get_basis(z, shared ? std::string("shape_basis") : p + "_basis", what, D);
  m.pca.eigenvalues = z.vector(p + "_eigenvalues");
  m.pca.coefficients = z.matrix(p + "_coefficients");
  const int K = static_cast<int>(m.pca.basis.cols());
  if (m.pca.mean.size() != D || m.pca.basis.rows() != D || m.pca.eigenvalues.size() != K ||
      m.pca.coefficients.cols() != K)
    throw InputError(fmt::format("{}: the {} model's arrays disagree (mean {}, basis {}×{}, eigenvalues {}, "
                                 "coefficients with {} columns; encoding size {})",
                                 what, p, m.pca.mean.size(), m.pca.basis.rows(), K,
                                 m.pca.eigenvalues.size(), m.pca.coefficients.cols(), D));
  check_finite(m.pca.mean, p + "_mean", what);
  check_finite(m.pca.basis, p + "_basis", what);
  check_finite(m.pca.eigenvalues, p + "_eigenvalues", what);
  // Eigenvalues are variances: a negative one made `generate` draw NaN coefficients and write
  // identical bodies.
  for (Eigen::Index k = 0; k < m.pca.eigenvalues.size(); ++k)
    if (m.pca.eigenvalues(k) < 0)
      throw InputError(fmt::format("{}: '{}_eigenvalues' element {} is {}, expected a variance ≥ 0", what, p, k,
                                   m.pca.eigenvalues(k)));
  check_finite(m.pca.coefficients, p + "_coefficients", what);
  const std::string lp = shape ? "" : p + "_";
  m.labels = z.matrix(lp + "labels");
  auto names = read_list(z, lp + "label_names", what);
  auto units = read_list(z, lp + "label_units", what);
  Eigen::MatrixXd stats = z.matrix(lp + "label_statistics");
  m.sample_ids = read_list(z, shape ? "subject_ids" : p + "_sample_ids", what);
  m.regression.offsets = z.vector(p + "_label_offsets");
  m.regression.gradients = z.matrix(p + "_label_gradients");
  const int L = static_cast<int>(names.size());
  if (static_cast<int>(units.size()) != L || stats.rows() != L || stats.cols() != 4 ||
      m.regression.offsets.size() != L || m.regression.gradients.rows() != K ||
      m.regression.gradients.cols() != L || m.labels.cols() != L ||
      m.labels.rows() != m.pca.coefficients.rows() ||
      static_cast<int>(m.sample_ids.size()) != m.pca.coefficients.rows())
    throw InputError(fmt::format("{}: the {} model's label arrays disagree with its {} labels", what, p, L));
  check_finite(m.labels, lp + "labels", what, /*missing_ok=*/true);
  check_finite(stats, lp + "label_statistics", what);
  check_finite(m.regression.offsets, p + "_label_offsets", what);
  check_finite(m.regression.gradients, p + "_label_gradients", what);
  for (int i = 0; i < L; ++i)
    m.regression.labels.push_back({names[i], units[i], stats(i, 0), stats(i, 1), stats(i, 2), stats(i, 3)});
  m.semantic_basis.basis = z.matrix(p + "_semantic_basis");
  m.semantic_basis.variances = z.vector(p + "_semantic_variances");
  m.semantic_basis.semantic_labels = read_list(z, p + "_semantic_labels", what);
  if (m.semantic_basis.basis.rows() != K || m.semantic_basis.basis.cols() != K)
    throw InputError(fmt::format("{}: {}_semantic_basis must be {}×{}", what, p, K, K));
  if (m.semantic_basis.variances.size() != K)
    throw InputError(fmt::format("{}: {}_semantic_variances has {} values, expected {} (one per component)",
                                 what, p, m.semantic_basis.variances.size(), K));
  check_finite(m.semantic_basis.basis, p + "_semantic_basis", what);
  check_finite(m.semantic_basis.variances, p + "_semantic_variances", what);
  return m;
}

// The rows of each part's triangles (15 encoding values each, triangle order).
std::vector<std::vector<Eigen::Index>> part_rows(const std::vector<int>& triangle_part, int parts) {
  std::vector<std::vector<Eigen::Index>> rows(parts);
  for (size_t f = 0; f < triangle_part.size(); ++f)
    for (int r = 0; r < 15; ++r) rows[triangle_part[f]].push_back(static_cast<Eigen::Index>(15 * f + r));
  return rows;
}

// The part-wise model (body_model.h, PartModel): each part's rows of the mean and of its own
// components only, so the file holds no zeros outside the parts (model_file.h, parts_*). Bases
// are float32 whatever the global bases' storage.
void put_parts(Npz& z, const PartModel& m) {
  const int P = m.part_count();
  const auto rows = part_rows(m.triangle_part, P);
  z.put_int("parts_count", P);
  z.put("parts_triangle_part", Eigen::VectorXi(Eigen::Map<const Eigen::VectorXi>(m.triangle_part.data(),
                                                                                    m.triangle_part.size())));
  z.put("parts_component_part", Eigen::VectorXi(Eigen::Map<const Eigen::VectorXi>(m.component_part.data(),
                                                                                     m.component_part.size())));
  z.put("parts_coefficients", m.pca.coefficients);
  for (int p = 0; p < P; ++p) {
    std::vector<Eigen::Index> cols;
    for (size_t k = 0; k < m.component_part.size(); ++k)
      if (m.component_part[k] == p) cols.push_back(static_cast<Eigen::Index>(k));
    const Eigen::Index R = static_cast<Eigen::Index>(rows[p].size()), C = static_cast<Eigen::Index>(cols.size());
    Eigen::VectorXd mean(R);
    Eigen::MatrixXd basis(R, C);
    Eigen::VectorXd variances(C);
    for (Eigen::Index i = 0; i < R; ++i) {
      mean(i) = m.pca.mean(rows[p][i]);
      for (Eigen::Index j = 0; j < C; ++j) basis(i, j) = m.pca.basis(rows[p][i], cols[j]);
    }
    for (Eigen::Index j = 0; j < C; ++j) variances(j) = m.pca.eigenvalues(cols[j]);
    const std::string k = fmt::format("parts_{}_", p);
    z.put(k + "mean", mean);
    z.put_float32(k + "basis", basis);
    z.put(k + "eigenvalues", variances);
  }
}

// One index array of the part-wise model: `size` entries in [0, bound); InputError naming the key.
std::vector<int> get_part_indices(const Npz& z, const std::string& key, const std::string& what, Eigen::Index size,
                                  int bound, const std::string& expected) {
  const Eigen::VectorXi v = z.int_vector(key);
  if (v.size() != size)
    throw InputError(fmt::format("{}: '{}' has {} entries, expected {} ({})", what, key, v.size(), size, expected));
  for (Eigen::Index i = 0; i < v.size(); ++i)
    if (v(i) < 0 || v(i) >= bound)
      throw InputError(fmt::format("{}: '{}' element {} is {}, expected a part index 0..{} ('parts_count' {})", what,
                                   key, i, v(i), bound - 1, bound));
  return std::vector<int>(v.data(), v.data() + v.size());
}

// The part-wise model assembled into one Pca (zero outside each component's part), checked
// against the template (#F triangles, D = 15·#F) and the full model's N training samples.
PartModel get_parts(const Npz& z, const std::string& what, int nf, Eigen::Index N) {
  PartModel m;
  const double count = z.scalar("parts_count");
  if (!(count >= 1 && count <= nf) || count != std::floor(count))
    throw InputError(fmt::format("{}: 'parts_count' is {}, expected 1..{} (the template's triangles)", what, count, nf));
  const int P = static_cast<int>(count);
  m.triangle_part = get_part_indices(z, "parts_triangle_part", what, nf, P, "one per template triangle");
  m.pca.coefficients = z.matrix("parts_coefficients");
  const Eigen::Index K = m.pca.coefficients.cols();
  if (m.pca.coefficients.rows() != N)
    throw InputError(fmt::format("{}: 'parts_coefficients' has {} rows, the full model {} training samples", what,
                                 m.pca.coefficients.rows(), N));
  check_finite(m.pca.coefficients, "parts_coefficients", what);
  m.component_part = get_part_indices(z, "parts_component_part", what, K, P, "one per column of 'parts_coefficients'");
  const auto rows = part_rows(m.triangle_part, P);
  const Eigen::Index D = 15 * static_cast<Eigen::Index>(nf);
  m.pca.mean = Eigen::VectorXd::Zero(D);
  m.pca.basis = Eigen::MatrixXd::Zero(D, K);
  m.pca.eigenvalues = Eigen::VectorXd::Zero(K);
  for (int p = 0; p < P; ++p) {
    std::vector<Eigen::Index> cols;
    for (Eigen::Index k = 0; k < K; ++k)
      if (m.component_part[k] == p) cols.push_back(k);
    const std::string k = fmt::format("parts_{}_", p);
    const Eigen::VectorXd mean = z.vector(k + "mean"), variances = z.vector(k + "eigenvalues");
    const Eigen::MatrixXd basis = z.matrix(k + "basis");
    const Eigen::Index R = static_cast<Eigen::Index>(rows[p].size()), C = static_cast<Eigen::Index>(cols.size());
    // A label array that moved triangles between parts no longer matches the parts' row counts.
    if (mean.size() != R || basis.rows() != R || basis.cols() != C || variances.size() != C)
      throw InputError(fmt::format("{}: part {} has {} triangles in 'parts_triangle_part' and {} components in "
                                   "'parts_component_part', but '{}mean' has {} values, '{}basis' is {}×{} and "
                                   "'{}eigenvalues' has {} (expected {} rows, {} columns)",
                                   what, p, R / 15, C, k, mean.size(), k, basis.rows(), basis.cols(), k,
                                   variances.size(), R, C));
    check_finite(mean, k + "mean", what);
    check_finite(basis, k + "basis", what);
    check_finite(variances, k + "eigenvalues", what);
    for (Eigen::Index j = 0; j < C; ++j) {
      if (variances(j) < 0)
        throw InputError(fmt::format("{}: '{}eigenvalues' element {} is {}, expected a variance ≥ 0", what, k, j,
                                     variances(j)));
      m.pca.eigenvalues(cols[j]) = variances(j);
    }
    for (Eigen::Index i = 0; i < R; ++i) {
      m.pca.mean(rows[p][i]) = mean(i);
      for (Eigen::Index j = 0; j < C; ++j) m.pca.basis(rows[p][i], cols[j]) = basis(i, j);
    }
  }
  return m;
}

}  // namespace

namespace {
// Paths recorded in the metadata (metadata["source"]: the folders a model was built from) keep
// only their last component, and so does any other absolute path: a model file must not carry
// the folders of the machine that built it.
void make_portable(nlohmann::json& j, bool in_source) {
  if (j.is_string()) {
    const std::string s = j.get<std::string>();
    if (in_source || (s.size() > 1 && s[0] == '/')) j = path_label(s);
  } else if (j.is_object()) {
    for (auto& [key, value] : j.items()) make_portable(value, in_source || key == "source");
  } else if (j.is_array()) {
    for (auto& value : j) make_portable(value, in_source);
  }
}
nlohmann::json portable_metadata(nlohmann::json meta) {
  make_portable(meta, false);
  return meta;
}
}  // namespace

void ModelFileOptions::validate() const {
  if ((basis_bits < kMinBasisBits || basis_bits > kMaxBasisBits) && basis_bits != 32)
    throw InputError(fmt::format("model file: basis bits must be {} to {}, or 32 (float32), got {}", kMinBasisBits,
                                 kMaxBasisBits, basis_bits));
  if (block_rows < 1) throw InputError(fmt::format("model file: quantisation block rows must be ≥ 1, got {}", block_rows));
  for (const Eigen::VectorXi* bits : {&shape_column_bits, &full_column_bits})
    for (Eigen::Index k = 0; k < bits->size(); ++k)
      if ((*bits)(k) < kMinBasisBits || (*bits)(k) > kMaxBasisBits)
        throw InputError(fmt::format("model file: column bits must be {} to {}, got {}", kMinBasisBits, kMaxBasisBits,
                                     (*bits)(k)));
}

// The bits histogram of a basis ("8": 12, ...) for the metadata.
nlohmann::json bits_histogram(const Eigen::VectorXi& bits) {
  nlohmann::json h = nlohmann::json::object();
  for (int b = kMinBasisBits; b <= kMaxBasisBits; ++b)
    if (const auto n = (bits.array() == b).count(); n > 0) h[std::to_string(b)] = n;
  return h;
}

Npz model_to_npz(const BodyModel& model, const ModelFileOptions& o) {
  o.validate();
  Npz z;
  // Quantised files are version 3 (4 when bit-packed); float32 ones stay 2 so older programs still read them.
  const Eigen::VectorXi shape_bits = column_bits_of(o, o.shape_column_bits, model.shape.component_count());
  const Eigen::VectorXi full_bits = column_bits_of(o, o.full_column_bits, model.full.component_count());
  const int version = o.basis_bits == 32 ? kModelFormatVersion
                      : byte_aligned(shape_bits) && byte_aligned(full_bits) ? kQuantisedModelFormatVersion
                                                                            : kPackedModelFormatVersion;
  nlohmann::json meta = portable_metadata(model.metadata);
  if (meta.is_object()) {
    meta["format_version"] = version;
    meta["basis_storage"] = o.basis_bits == 32 ? nlohmann::json("float32")
                                               : nlohmann::json({{"bits", o.basis_bits},
                                                                 {"block_rows", o.block_rows},
                                                                 {"shape_16_bit_columns", (shape_bits.array() == 16).count()},
                                                                 {"full_16_bit_columns", (full_bits.array() == 16).count()},
                                                                 {"shape_column_bits", bits_histogram(shape_bits)},
                                                                 {"full_column_bits", bits_histogram(full_bits)}});
  }
  z.put_text("metadata", json_text(meta));
  z.put_int("format_version", version);
  z.put("template_vertices", Eigen::MatrixXd(model.tmpl->rest_vertices()));
  z.put("template_faces", Eigen::MatrixXi(model.tmpl->faces()));
  z.put("encoding_mean", model.mean->values);
  put_sub_model(z, "shape", model.shape, true, o);
  // The basis is most of the file: when the full model's is the shape model's (one person in
  // many poses, or a population of one standard-pose mesh per person) it is stored once.
  const bool shared = model.full.pca.basis.rows() == model.shape.pca.basis.rows() &&
                      model.full.pca.basis.cols() == model.shape.pca.basis.cols() &&
                      model.full.pca.basis == model.shape.pca.basis;
  put_sub_model(z, "full", model.full, false, o, !shared);
  if (shared) z.put("full_basis_is_shape_basis", 1.0);
  if (!model.rig.empty()) {
    z.put_text("rig_bone_names", json_list(model.rig.bone_names));
    z.put("rig_parents", Eigen::VectorXi(Eigen::Map<const Eigen::VectorXi>(
                             model.rig.parents.data(), model.rig.parents.size())));
    put_sparse(z, "rig_head_regressor", model.rig.head_regressor);
    put_sparse(z, "rig_tail_regressor", model.rig.tail_regressor);
    put_sparse(z, "rig_weights", model.rig.weights);
  }
  if (!model.parts.empty()) put_parts(z, model.parts);
  return z;
}

BodyModel model_from_npz(const Npz& z, const std::string& what) {
  if (!z.has("metadata") || !z.has("format_version"))
    throw InputError(fmt::format("{}: not a bodymodel model file (no 'metadata'/'format_version' "
                                 "entries; it has: {})",
                                 what, [&] {
                                   std::string s;
                                   for (auto& k : z.keys()) s += (s.empty() ? "" : ", ") + k;
                                   return s.empty() ? std::string("nothing") : s;
                                 }()));
  BodyModel model;
  try {
    model.metadata = nlohmann::json::parse(z.text("metadata"));
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("{}: 'metadata' is not valid JSON ({})", what, e.what()));
  }
  if (model.metadata.value("format", std::string()) != "bodymodel-model")
    throw InputError(fmt::format("{}: metadata says format '{}', expected 'bodymodel-model'", what,
                                 model.metadata.value("format", std::string("(none)"))));
  double version = z.scalar("format_version");
  // Version 1 (all float64) has the same keys as version 2 (bases float32): both are read, and
  // version 3 (quantised bases, each with its codes, scales and column norms) and 4 (bit-packed codes).
  if (version != kModelFormatVersion && version != 1 && version != kQuantisedModelFormatVersion &&
      version != kPackedModelFormatVersion)
    throw InputError(fmt::format("{}: model format version {}, this program reads versions 1 to {} "
                                 "(rebuild the model with `bodymodel build`)",
                                 what, version, kPackedModelFormatVersion));
  Eigen::MatrixXd V = z.matrix("template_vertices");
  Eigen::MatrixXi F = z.int_matrix("template_faces");
  if (V.cols() != 3 || F.cols() != 3)
    throw InputError(fmt::format("{}: template_vertices/template_faces must have 3 columns", what));
  if (V.rows() == 0 || F.rows() == 0)
    throw InputError(fmt::format("{}: the template has {} vertices and {} faces, expected at least one of each",
                                 what, V.rows(), F.rows()));
  check_finite(V, "template_vertices", what);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (F(f, k) < 0 || F(f, k) >= V.rows())
        throw InputError(fmt::format("{}: 'template_faces' row {} names vertex {}, expected 0..{} "
                                     "('template_vertices' has {} rows)",
                                     what, f, F(f, k), V.rows() - 1, V.rows()));
  try {
    model.tmpl = std::make_shared<EncodingTemplate>(Eigen::MatrixX3d(V), Eigen::MatrixX3i(F));
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: 'template_vertices'/'template_faces': {}", what, e.what()));
  }
  const int D = model.tmpl->encoding_size();
  Eigen::VectorXd mean = z.vector("encoding_mean");
  if (mean.size() != D)
    throw InputError(fmt::format("{}: encoding_mean has {} values, the template needs {}", what, mean.size(), D));
  check_finite(mean, "encoding_mean", what);
  model.mean = EncodingMean::from_values(std::move(mean));
  model.shape = get_sub_model(z, "shape", true, D, what);
  model.full = get_sub_model(z, "full", false, D, what);
  if (z.has("rig_bone_names")) {
    model.rig.bone_names = read_list(z, "rig_bone_names", what);
    const int B = model.rig.bone_count(), nv = static_cast<int>(V.rows());
    Eigen::VectorXi par = z.int_vector("rig_parents");
    if (par.size() != B)
      throw InputError(fmt::format("{}: 'rig_parents' has {} entries, 'rig_bone_names' {} bones", what,
                                   par.size(), B));
    // Parents come before their children (the order forward kinematics walks): no cycles.
    for (int b = 0; b < B; ++b)
      if (par(b) < -1 || par(b) >= b)
        throw InputError(fmt::format("{}: 'rig_parents' gives bone {} ('{}') the parent {}, expected -1 "
                                     "(a root) or a bone index below {}",
                                     what, b, model.rig.bone_names[b], par(b), b));
    model.rig.parents.assign(par.data(), par.data() + par.size());
    model.rig.head_regressor = get_sparse(z, "rig_head_regressor", what, B, nv);
    model.rig.tail_regressor = get_sparse(z, "rig_tail_regressor", what, B, nv);
    model.rig.weights = get_sparse(z, "rig_weights", what, nv, B);
  }
  if (z.has("parts_triangle_part"))
    model.parts = get_parts(z, what, static_cast<int>(F.rows()), model.full.pca.coefficients.rows());
  return model;
}

void save_model(const std::filesystem::path& path, const BodyModel& model, const ModelFileOptions& options) {
  model_to_npz(model, options).save(path);  // deflated (core/io/npz.h)
}

BodyModel load_model(const std::filesystem::path& path, PartModelUse parts) {
  Npz z = Npz::load(path);
  // Checked before reading: the part-wise model is assembled densely in memory.
  if (parts == PartModelUse::refuse && z.has("parts_triangle_part"))
    throw InputError(fmt::format("'{}' holds a part-wise pose model (`build --parts`, key 'parts_triangle_part'): "
                                 "only `fit` and `eval-model` use it; build the model without --parts for this",
                                 path.string()));
  try {
    return model_from_npz(z, "'" + path.string() + "'");
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(fmt::format("'{}': not a readable model file ({})", path.string(), e.what()));
  }
}

}  // namespace bodymodel
