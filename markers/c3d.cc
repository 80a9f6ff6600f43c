#include "markers/c3d.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <map>
#include <vector>

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {

double dec_float_value(const unsigned char b[4]) {
  // Two little-endian 16-bit words; the first holds sign, an 8-bit exponent biased by 128 and the
  // top 7 bits of a 0.1fff… mantissa (hidden bit worth 1/2).
  const uint32_t w0 = b[0] | (uint32_t(b[1]) << 8), w1 = b[2] | (uint32_t(b[3]) << 8);
  const int sign = (w0 >> 15) & 1, exponent = (w0 >> 7) & 0xFF;
  const uint32_t fraction = ((w0 & 0x7F) << 16) | w1;
  if (exponent == 0) return sign ? std::numeric_limits<double>::quiet_NaN() : 0.0;  // reserved operand
  const double v = std::ldexp(0.5 + fraction / 16777216.0, exponent - 128);
  return sign ? -v : v;
}

void dec_float_bytes(float value, unsigned char b[4]) {
  std::memset(b, 0, 4);
  if (value == 0) return;
  if (!std::isfinite(value)) throw InputError("C3D (DEC): a non-finite value has no DEC float");
  int e = 0;
  const double m = std::frexp(std::abs(double(value)), &e);  // m in [0.5, 1)
  const int exponent = e + 128;
  if (exponent < 1 || exponent > 255) throw InputError("C3D (DEC): value out of the DEC float range");
  const uint32_t fraction = static_cast<uint32_t>(std::llround((m - 0.5) * 16777216.0)) & 0x7FFFFF;
  const uint32_t w0 = (value < 0 ? 0x8000u : 0u) | (uint32_t(exponent) << 7) | (fraction >> 16);
  const uint32_t w1 = fraction & 0xFFFF;
  b[0] = w0 & 0xFF, b[1] = w0 >> 8, b[2] = w1 & 0xFF, b[3] = w1 >> 8;
}

namespace {

constexpr size_t kBlock = 512;

// Bounds-checked reads of the file's bytes in its processor's byte order and float format.
struct Bytes {
  const std::string& b;
  const std::string& source;
  C3dProcessor proc = C3dProcessor::intel;

  [[noreturn]] void fail(const std::string& what) const { throw InputError("C3D '" + source + "': " + what); }
  void need(size_t off, size_t n, const char* what) const {
    if (off > b.size() || n > b.size() - off)
      fail(std::string("truncated (") + what + " at byte " + std::to_string(off) + " of " + std::to_string(b.size()) + ")");
  }
  unsigned char u8(size_t off) const { return static_cast<unsigned char>(b[off]); }
  uint16_t u16(size_t off, const char* what) const {
    need(off, 2, what);
    return proc == C3dProcessor::mips ? uint16_t(u8(off) << 8 | u8(off + 1)) : uint16_t(u8(off) | u8(off + 1) << 8);
  }
  int16_t i16(size_t off, const char* what) const { return static_cast<int16_t>(u16(off, what)); }
  double f32(size_t off, const char* what) const {
    need(off, 4, what);
    unsigned char q[4] = {u8(off), u8(off + 1), u8(off + 2), u8(off + 3)};
    if (proc == C3dProcessor::dec) return dec_float_value(q);
    if (proc == C3dProcessor::mips) std::swap(q[0], q[3]), std::swap(q[1], q[2]);
    const uint32_t u = q[0] | uint32_t(q[1]) << 8 | uint32_t(q[2]) << 16 | uint32_t(q[3]) << 24;
    float f;
    std::memcpy(&f, &u, 4);
    return f;
  }
};

struct Param {
  int group = 0;
  int type = 0;  // -1 char, 1 byte, 2 int16, 4 float
  std::vector<int> dims;
  size_t data = 0, size = 0;
};

std::string upper_trimmed(std::string s) {
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  size_t i = 0;
  while (i < s.size() && s[i] == ' ') ++i;
  s = s.substr(i);
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

// The parameter section: "GROUP:NAME" -> where its data is. Records are followed through their
// offset words; each must stay inside the section.
std::map<std::string, Param> parse_parameters(const Bytes& r, size_t start, size_t end) {
  std::map<int, std::string> groups;
  std::vector<std::pair<std::string, Param>> params;
  size_t pos = start + 4;
  while (pos + 2 <= end) {
    const int len = std::abs(static_cast<int8_t>(r.u8(pos)));
    const int id = static_cast<int8_t>(r.u8(pos + 1));
    if (len == 0) break;
    if (id == 0) r.fail("parameter record at byte " + std::to_string(pos) + " has group id 0");
    if (pos + 2 + len + 2 > end) r.fail("parameter record at byte " + std::to_string(pos) + " runs past the parameter section");
    const std::string name = upper_trimmed(r.b.substr(pos + 2, len));
    const size_t offset_at = pos + 2 + len;
    const int next = r.i16(offset_at, "parameter offset");
    if (id < 0) {
      groups[-id] = name;
    } else {
      Param p;
      p.group = id;
      if (offset_at + 4 > end) r.fail("parameter '" + name + "' runs past the parameter section");
      p.type = static_cast<int8_t>(r.u8(offset_at + 2));
      if (p.type != -1 && p.type != 1 && p.type != 2 && p.type != 4)
        r.fail("parameter '" + name + "' has data type " + std::to_string(p.type) + " (expected -1, 1, 2 or 4)");
      const int ndims = r.u8(offset_at + 3);
      if (ndims > 7) r.fail("parameter '" + name + "' has " + std::to_string(ndims) + " dimensions (at most 7)");
      if (offset_at + 4 + ndims > end) r.fail("parameter '" + name + "' runs past the parameter section");
      uint64_t count = 1;
      for (int k = 0; k < ndims; ++k) {
        p.dims.push_back(r.u8(offset_at + 4 + k));
        count *= uint64_t(p.dims.back());  // at most 255^7: no overflow
      }
      p.data = offset_at + 4 + ndims;
      const uint64_t size = count * uint64_t(std::abs(p.type));
      if (size > end - p.data) r.fail("parameter '" + name + "' holds more data than the parameter section");
      p.size = static_cast<size_t>(size);
      params.emplace_back(name, p);
    }
    if (next <= 0) break;  // 0 marks the last record
    pos = offset_at + static_cast<size_t>(next);
  }
  std::map<std::string, Param> out;
  for (auto& [name, p] : params)
    if (groups.count(p.group)) out.emplace(groups[p.group] + ":" + name, p);
  return out;
}

struct Layout {
  int points = 0, first = 1, frames = 0, analog_per_frame = 0, data_start = 0;
  double scale = -1, rate = 0, mm_per_unit = 1;
  std::vector<std::string> labels;
};

double param_number(const Bytes& r, const Param& p, const std::string& name) {
  if (p.size == 0 || p.type == -1) r.fail("parameter " + name + " is not a number");
  if (p.type == 1) return r.u8(p.data);
  if (p.type == 2) return r.i16(p.data, name.c_str());
  return r.f32(p.data, name.c_str());
}

std::vector<std::string> param_strings(const Bytes& r, const Param& p) {
  std::vector<std::string> out;
  if (p.type != -1) return out;
  const size_t len = p.dims.empty() ? p.size : size_t(p.dims[0]);
  if (len == 0) return out;
  for (size_t k = 0; k + len <= p.size; k += len) {
    std::string s = r.b.substr(p.data + k, len);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
    out.push_back(s);
  }
  return out;
}

// Header words, overridden by the POINT parameters where present (the parameters are the
// authority in the spec; the header is kept for old readers).
Layout read_layout(const Bytes& r, const std::map<std::string, Param>& params) {
  Layout l;
  l.points = r.u16(2, "header");
  l.analog_per_frame = r.u16(4, "header");
  l.first = r.u16(6, "header");
  const int last = r.u16(8, "header");
  l.frames = last >= l.first ? last - l.first + 1 : 0;
  l.scale = r.f32(12, "header");
  l.data_start = r.u16(16, "header");
  l.rate = r.f32(20, "header");
  auto number = [&](const char* key, auto& field) {
    auto it = params.find(key);
    if (it == params.end()) return;
    const double v = param_number(r, it->second, key);
    if (!std::isfinite(v)) r.fail(std::string(key) + " is not finite");
    using T = std::decay_t<decltype(field)>;
    // USED, DATA_START and FRAMES are 16-bit counts that writers store unsigned beyond 32767.
    if constexpr (std::is_integral_v<T>) {
      const double w = v < 0 && it->second.type == 2 ? v + 65536 : v;
      if (w < 0 || w > 1e9) r.fail(std::string(key) + " is out of range (" + std::to_string(v) + ")");
      field = static_cast<T>(w);
    } else {
      field = v;
    }
  };
  number("POINT:USED", l.points);
  number("POINT:SCALE", l.scale);
  number("POINT:RATE", l.rate);
  number("POINT:DATA_START", l.data_start);
  number("POINT:FRAMES", l.frames);
  for (int k = 1; k < 100 && static_cast<int>(l.labels.size()) < l.points; ++k) {
    auto it = params.find(k == 1 ? std::string("POINT:LABELS") : "POINT:LABELS" + std::to_string(k));
    if (it == params.end()) break;
    for (auto& s : param_strings(r, it->second)) l.labels.push_back(s);
  }
  if (auto it = params.find("POINT:UNITS"); it != params.end()) {
    const auto u = param_strings(r, it->second);
    l.mm_per_unit = millimetres_per_unit(u.empty() ? "" : u[0], "C3D '" + r.source + "' POINT:UNITS");
  }
  return l;
}

void check_layout(const Bytes& r, Layout& l) {
  if (!std::isfinite(l.scale) || l.scale == 0) r.fail("POINT:SCALE must be a non-zero number");
  if (!std::isfinite(l.rate) || l.rate <= 0) r.fail("POINT:RATE must be positive, found " + std::to_string(l.rate));
  if (l.data_start < 2) r.fail("DATA_START block " + std::to_string(l.data_start) + " is before the parameter section");
  l.labels.resize(static_cast<size_t>(l.points));
  for (int m = 0; m < l.points; ++m) {
    std::string& s = l.labels[m];
    s.erase(std::remove_if(s.begin(), s.end(), [](char c) { return c == '\t' || c == '\r' || c == '\n' || c == '\0'; }), s.end());
    if (s.empty()) s = "M" + std::to_string(m + 1);  // a point without a label
  }
}

void read_samples(const Bytes& r, const Layout& l, MarkerData& d) {
  const bool floating = l.scale < 0;
  const uint64_t word = floating ? 4 : 2;
  const uint64_t stride = word * (4 * uint64_t(l.points) + uint64_t(l.analog_per_frame));
  const uint64_t start = uint64_t(l.data_start - 1) * kBlock;
  // Checked before any allocation: the frames must be in the file.
  if (start > r.b.size() || (stride > 0 && uint64_t(l.frames) > (r.b.size() - start) / stride))
    r.fail("truncated: " + std::to_string(l.frames) + " frames of " + std::to_string(l.points) + " points from block " +
           std::to_string(l.data_start) + " need " + std::to_string(start + l.frames * stride) + " bytes, the file has " +
           std::to_string(r.b.size()));
  d.xyz.setConstant(l.frames, 3 * l.points, std::numeric_limits<double>::quiet_NaN());
  const double unit = floating ? l.mm_per_unit : l.scale * l.mm_per_unit;
  for (int f = 0; f < l.frames; ++f)
    for (int m = 0; m < l.points; ++m) {
      const size_t at = static_cast<size_t>(start + f * stride + uint64_t(m) * 4 * word);
      double v[4];
      for (int k = 0; k < 4; ++k) v[k] = floating ? r.f32(at + k * word, "sample") : r.i16(at + k * word, "sample");
      if (std::isnan(v[3]) || v[3] < 0) continue;  // residual word negative (-1): missing
      if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2]))
        r.fail("frame " + std::to_string(l.first + f) + " point '" + d.labels[m] + "' has a non-finite coordinate");
      d.set(f, m, Eigen::Vector3d(v[0], v[1], v[2]) * unit);
    }
}

}  // namespace

MarkerData parse_c3d(const std::string& bytes, const std::string& source) {
  Bytes r{bytes, source};
  r.need(0, kBlock, "header");
  if (r.u8(1) != 0x50) r.fail("not a C3D file (byte 2 is " + std::to_string(r.u8(1)) + ", expected 80)");
  const int param_block = r.u8(0);
  if (param_block < 2) r.fail("parameter section at block " + std::to_string(param_block) + " (expected 2 or later)");
  const size_t pstart = size_t(param_block - 1) * kBlock;
  r.need(pstart, 4, "parameter section header");
  const int proc = r.u8(pstart + 3);
  if (proc < 84 || proc > 86) r.fail("unknown processor type " + std::to_string(proc) + " (expected 84, 85 or 86)");
  r.proc = static_cast<C3dProcessor>(proc);
  const size_t nblocks = std::max<size_t>(1, r.u8(pstart + 2));
  r.need(pstart, nblocks * kBlock, "parameter section");
  const auto params = parse_parameters(r, pstart, pstart + nblocks * kBlock);
  Layout l = read_layout(r, params);
  check_layout(r, l);
  if (size_t(l.data_start - 1) * kBlock < pstart + nblocks * kBlock)
    r.fail("DATA_START block " + std::to_string(l.data_start) + " overlaps the parameter section");
  MarkerData d;
  d.labels = l.labels;
  d.rate = l.rate;
  d.first_frame = l.first;
  read_samples(r, l, d);
  return d;
}

MarkerData read_c3d(const std::filesystem::path& path) { return parse_c3d(read_text_file(path), path.string()); }

namespace {

// Little helpers writing in the chosen processor's byte order and float format.
struct Out {
  C3dProcessor proc;
  std::string s;
  void u8(int v) { s.push_back(static_cast<char>(v & 0xFF)); }
  void i16(int v) {
    const uint16_t u = static_cast<uint16_t>(v);
    if (proc == C3dProcessor::mips) u8(u >> 8), u8(u);
    else u8(u), u8(u >> 8);
  }
  void f32(float v) {
    unsigned char q[4];
    if (proc == C3dProcessor::dec) {
      dec_float_bytes(v, q);
    } else {
      uint32_t u;
      std::memcpy(&u, &v, 4);
      for (int k = 0; k < 4; ++k) q[k] = (u >> (8 * k)) & 0xFF;
      if (proc == C3dProcessor::mips) std::swap(q[0], q[3]), std::swap(q[1], q[2]);
    }
    s.append(reinterpret_cast<const char*>(q), 4);
  }
  void pad() { s.resize((s.size() + kBlock - 1) / kBlock * kBlock, '\0'); }
};

// One parameter record (group 1, POINT) with `body` = type, dims and data already encoded.
void parameter(Out& o, const std::string& name, const std::string& body, bool last) {
  o.u8(static_cast<int>(name.size()));
  o.u8(1);
  o.s += name;
  o.i16(last ? 0 : static_cast<int>(2 + body.size() + 1));  // offset word + body + empty description
  o.s += body;
  o.u8(0);
}

std::string parameter_section(const MarkerData& d, C3dProcessor proc, double scale, int data_start) {
  Out o{proc};
  auto number_body = [&](int type, double v) {
    Out b{proc};
    b.u8(type), b.u8(0);
    if (type == 2) b.i16(static_cast<int>(v));
    else b.f32(static_cast<float>(v));
    return b.s;
  };
  std::vector<std::pair<std::string, std::string>> recs = {
      {"USED", number_body(2, d.marker_count())}, {"SCALE", number_body(4, scale)},
      {"RATE", number_body(4, d.rate)},           {"DATA_START", number_body(2, data_start)},
      {"FRAMES", number_body(2, d.frame_count())}};
  for (int k = 0; k * 255 < d.marker_count(); ++k) {  // 255 labels per parameter (1-byte dimensions)
    const int n = std::min(255, d.marker_count() - k * 255);
    size_t len = 1;
    for (int m = 0; m < n; ++m) len = std::max(len, d.labels[k * 255 + m].size());
    if (len > 255) throw InputError("C3D: a label longer than 255 characters");
    Out b{proc};
    b.u8(-1), b.u8(2), b.u8(static_cast<int>(len)), b.u8(n);
    for (int m = 0; m < n; ++m) b.s += d.labels[k * 255 + m] + std::string(len - d.labels[k * 255 + m].size(), ' ');
    recs.emplace_back(k == 0 ? "LABELS" : "LABELS" + std::to_string(k + 1), b.s);
  }
  recs.emplace_back("UNITS", std::string("\xff\x01\x02mm", 5));
  o.u8(1), o.u8(0x50), o.u8(0), o.u8(static_cast<int>(proc));  // block count set below
  o.u8(5), o.u8(-1), o.s += "POINT";
  o.i16(2 + 1), o.u8(0);  // group record: offset word, empty description
  for (size_t k = 0; k < recs.size(); ++k) parameter(o, recs[k].first, recs[k].second, k + 1 == recs.size());
  o.pad();
  o.s[2] = static_cast<char>(o.s.size() / kBlock);
  return o.s;
}

}  // namespace

std::string c3d_bytes(const MarkerData& d, const C3dWriteOptions& opt) {
  check_marker_data(d, "C3D output");
  if (d.marker_count() > 32767) throw InputError("C3D: more than 32767 markers");
  if (d.first_frame < 1 || d.first_frame + d.frame_count() - 1 > 65535)
    throw InputError("C3D: frames " + std::to_string(d.first_frame) + "…" + std::to_string(d.first_frame + d.frame_count() - 1) +
                     " do not fit the header's 16-bit frame numbers");
  double scale = opt.scale;
  if (!opt.floating && scale <= 0) {  // the smallest step that fits every coordinate
    const double big = d.xyz.array().isNaN().select(0, d.xyz.array().abs()).maxCoeff();
    scale = std::max(big / 32000.0, 1e-3);
  }
  const int pblocks = static_cast<int>(parameter_section(d, opt.processor, 1, 2).size() / kBlock);
  const int data_start = 2 + pblocks;
  const double stored_scale = opt.floating ? -(scale > 0 ? scale : 0.1) : scale;
  Out o{opt.processor};
  o.u8(2), o.u8(0x50);
  o.i16(d.marker_count()), o.i16(0), o.i16(d.first_frame), o.i16(d.first_frame + d.frame_count() - 1), o.i16(0);
  o.f32(static_cast<float>(stored_scale));
  o.i16(data_start), o.i16(0);
  o.f32(static_cast<float>(d.rate));
  o.pad();
  o.s += parameter_section(d, opt.processor, stored_scale, data_start);
  for (int f = 0; f < d.frame_count(); ++f)
    for (int m = 0; m < d.marker_count(); ++m) {
      const bool ok = d.present(f, m);
      for (int k = 0; k < 3; ++k) {
        const double v = ok ? d.xyz(f, 3 * m + k) : 0.0;
        if (opt.floating) {
          o.f32(static_cast<float>(v));
          continue;
        }
        const double steps = std::round(v / scale);
        if (std::abs(steps) > 32767)
          throw InputError("C3D: marker '" + d.labels[m] + "' frame " + std::to_string(f + d.first_frame) +
                           " does not fit 16-bit integers at scale " + std::to_string(scale) + " mm");
        o.i16(static_cast<int>(steps));
      }
      if (opt.floating) o.f32(ok ? 0.0f : -1.0f);
      else o.i16(ok ? 0 : -1);
    }
  o.pad();
  return o.s;
}

void write_c3d(const std::filesystem::path& path, const MarkerData& d, const C3dWriteOptions& options) {
  const std::string bytes = c3d_bytes(d, options);
  write_atomically(path, [&](std::ostream& os) { os.write(bytes.data(), static_cast<std::streamsize>(bytes.size())); });
}

}  // namespace bodymodel
