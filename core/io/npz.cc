#include "core/io/npz.h"

#include <tbb/parallel_for.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
#include <vector>
#include <regex>

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {

int64_t NpyArray::size() const {
  int64_t n = 1;
  for (auto s : shape) n *= s;
  return n;
}

// ---- adders ------------------------------------------------------------------------------------

void Npz::put(const std::string& name, const Eigen::MatrixXd& m) {
  NpyArray a;
  a.shape = {m.rows(), m.cols()};
  a.f64.resize(m.size());
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      a.f64.data(), m.rows(), m.cols()) = m;
  arrays_[name] = std::move(a);
}
void Npz::put_float32(const std::string& name, const Eigen::MatrixXd& m) {
  put(name, m);
  arrays_[name].store_float32 = true;
}
void Npz::put_small_int(const std::string& name, const Eigen::MatrixXi& m, int bytes) {
  if (bytes != 1 && bytes != 2) throw InputError("npz: small integers are 1 or 2 bytes, got " + std::to_string(bytes));
  const int limit = bytes == 1 ? 127 : 32767;
  if (m.size() > 0 && (m.maxCoeff() > limit || m.minCoeff() < -limit - 1))
    throw InputError("npz: array '" + name + "' holds values outside int" + std::to_string(8 * bytes));
  put(name, m);
  arrays_[name].store_int_bytes = bytes;
}
void Npz::put_bytes(const std::string& name, const std::vector<uint8_t>& bytes) {
  NpyArray a;
  a.is_float = false;
  a.shape = {static_cast<int64_t>(bytes.size())};
  a.i64.assign(bytes.begin(), bytes.end());
  a.store_uint8 = true;
  arrays_[name] = std::move(a);
}
void Npz::put(const std::string& name, const Eigen::VectorXd& v) {
  NpyArray a;
  a.shape = {v.size()};
  a.f64.assign(v.data(), v.data() + v.size());
  arrays_[name] = std::move(a);
}
void Npz::put(const std::string& name, const Eigen::MatrixXi& m) {
  NpyArray a;
  a.is_float = false;
  a.shape = {m.rows(), m.cols()};
  a.i64.resize(m.size());
  for (Eigen::Index r = 0; r < m.rows(); ++r)
    for (Eigen::Index c = 0; c < m.cols(); ++c) a.i64[r * m.cols() + c] = m(r, c);
  arrays_[name] = std::move(a);
}
void Npz::put(const std::string& name, const Eigen::VectorXi& v) {
  NpyArray a;
  a.is_float = false;
  a.shape = {v.size()};
  a.i64.assign(v.data(), v.data() + v.size());
  arrays_[name] = std::move(a);
}
void Npz::put(const std::string& name, double scalar) {
  NpyArray a;
  a.f64 = {scalar};
  arrays_[name] = std::move(a);
}
void Npz::put_int(const std::string& name, int scalar) {
  NpyArray a;
  a.is_float = false;
  a.i64 = {scalar};
  arrays_[name] = std::move(a);
}
void Npz::put_text(const std::string& name, const std::string& text) {
  NpyArray a;
  a.is_float = false;
  a.text = text;
  a.shape = {};
  arrays_[name] = std::move(a);
}

// ---- accessors ---------------------------------------------------------------------------------

bool Npz::has(const std::string& name) const { return arrays_.count(name) > 0; }

namespace {
const NpyArray& get(const std::map<std::string, NpyArray>& arrays, const std::string& name,
                    const std::string& source) {
  auto it = arrays.find(name);
  if (it == arrays.end())
    throw InputError("'" + source + "': missing array '" + name + "' (not a file of this kind?)");
  return it->second;
}
double value(const NpyArray& a, int64_t i) {
  return a.is_float ? a.f64[i] : static_cast<double>(a.i64[i]);
}
}  // namespace

Eigen::MatrixXd Npz::matrix(const std::string& name) const {
  const NpyArray& a = get(arrays_, name, source_);
  if (a.shape.size() > 2 || !a.text.empty())
    throw InputError("'" + source_ + "': array '" + name + "' is not a 1-D or 2-D numeric array");
  int64_t rows = a.shape.empty() ? 1 : a.shape[0];
  int64_t cols = a.shape.size() == 2 ? a.shape[1] : 1;
  Eigen::MatrixXd m(rows, cols);
  for (int64_t r = 0; r < rows; ++r)
    for (int64_t c = 0; c < cols; ++c) m(r, c) = value(a, r * cols + c);
  return m;
}
Eigen::VectorXd Npz::vector(const std::string& name) const {
  const NpyArray& a = get(arrays_, name, source_);
  if (!a.text.empty()) throw InputError("'" + source_ + "': array '" + name + "' is text");
  Eigen::VectorXd v(a.size());
  for (int64_t i = 0; i < a.size(); ++i) v(i) = value(a, i);
  return v;
}
namespace {
// Rounds to int; a NaN, infinite or out-of-int32 value is an InputError naming the array and
// element (converting it would be undefined behaviour).
Eigen::MatrixXi to_int(const Eigen::MatrixXd& m, const std::string& source, const std::string& name) {
  for (Eigen::Index c = 0; c < m.cols(); ++c)
    for (Eigen::Index r = 0; r < m.rows(); ++r) {
      const double x = std::round(m(r, c));
      if (!(x >= -2147483648.0 && x <= 2147483647.0))
        throw InputError("'" + source + "': array '" + name + "' element " +
                         (m.cols() > 1 ? "(" + std::to_string(r) + ", " + std::to_string(c) + ")"
                                       : std::to_string(r)) +
                         " is " + std::to_string(m(r, c)) + ", expected an integer in the int32 range");
    }
  return m.array().round().cast<int>();
}
}  // namespace

Eigen::MatrixXi Npz::int_matrix(const std::string& name) const {
  return to_int(matrix(name), source_, name);
}
Eigen::VectorXi Npz::int_vector(const std::string& name) const {
  return to_int(vector(name), source_, name);
}
double Npz::scalar(const std::string& name) const {
  const NpyArray& a = get(arrays_, name, source_);
  if (a.size() != 1 || !a.text.empty())
    throw InputError("'" + source_ + "': array '" + name + "' is not a scalar");
  return value(a, 0);
}
std::string Npz::text(const std::string& name) const {
  const NpyArray& a = get(arrays_, name, source_);
  if (a.text.empty() && a.size() != 0 && (a.is_float || !a.i64.empty()))
    throw InputError("'" + source_ + "': array '" + name + "' is not text");
  return a.text;
}
std::vector<std::string> Npz::keys() const {
  std::vector<std::string> k;
  for (auto& [name, a] : arrays_) k.push_back(name);
  return k;
}

// ---- NPY encoding ------------------------------------------------------------------------------

namespace {

void append_u16(std::string& s, uint16_t v) { s.append(reinterpret_cast<char*>(&v), 2); }
void append_u32(std::string& s, uint32_t v) { s.append(reinterpret_cast<char*>(&v), 4); }

std::string utf8_to_utf32le(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size();) {
    unsigned char c = s[i];
    uint32_t cp;
    int n;
    if (c < 0x80) { cp = c; n = 1; }
    else if ((c >> 5) == 6) { cp = c & 0x1f; n = 2; }
    else if ((c >> 4) == 14) { cp = c & 0x0f; n = 3; }
    else { cp = c & 0x07; n = 4; }
    for (int k = 1; k < n && i + k < s.size(); ++k) cp = (cp << 6) | (s[i + k] & 0x3f);
    i += n;
    append_u32(out, cp);
  }
  return out;
}

std::string utf32le_to_utf8(const char* p, size_t chars) {
  std::string out;
  for (size_t i = 0; i < chars; ++i) {
    uint32_t cp;
    std::memcpy(&cp, p + 4 * i, 4);
    if (cp == 0) break;
    if (cp < 0x80) out.push_back(static_cast<char>(cp));
    else if (cp < 0x800) { out.push_back(char(0xc0 | (cp >> 6))); out.push_back(char(0x80 | (cp & 0x3f))); }
    else if (cp < 0x10000) { out.push_back(char(0xe0 | (cp >> 12))); out.push_back(char(0x80 | ((cp >> 6) & 0x3f))); out.push_back(char(0x80 | (cp & 0x3f))); }
    else { out.push_back(char(0xf0 | (cp >> 18))); out.push_back(char(0x80 | ((cp >> 12) & 0x3f))); out.push_back(char(0x80 | ((cp >> 6) & 0x3f))); out.push_back(char(0x80 | (cp & 0x3f))); }
  }
  return out;
}

std::string npy_bytes(const NpyArray& a) {
  std::string descr, payload;
  std::string shape = "(";
  if (!a.text.empty() || (!a.is_float && a.i64.empty() && a.shape.empty())) {
    std::string u = utf8_to_utf32le(a.text);
    size_t chars = std::max<size_t>(1, u.size() / 4);
    descr = "<U" + std::to_string(chars);
    payload = u;
    payload.resize(chars * 4, '\0');
  } else if (a.is_float && a.store_float32) {
    descr = "<f4";
    std::vector<float> f(a.f64.begin(), a.f64.end());
    payload.assign(reinterpret_cast<const char*>(f.data()), f.size() * 4);
  } else if (a.is_float) {
    descr = "<f8";
    payload.assign(reinterpret_cast<const char*>(a.f64.data()), a.f64.size() * 8);
  } else if (a.store_uint8) {
    descr = "|u1";
    payload.resize(a.i64.size());
    for (size_t i = 0; i < a.i64.size(); ++i) payload[i] = static_cast<char>(static_cast<uint8_t>(a.i64[i]));
  } else if (a.store_int_bytes == 1) {
    descr = "|i1";
    payload.resize(a.i64.size());
    for (size_t i = 0; i < a.i64.size(); ++i) payload[i] = static_cast<char>(static_cast<int8_t>(a.i64[i]));
  } else if (a.store_int_bytes == 2) {
    descr = "<i2";
    payload.resize(a.i64.size() * 2);
    for (size_t i = 0; i < a.i64.size(); ++i) {
      const int16_t v = static_cast<int16_t>(a.i64[i]);
      std::memcpy(payload.data() + 2 * i, &v, 2);
    }
  } else if (a.store_int64) {
    descr = "<i8";
    payload.assign(reinterpret_cast<const char*>(a.i64.data()), a.i64.size() * 8);
  } else {
    // int32, as documented for every integer array (faces, influences, parents, counts).
    descr = "<i4";
    payload.resize(a.i64.size() * 4);
    for (size_t i = 0; i < a.i64.size(); ++i) {
      if (a.i64[i] < INT32_MIN || a.i64[i] > INT32_MAX)
        throw InputError("npz: integer " + std::to_string(a.i64[i]) + " does not fit int32");
      const int32_t v = static_cast<int32_t>(a.i64[i]);
      std::memcpy(payload.data() + 4 * i, &v, 4);
    }
  }
  if (a.text.empty())
    for (size_t i = 0; i < a.shape.size(); ++i)
      shape += std::to_string(a.shape[i]) + (a.shape.size() == 1 ? "," : (i + 1 < a.shape.size() ? ", " : ""));
  shape += ")";
  std::string header = "{'descr': '" + descr + "', 'fortran_order': False, 'shape': " + shape + ", }";
  size_t total = 10 + header.size() + 1;
  header.append((64 - total % 64) % 64, ' ');
  header.push_back('\n');
  std::string out = "\x93NUMPY";
  out.push_back(1);
  out.push_back(0);
  append_u16(out, static_cast<uint16_t>(header.size()));
  out += header;
  out += payload;
  return out;
}

NpyArray parse_npy(const std::string& b, const std::string& what) {
  auto bad = [&](const std::string& why) { return InputError("'" + what + "': " + why); };
  if (b.size() < 10 || b.compare(0, 6, "\x93NUMPY") != 0) throw bad("not a .npy array");
  int major = static_cast<unsigned char>(b[6]);
  size_t hlen, hstart;
  if (major == 1) {
    uint16_t l;
    std::memcpy(&l, b.data() + 8, 2);
    hlen = l;
    hstart = 10;
  } else {
    if (b.size() < 12) throw bad("truncated .npy header");
    uint32_t l;
    std::memcpy(&l, b.data() + 8, 4);
    hlen = l;
    hstart = 12;
  }
  if (hstart + hlen > b.size()) throw bad("truncated .npy header");
  std::string header = b.substr(hstart, hlen);
  std::smatch m;
  if (!std::regex_search(header, m, std::regex("'descr':\\s*'([^']*)'")))
    throw bad("npy header has no descr");
  std::string descr = m[1];
  if (std::regex_search(header, m, std::regex("'fortran_order':\\s*True")))
    throw bad("Fortran-ordered arrays are not supported");
  if (!std::regex_search(header, m, std::regex("'shape':\\s*\\(([^)]*)\\)")))
    throw bad("npy header has no shape");
  NpyArray a;
  std::string dims = m[1];
  std::regex num("\\d+");
  for (auto it = std::sregex_iterator(dims.begin(), dims.end(), num); it != std::sregex_iterator(); ++it) {
    long long d = std::stoll(it->str());
    if (d < 0 || d > (1LL << 40)) throw bad("implausible array shape");
    a.shape.push_back(d);
  }
  int64_t n = a.size();
  const char* data = b.data() + hstart + hlen;
  size_t avail = b.size() - hstart - hlen;
  if (descr.size() < 3) throw bad("unsupported dtype '" + descr + "'");
  a.dtype = descr;
  char order = descr[0];
  char kind = descr[1];
  size_t width = static_cast<size_t>(std::atoi(descr.c_str() + 2));
  if (order == '>') throw bad("big-endian arrays are not supported");
  if (kind == 'U') {
    if (avail < width * 4 * n) throw bad("array data truncated");
    a.is_float = false;
    a.text = utf32le_to_utf8(data, width * std::max<int64_t>(n, 1));
    return a;
  }
  if (kind == 'S') {
    a.is_float = false;
    a.text = std::string(data, std::min(avail, width));
    a.text = a.text.substr(0, a.text.find('\0'));
    return a;
  }
  if (width == 0 || avail < width * static_cast<size_t>(n)) throw bad("array data truncated");
  if (kind == 'f') {
    a.f64.resize(n);
    a.store_float32 = width == 4;
    for (int64_t i = 0; i < n; ++i) {
      if (width == 8) { double v; std::memcpy(&v, data + 8 * i, 8); a.f64[i] = v; }
      else if (width == 4) { float v; std::memcpy(&v, data + 4 * i, 4); a.f64[i] = v; }
      else throw bad("unsupported float width in '" + descr + "'");
    }
  } else if (kind == 'i' || kind == 'u' || kind == 'b') {
    a.is_float = false;
    if (kind == 'i' && (width == 1 || width == 2)) a.store_int_bytes = static_cast<int>(width);  // saved as it came
    a.store_uint8 = kind == 'u' && width == 1;
    a.i64.resize(n);
    for (int64_t i = 0; i < n; ++i) {
      const char* p = data + width * i;
      int64_t v = 0;
      if (width == 1) v = kind == 'i' ? int64_t(int8_t(*p)) : int64_t(uint8_t(*p));
      else if (width == 2) { int16_t x; uint16_t y; std::memcpy(&x, p, 2); std::memcpy(&y, p, 2); v = kind == 'i' ? int64_t(x) : int64_t(y); }
      // Each branch widened on its own: `kind == 'i' ? x : y` would convert x to uint32_t, and an
      // int32 -1 (a root's parent) came back as 4294967295.
      else if (width == 4) { int32_t x; uint32_t y; std::memcpy(&x, p, 4); std::memcpy(&y, p, 4); v = kind == 'i' ? int64_t(x) : int64_t(y); }
      else if (width == 8) std::memcpy(&v, p, 8);
      else throw bad("unsupported integer width in '" + descr + "'");
      a.i64[i] = v;
      if (v < INT32_MIN || v > INT32_MAX) a.store_int64 = true;  // saved again as it came
    }
  } else {
    throw bad("unsupported dtype '" + descr + "'");
  }
  return a;
}

}  // namespace

// ---- zip container -----------------------------------------------------------------------------

namespace {

// Raw deflate (zip method 8), level 1. Float arrays get Huffman coding only: on the demo model's
// bases it keeps 7.4 % of the 8.3 % that string matching saves, at 40 % of the time (2 s instead
// of 5.5 s for 107 MB); faces, indices and text keep string matching, which shrinks them most.
std::string deflated(const std::string& data, bool floats) {
  z_stream s{};
  if (deflateInit2(&s, 1, Z_DEFLATED, -MAX_WBITS, 8, floats ? Z_HUFFMAN_ONLY : Z_DEFAULT_STRATEGY) != Z_OK)
    throw std::runtime_error("npz: zlib deflateInit2 failed");
  std::string out(deflateBound(&s, static_cast<uLong>(data.size())), '\0');
  s.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  s.avail_in = static_cast<uInt>(data.size());
  s.next_out = reinterpret_cast<Bytef*>(out.data());
  s.avail_out = static_cast<uInt>(out.size());
  const int r = deflate(&s, Z_FINISH);
  const uLong n = s.total_out;
  deflateEnd(&s);
  if (r != Z_STREAM_END) throw std::runtime_error("npz: zlib deflate failed");
  out.resize(n);
  return out;
}

}  // namespace

std::string Npz::serialize() const {
  std::string out, central;
  uint16_t count = 0;
  for (auto& [name, a] : arrays_) {
    std::string fname = name + ".npy";
    std::string data = npy_bytes(a);
    uint32_t crc = static_cast<uint32_t>(crc32(0L, reinterpret_cast<const Bytef*>(data.data()), data.size()));
    uint32_t offset = static_cast<uint32_t>(out.size());
    if (out.size() + data.size() > 0xFFFFFFF0ull)
      throw InputError("npz: archive larger than 4 GiB is not supported");
    // Deflated as np.savez_compressed does; a member deflate would not shrink is stored.
    std::string packed = deflated(data, a.is_float && a.text.empty());
    const uint16_t method = packed.size() < data.size() ? 8 : 0;
    const std::string& body = method == 8 ? packed : data;
    // local file header
    append_u32(out, 0x04034b50);
    append_u16(out, 20); append_u16(out, 0); append_u16(out, method);  // version, flags, method
    append_u16(out, 0); append_u16(out, 0x21);                          // time, date (1980-01-01)
    append_u32(out, crc);
    append_u32(out, static_cast<uint32_t>(body.size()));
    append_u32(out, static_cast<uint32_t>(data.size()));
    append_u16(out, static_cast<uint16_t>(fname.size())); append_u16(out, 0);
    out += fname;
    out += body;
    // central directory entry
    append_u32(central, 0x02014b50);
    append_u16(central, 20); append_u16(central, 20); append_u16(central, 0); append_u16(central, method);
    append_u16(central, 0); append_u16(central, 0x21);
    append_u32(central, crc);
    append_u32(central, static_cast<uint32_t>(body.size()));
    append_u32(central, static_cast<uint32_t>(data.size()));
    append_u16(central, static_cast<uint16_t>(fname.size()));
    append_u16(central, 0); append_u16(central, 0); append_u16(central, 0); append_u16(central, 0);
    append_u32(central, 0);
    append_u32(central, offset);
    central += fname;
    ++count;
  }
  uint32_t cd_offset = static_cast<uint32_t>(out.size());
  out += central;
  append_u32(out, 0x06054b50);
  append_u16(out, 0); append_u16(out, 0);
  append_u16(out, count); append_u16(out, count);
  append_u32(out, static_cast<uint32_t>(central.size()));
  append_u32(out, cd_offset);
  append_u16(out, 0);
  return out;
}

namespace {

// A member of the archive as its central directory describes it.
struct Member {
  std::string name;
  uint16_t method;
  uint32_t crc;
  size_t data_start;
  uint64_t csize, usize;
};

// The member's bytes (stored or deflated, CRC-checked) parsed as .npy; InputError naming it.
NpyArray read_member(const std::string& z, const Member& m, const std::string& what) {
  auto bad = [&](const std::string& why) {
    return InputError("'" + what + "': member '" + m.name + "' " + why + " (not a valid .npz file?)");
  };
  std::string data;
  if (m.method == 0) {
    data = z.substr(m.data_start, m.csize);
  } else if (m.method == 8) {
    data.resize(m.usize);
    z_stream s{};
    if (inflateInit2(&s, -MAX_WBITS) != Z_OK) throw bad("zlib failure");
    s.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(z.data() + m.data_start));
    s.avail_in = static_cast<uInt>(m.csize);
    s.next_out = reinterpret_cast<Bytef*>(data.data());
    s.avail_out = static_cast<uInt>(m.usize);
    int r = inflate(&s, Z_FINISH);
    inflateEnd(&s);
    if (r != Z_STREAM_END || s.total_out != m.usize) throw bad("does not inflate");
  } else {
    throw bad("uses unsupported compression method " + std::to_string(m.method));
  }
  if (static_cast<uint32_t>(crc32(0L, reinterpret_cast<const Bytef*>(data.data()), data.size())) != m.crc)
    throw bad("fails its CRC check (corrupt file)");
  return parse_npy(data, what + ":" + m.name);
}

}  // namespace

Npz Npz::parse(const std::string& z, const std::string& what) {
  auto bad = [&](const std::string& why) {
    return InputError("'" + what + "': " + why + " (not a valid .npz file?)");
  };
  auto u16 = [&](size_t p) { uint16_t v; if (p + 2 > z.size()) throw bad("truncated"); std::memcpy(&v, z.data() + p, 2); return v; };
  auto u32 = [&](size_t p) { uint32_t v; if (p + 4 > z.size()) throw bad("truncated"); std::memcpy(&v, z.data() + p, 4); return v; };
  if (z.size() < 22) throw bad("file too short for a zip archive");
  // Find the end-of-central-directory record (last 64 KiB).
  size_t eocd = std::string::npos;
  for (size_t p = z.size() - 22 + 1; p-- > 0 && z.size() - p <= 65557;)
    if (u32(p) == 0x06054b50) { eocd = p; break; }
  if (eocd == std::string::npos) throw bad("no zip end-of-central-directory record");
  size_t entries = u16(eocd + 10);
  size_t cd = u32(eocd + 16);
  Npz npz;
  npz.source_ = what;
  std::vector<Member> members;
  size_t p = cd;
  for (size_t e = 0; e < entries; ++e) {
    if (u32(p) != 0x02014b50) throw bad("corrupt central directory");
    uint16_t method = u16(p + 10);
    uint32_t crc = u32(p + 16);
    uint64_t csize = u32(p + 20), usize = u32(p + 24);
    uint16_t nlen = u16(p + 28), xlen = u16(p + 30), clen = u16(p + 32);
    uint64_t local = u32(p + 42);
    if (p + 46 + nlen > z.size()) throw bad("truncated central directory");
    std::string fname = z.substr(p + 46, nlen);
    // zip64 extra field
    size_t x = p + 46 + nlen, xend = x + xlen;
    while (x + 4 <= xend && x + 4 <= z.size()) {
      uint16_t id = u16(x), sz = u16(x + 2);
      if (id == 0x0001) {
        size_t q = x + 4;
        if (usize == 0xFFFFFFFF) { uint64_t v; std::memcpy(&v, z.data() + q, 8); usize = v; q += 8; }
        if (csize == 0xFFFFFFFF) { uint64_t v; std::memcpy(&v, z.data() + q, 8); csize = v; q += 8; }
        if (local == 0xFFFFFFFF) { uint64_t v; std::memcpy(&v, z.data() + q, 8); local = v; }
      }
      x += 4 + sz;
    }
    p = xend + clen;
    if (local + 30 > z.size() || u32(local) != 0x04034b50) throw bad("corrupt local header of '" + fname + "'");
    size_t data_start = local + 30 + u16(local + 26) + u16(local + 28);
    if (data_start + csize > z.size()) throw bad("member '" + fname + "' is truncated");
    if (usize > (1ull << 34)) throw bad("member '" + fname + "' is implausibly large");
    if (method == 8 && usize > 1032 * csize + 1024)  // deflate expands at most 1032:1
      throw bad("member '" + fname + "' claims " + std::to_string(usize) + " bytes from " +
                std::to_string(csize) + " compressed bytes, more than deflate can produce");
    members.push_back(Member{std::move(fname), method, crc, data_start, csize, usize});
  }
  // Inflating, checking and parsing the members is most of a model's loading time: in parallel
  // (each member on its own; the first bad member in file order is the error reported).
  std::vector<NpyArray> arrays(members.size());
  std::vector<std::string> errors(members.size());
  tbb::parallel_for(size_t(0), members.size(), [&](size_t e) {
    try {
      arrays[e] = read_member(z, members[e], what);
    } catch (const InputError& error) {
      errors[e] = error.what();
    }
  });
  for (size_t e = 0; e < members.size(); ++e) {
    if (!errors[e].empty()) throw InputError(errors[e]);
    const std::string& fname = members[e].name;
    std::string key = fname.size() > 4 && fname.substr(fname.size() - 4) == ".npy" ? fname.substr(0, fname.size() - 4) : fname;
    npz.arrays_[key] = std::move(arrays[e]);
  }
  return npz;
}

void Npz::save(const std::filesystem::path& path) const {
  std::string bytes = serialize();
  write_atomically(path, [&](std::ostream& out) { out.write(bytes.data(), bytes.size()); });
}

Npz Npz::load(const std::filesystem::path& path) { return parse(read_text_file(path), path.string()); }

}  // namespace bodymodel
