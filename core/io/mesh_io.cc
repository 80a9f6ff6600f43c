#include "core/io/mesh_io.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <sstream>
#include <unordered_map>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/off.h"

namespace bodymodel {

namespace fs = std::filesystem;

namespace {

std::string lower_ext(const fs::path& p) {
  std::string e = p.extension().string();
  for (auto& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

std::string where(const std::string& source, size_t line) {
  return "'" + source + "' line " + std::to_string(line);
}

// Splits [b, e) on blanks.
void split(const char* b, const char* e, std::vector<std::string_view>& out) {
  out.clear();
  while (b < e) {
    while (b < e && (*b == ' ' || *b == '\t' || *b == '\r')) ++b;
    const char* s = b;
    while (b < e && *b != ' ' && *b != '\t' && *b != '\r') ++b;
    if (b > s) out.emplace_back(s, b - s);
  }
}

bool parse_double(std::string_view s, double& v) {
  auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}
bool parse_int(std::string_view s, long& v) {
  auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

}  // namespace

ObjContents read_obj_contents(const fs::path& path) {
  return parse_obj(read_text_file(path), path.string());
}

ObjContents parse_obj(std::string_view text, const std::string& path) {
  ObjContents obj;
  std::vector<double> coords;
  std::vector<size_t> polygon_line;
  std::unordered_map<std::string, int> group_index;
  int current_group = -1;
  std::vector<std::string_view> tok;
  size_t line_no = 0;
  const char* p = text.data();
  const char* end = p + text.size();
  while (p < end) {
    const char* eol = static_cast<const char*>(std::memchr(p, '\n', end - p));
    if (!eol) eol = end;
    ++line_no;
    split(p, eol, tok);
    p = eol + 1;
    if (tok.empty() || tok[0][0] == '#') continue;
    if (tok[0] == "v") {
      if (tok.size() < 4)
        throw InputError(where(path, line_no) + ": a vertex needs 3 coordinates, found " +
                         std::to_string(tok.size() - 1) + " (file truncated?)");
      for (int k = 1; k <= 3; ++k) {
        double v;
        if (!parse_double(tok[k], v))
          throw InputError(where(path, line_no) + ": '" + std::string(tok[k]) +
                           "' is not a number");
        coords.push_back(v);
      }
    } else if (tok[0] == "f") {
      if (tok.size() < 4)
        throw InputError(where(path, line_no) + ": a face needs at least 3 vertices, found " +
                         std::to_string(tok.size() - 1) + " (file truncated?)");
      std::vector<int> poly;
      poly.reserve(tok.size() - 1);
      long nv = static_cast<long>(coords.size() / 3);
      for (size_t k = 1; k < tok.size(); ++k) {
        std::string_view t = tok[k].substr(0, tok[k].find('/'));
        long idx;
        if (!parse_int(t, idx) || idx == 0)
          throw InputError(where(path, line_no) + ": '" + std::string(tok[k]) +
                           "' is not a vertex reference");
        long zero_based = idx > 0 ? idx - 1 : nv + idx;
        if (zero_based < 0)
          throw InputError(where(path, line_no) + ": relative vertex index " +
                           std::to_string(idx) + " points before the first vertex");
        poly.push_back(static_cast<int>(zero_based));
      }
      if (current_group < 0) {
        group_index[""] = 0;
        obj.group_names.push_back("");
        current_group = 0;
      }
      obj.polygons.push_back(std::move(poly));
      obj.polygon_group.push_back(current_group);
      polygon_line.push_back(line_no);
    } else if (tok[0] == "g") {
      std::string name = tok.size() > 1 ? std::string(tok[1]) : std::string();
      auto [it, inserted] = group_index.emplace(name, static_cast<int>(obj.group_names.size()));
      if (inserted) obj.group_names.push_back(name);
      current_group = it->second;
    }
    // vt, vn, s, o, usemtl, mtllib, l ...: not needed, ignored.
  }
  const long nv = static_cast<long>(coords.size() / 3);
  if (nv == 0) throw InputError("'" + path + "': no vertices (empty or not an OBJ file)");
  obj.V = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(coords.data(), nv, 3);
  for (size_t f = 0; f < obj.polygons.size(); ++f)
    for (int v : obj.polygons[f])
      if (v >= nv)
        throw InputError(where(path, polygon_line[f]) + ": face refers to vertex " +
                         std::to_string(v + 1) + " but the file has only " + std::to_string(nv) +
                         " vertices (file truncated?)");
  return obj;
}

Eigen::MatrixX3i triangulate(const std::vector<std::vector<int>>& polygons) {
  size_t n = 0;
  for (auto& p : polygons) n += p.size() - 2;
  Eigen::MatrixX3i F(n, 3);
  size_t r = 0;
  for (auto& p : polygons)
    for (size_t k = 1; k + 1 < p.size(); ++k) F.row(r++) << p[0], p[k], p[k + 1];
  return F;
}


// ---- OFF ---------------------------------------------------------------------------------------

ObjContents parse_off(std::string_view text, const std::string& path) {
  // Lines with their numbers, comments ('#' to the end of the line) and blank lines skipped.
  std::vector<std::string_view> tok;
  size_t line_no = 0;
  const char* p = text.data();
  const char* const end = p + text.size();
  auto next_line = [&]() -> bool {
    while (p < end) {
      const char* eol = static_cast<const char*>(std::memchr(p, '\n', end - p));
      if (!eol) eol = end;
      ++line_no;
      const char* hash = static_cast<const char*>(std::memchr(p, '#', eol - p));
      split(p, hash ? hash : eol, tok);
      p = eol + (eol < end ? 1 : 0);
      if (!tok.empty()) return true;
    }
    tok.clear();
    return false;
  };
  if (!next_line()) throw InputError("'" + path + "': empty file (expected an OFF mesh)");
  // Header: OFF, COFF, NOFF, CNOFF, STOFF ... (prefix letters add per-vertex values), possibly
  // followed by the counts on the same line; "OFF BINARY" is refused.
  size_t extra_per_vertex = 0;
  size_t counts_at = 0;
  const std::string_view head = tok[0];
  if (head.size() >= 3 && head.substr(head.size() - 3) == "OFF") {
    const std::string_view prefix = head.substr(0, head.size() - 3);
    for (char c : prefix) {
      if (c == 'C') extra_per_vertex += 4;       // colour r g b a
      else if (c == 'N') extra_per_vertex += 3;  // normal
      else if (c == 'S' || c == 'T') extra_per_vertex += 2;  // texture coordinates (STOFF)
      else
        throw InputError(where(path, line_no) + ": unsupported OFF variant '" + std::string(head) +
                         "' (expected OFF, COFF, NOFF or CNOFF)");
    }
    if (tok.size() > 1 && tok[1] == "BINARY")
      throw InputError(where(path, line_no) +
                       ": binary OFF is not supported (convert it to ASCII OFF, PLY or OBJ)");
    counts_at = 1;  // "OFF #V #F #E" on one line
    if (tok.size() == 1) {
      if (!next_line())
        throw InputError("'" + path + "': no counts line after the OFF header (file truncated?)");
      counts_at = 0;
    }
  }
  long counts[2] = {-1, -1};
  if (tok.size() < counts_at + 2 || !parse_int(tok[counts_at], counts[0]) ||
      !parse_int(tok[counts_at + 1], counts[1]) || counts[0] < 0 || counts[1] < 0)
    throw InputError(where(path, line_no) +
                     ": expected the counts line '#vertices #faces #edges' of an OFF file");
  // Each vertex line takes at least 6 bytes ("0 0 0\n"), each face line 8 ("3 0 1 2\n"): a count
  // the file cannot hold is refused before anything is allocated.
  if (counts[0] > long(text.size() / 6) + 1 || counts[1] > long(text.size() / 8) + 1)
    throw InputError(where(path, line_no) + ": the counts line declares " +
                     std::to_string(counts[0]) + " vertices and " + std::to_string(counts[1]) +
                     " faces, more than the file's " + std::to_string(text.size()) +
                     " bytes can hold (wrong counts or truncated file)");
  const long nv = counts[0], nf = counts[1];
  const std::string declared = " (the counts line declares " + std::to_string(nv) +
                               " vertices and " + std::to_string(nf) + " faces)";
  ObjContents out;
  out.V.resize(nv, 3);
  for (long i = 0; i < nv; ++i) {
    if (!next_line())
      throw InputError("'" + path + "': the file ends after " + std::to_string(i) + " vertices" +
                       declared);
    if (tok.size() < 3)
      throw InputError(where(path, line_no) + ": vertex " + std::to_string(i) +
                       " needs 3 coordinates, found " + std::to_string(tok.size()) + declared);
    for (int k = 0; k < 3; ++k) {
      double v;
      if (!parse_double(tok[k], v))
        throw InputError(where(path, line_no) + ": '" + std::string(tok[k]) +
                         "' is not a number (vertex " + std::to_string(i) + ")");
      if (!std::isfinite(v))
        throw InputError(where(path, line_no) + ": vertex " + std::to_string(i) +
                         " has a NaN or infinite coordinate");
      out.V(i, k) = v;
    }
    // The variant's extra values (colour, normal) and up to 4 colour values may follow.
    if (tok.size() > 3 + extra_per_vertex + 4)
      throw InputError(where(path, line_no) + ": vertex " + std::to_string(i) + " has " +
                       std::to_string(tok.size()) + " values, expected 3" + declared);
  }
  out.polygons.reserve(nf);
  for (long f = 0; f < nf; ++f) {
    if (!next_line())
      throw InputError("'" + path + "': the file ends after " + std::to_string(f) + " faces" +
                       declared);
    long k;
    if (!parse_int(tok[0], k))
      throw InputError(where(path, line_no) + ": face " + std::to_string(f) + " starts with '" +
                       std::string(tok[0]) + "', expected its vertex count" + declared);
    if (k < 3)
      throw InputError(where(path, line_no) + ": face " + std::to_string(f) + " has " +
                       std::to_string(k) + " vertices; a face needs at least 3");
    if (long(tok.size()) < 1 + k)
      throw InputError(where(path, line_no) + ": face " + std::to_string(f) + " declares " +
                       std::to_string(k) + " vertices but lists " +
                       std::to_string(tok.size() - 1) + " (file truncated?)");
    // Up to 4 colour values may follow the indices (COFF face colours); more is an error.
    if (long(tok.size()) > 1 + k + 4)
      throw InputError(where(path, line_no) + ": face " + std::to_string(f) + " declares " +
                       std::to_string(k) + " vertices but the line has " +
                       std::to_string(tok.size() - 1) + " values");
    std::vector<int> poly(k);
    for (long j = 0; j < k; ++j) {
      long v;
      if (!parse_int(tok[1 + j], v))
        throw InputError(where(path, line_no) + ": '" + std::string(tok[1 + j]) +
                         "' is not a vertex index (face " + std::to_string(f) + ")");
      if (v < 0 || v >= nv)
        throw InputError(where(path, line_no) + ": face " + std::to_string(f) +
                         " refers to vertex " + std::to_string(v) + ", expected 0.." +
                         std::to_string(nv - 1) + " (0-based)");
      poly[j] = int(v);
    }
    out.polygons.push_back(std::move(poly));
    out.polygon_group.push_back(0);
  }
  if (next_line())
    throw InputError(where(path, line_no) + ": unexpected data after the last face" + declared);
  if (nf > 0) out.group_names.push_back("");
  if (nv == 0) throw InputError("'" + path + "': no vertices (empty OFF mesh)");
  return out;
}

static void write_off(const fs::path& path, const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  write_atomically(path, [&](std::ostream& out) {
    std::string buf(static_cast<size_t>(V.rows()) * 3 * 26 + static_cast<size_t>(F.rows()) * 3 * 13 +
                        64, '\0');
    char* q = buf.data();
    char* const e = buf.data() + buf.size();
    auto put = [&](std::string_view s) { q = std::copy(s.begin(), s.end(), q); };
    put("OFF\n");
    q = std::to_chars(q, e, V.rows()).ptr;
    put(" ");
    q = std::to_chars(q, e, F.rows()).ptr;
    put(" 0\n");
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
      for (int k = 0; k < 3; ++k) {
        if (k) *q++ = ' ';
        q = std::to_chars(q, e, V(i, k), std::chars_format::general, 9).ptr;
      }
      *q++ = '\n';
    }
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
      *q++ = '3';
      for (int k = 0; k < 3; ++k) {
        *q++ = ' ';
        q = std::to_chars(q, e, F(f, k)).ptr;
      }
      *q++ = '\n';
    }
    out.write(buf.data(), q - buf.data());
  });
}

// ---- PLY ---------------------------------------------------------------------------------------

namespace {

enum class PlyType { I8, U8, I16, U16, I32, U32, F32, F64 };

PlyType ply_type(std::string_view s, const std::string& path) {
  static const std::unordered_map<std::string_view, PlyType> types = {
      {"char", PlyType::I8},    {"int8", PlyType::I8},     {"uchar", PlyType::U8},
      {"uint8", PlyType::U8},   {"short", PlyType::I16},   {"int16", PlyType::I16},
      {"ushort", PlyType::U16}, {"uint16", PlyType::U16},  {"int", PlyType::I32},
      {"int32", PlyType::I32},  {"uint", PlyType::U32},    {"uint32", PlyType::U32},
      {"float", PlyType::F32},  {"float32", PlyType::F32}, {"double", PlyType::F64},
      {"float64", PlyType::F64}};
  auto it = types.find(s);
  if (it == types.end())
    throw InputError("'" + path + "': unknown PLY property type '" + std::string(s) + "'");
  return it->second;
}

size_t type_size(PlyType t) {
  switch (t) {
    case PlyType::I8: case PlyType::U8: return 1;
    case PlyType::I16: case PlyType::U16: return 2;
    case PlyType::I32: case PlyType::U32: case PlyType::F32: return 4;
    case PlyType::F64: return 8;
  }
  return 0;
}

struct PlyProperty {
  std::string name;
  PlyType type;
  bool is_list = false;
  PlyType count_type = PlyType::U8;
};
struct PlyElement {
  std::string name;
  size_t count = 0;
  std::vector<PlyProperty> props;
};

// Reads scalar values from the body, ASCII or binary (with byte swapping for big-endian).
class PlyBody {
 public:
  PlyBody(const std::string& data, size_t pos, int format, const std::string& path)
      : d_(data), pos_(pos), format_(format), path_(path) {}

  double read(PlyType t) {
    if (format_ == 0) return read_ascii();
    size_t n = type_size(t);
    if (pos_ + n > d_.size())
      throw InputError("'" + path_ + "': binary PLY body ends early: " + counts_ +
                       " (file truncated, or header counts that disagree with the data?)");
    unsigned char b[8];
    std::memcpy(b, d_.data() + pos_, n);
    pos_ += n;
    if (format_ == 2) std::reverse(b, b + n);
    switch (t) {
      case PlyType::I8: { int8_t v; std::memcpy(&v, b, 1); return v; }
      case PlyType::U8: { uint8_t v; std::memcpy(&v, b, 1); return v; }
      case PlyType::I16: { int16_t v; std::memcpy(&v, b, 2); return v; }
      case PlyType::U16: { uint16_t v; std::memcpy(&v, b, 2); return v; }
      case PlyType::I32: { int32_t v; std::memcpy(&v, b, 4); return v; }
      case PlyType::U32: { uint32_t v; std::memcpy(&v, b, 4); return v; }
      case PlyType::F32: { float v; std::memcpy(&v, b, 4); return v; }
      case PlyType::F64: { double v; std::memcpy(&v, b, 8); return v; }
    }
    return 0;
  }

 private:
  double read_ascii() {
    while (pos_ < d_.size() && std::isspace(static_cast<unsigned char>(d_[pos_]))) ++pos_;
    size_t s = pos_;
    while (pos_ < d_.size() && !std::isspace(static_cast<unsigned char>(d_[pos_]))) ++pos_;
    if (s == pos_)
      throw InputError("'" + path_ + "': ASCII PLY body ends early: " + counts_ +
                       " (file truncated, or header counts that disagree with the data?)");
    double v;
    std::string_view tok(d_.data() + s, pos_ - s);
    if (!parse_double(tok, v))
      throw InputError("'" + path_ + "': '" + std::string(tok) + "' is not a number");
    return v;
  }

 public:
  // "the header announces vertex 8, face 12": quoted by the errors that a wrong count causes.
  std::string counts_;
  // Bytes of the body not read (ASCII: whitespace does not count).
  size_t unread() const {
    size_t p = pos_;
    while (p < d_.size() && std::isspace(static_cast<unsigned char>(d_[p]))) ++p;
    return p < d_.size() ? d_.size() - pos_ : 0;
  }

 private:
  const std::string& d_;
  size_t pos_;
  int format_;  // 0 ascii, 1 binary LE, 2 binary BE
  const std::string& path_;
};

struct PlyContents {
  Eigen::MatrixX3d V, N;
  std::vector<std::vector<int>> faces;
};

PlyContents parse_ply(const std::string& data, const std::string& path) {
  if (data.compare(0, 3, "ply") != 0)
    throw InputError("'" + path + "': not a PLY file (no 'ply' magic)");
  size_t header_end = data.find("end_header");
  if (header_end == std::string::npos)
    throw InputError("'" + path + "': PLY header has no end_header");
  size_t body = data.find('\n', header_end);
  body = body == std::string::npos ? data.size() : body + 1;
  std::istringstream header(data.substr(0, header_end));
  std::string line;
  int format = -1;
  std::vector<PlyElement> elements;
  size_t line_no = 0;
  while (std::getline(header, line)) {
    ++line_no;
    std::istringstream ls(line);
    std::string kw;
    ls >> kw;
    if (kw == "format") {
      std::string f;
      ls >> f;
      format = f == "ascii" ? 0 : f == "binary_little_endian" ? 1 : f == "binary_big_endian" ? 2 : -1;
      if (format < 0) throw InputError(where(path, line_no) + ": unknown PLY format '" + f + "'");
    } else if (kw == "element") {
      PlyElement e;
      long long count = -1;
      ls >> e.name >> count;
      if (count < 0 || count > (1LL << 31))
        throw InputError(where(path, line_no) + ": bad element count");
      e.count = static_cast<size_t>(count);
      elements.push_back(e);
    } else if (kw == "property") {
      if (elements.empty())
        throw InputError(where(path, line_no) + ": property before any element");
      PlyProperty p;
      std::string t;
      ls >> t;
      if (t == "list") {
        std::string ct, it;
        ls >> ct >> it >> p.name;
        p.is_list = true;
        p.count_type = ply_type(ct, path);
        p.type = ply_type(it, path);
      } else {
        p.type = ply_type(t, path);
        ls >> p.name;
      }
      elements.back().props.push_back(p);
    }
  }
  if (format < 0) throw InputError("'" + path + "': PLY header has no format line");
  // A cheap sanity bound so a corrupt count cannot make us allocate absurd memory.
  for (auto& e : elements) {
    size_t min_bytes = 0;
    for (auto& p : e.props) min_bytes += p.is_list ? type_size(p.count_type) : type_size(p.type);
    if (format != 0 && e.count * min_bytes > data.size() - body + 0)
      throw InputError("'" + path + "': element '" + e.name + "' claims " +
                       std::to_string(e.count) + " entries but the file is too short (truncated?)");
    if (format == 0 && e.count > data.size())
      throw InputError("'" + path + "': element '" + e.name + "' count exceeds file size");
  }
  PlyBody reader(data, body, format, path);
  reader.counts_ = "the header announces";
  for (size_t i = 0; i < elements.size(); ++i)
    reader.counts_ += (i ? ", " : " ") + elements[i].name + " " + std::to_string(elements[i].count);
  PlyContents out;
  for (auto& e : elements) {
    if (e.name == "vertex") {
      int ix[6] = {-1, -1, -1, -1, -1, -1};
      const char* names[6] = {"x", "y", "z", "nx", "ny", "nz"};
      for (size_t k = 0; k < e.props.size(); ++k)
        for (int j = 0; j < 6; ++j)
          if (e.props[k].name == names[j] && !e.props[k].is_list) ix[j] = static_cast<int>(k);
      if (ix[0] < 0 || ix[1] < 0 || ix[2] < 0)
        throw InputError("'" + path + "': PLY vertex element has no x, y, z properties");
      bool normals = ix[3] >= 0 && ix[4] >= 0 && ix[5] >= 0;
      out.V.resize(e.count, 3);
      if (normals) out.N.resize(e.count, 3);
      std::vector<double> vals(e.props.size());
      for (size_t i = 0; i < e.count; ++i) {
        for (size_t k = 0; k < e.props.size(); ++k) {
          if (e.props[k].is_list) {
            const double nd = reader.read(e.props[k].count_type);
            if (!(nd >= 0 && nd <= 1000))  // also NaN (a float count type)
              throw InputError("'" + path + "': vertex " + std::to_string(i) +
                               " has an implausible list length " + std::to_string(nd));
            size_t n = static_cast<size_t>(nd);
            for (size_t j = 0; j < n; ++j) reader.read(e.props[k].type);
          } else {
            vals[k] = reader.read(e.props[k].type);
          }
        }
        for (int j = 0; j < 3; ++j) out.V(i, j) = vals[ix[j]];
        if (normals)
          for (int j = 0; j < 3; ++j) out.N(i, j) = vals[ix[3 + j]];
      }
    } else {
      // An element without properties has no data to read, however large its count (fuzz_ply:
      // "element facd 3333333333" with no properties looped for minutes).
      if (e.props.empty()) continue;
      const bool is_face = e.name == "face";
      for (size_t i = 0; i < e.count; ++i) {
        for (auto& p : e.props) {
          if (p.is_list) {
            double nd = reader.read(p.count_type);
            if (!(nd >= 0 && nd <= 1000))  // also NaN (a float count type)
              throw InputError("'" + path + "': " + e.name + " " + std::to_string(i) +
                               " has an implausible list length " + std::to_string(nd) + " (" + reader.counts_ +
                               ")");
            size_t n = static_cast<size_t>(nd);
            std::vector<int> poly(n);
            for (size_t j = 0; j < n; ++j) {
              double v = reader.read(p.type);
              if (is_face && !(v >= 0 && v < static_cast<double>(out.V.rows())))
                throw InputError("'" + path + "': face " + std::to_string(i) +
                                 " refers to vertex " + std::to_string(static_cast<long long>(v)) +
                                 " but " + reader.counts_ +
                                 " (a header count that disagrees with the data, or a corrupt face)");
              poly[j] = is_face ? static_cast<int>(v) : 0;  // checked above; other lists unused
            }
            if (is_face && (p.name == "vertex_indices" || p.name == "vertex_index")) {
              if (n < 3)
                throw InputError("'" + path + "': face " + std::to_string(i) + " has fewer than 3 vertices (" +
                                 reader.counts_ + ")");
              out.faces.push_back(std::move(poly));
            }
          } else {
            reader.read(p.type);
          }
        }
      }
    }
  }
  // Data beyond the announced elements: a header count smaller than the data (its last faces
  // would be dropped without a word).
  if (const size_t extra = reader.unread(); extra > 0)
    throw InputError("'" + path + "': " + std::to_string(extra) + " bytes of data follow the last element, but " +
                     reader.counts_ + ": the header's counts disagree with the data");
  return out;
}

void write_ply(const fs::path& path, const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& N,
               const Eigen::MatrixX3i& F, const Eigen::MatrixX3d& C, bool ascii) {
  const bool normals = N.rows() == V.rows() && V.rows() > 0;
  const bool colors = C.rows() == V.rows() && V.rows() > 0;
  write_atomically(path, [&](std::ostream& out) {
    out << "ply\nformat " << (ascii ? "ascii" : "binary_little_endian") << " 1.0\n"
        << "comment written by bodymodel\n"
        << "element vertex " << V.rows() << "\n"
        << "property float x\nproperty float y\nproperty float z\n";
    if (normals) out << "property float nx\nproperty float ny\nproperty float nz\n";
    if (colors) out << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    if (F.rows() > 0) out << "element face " << F.rows() << "\nproperty list uchar int vertex_indices\n";
    out << "end_header\n";
    auto rgb = [&](Eigen::Index i, int k) {
      return static_cast<uint8_t>(std::lround(std::clamp(C(i, k), 0.0, 1.0) * 255));
    };
    if (ascii) {
      out.precision(9);
      for (Eigen::Index i = 0; i < V.rows(); ++i) {
        out << V(i, 0) << ' ' << V(i, 1) << ' ' << V(i, 2);
        if (normals) out << ' ' << N(i, 0) << ' ' << N(i, 1) << ' ' << N(i, 2);
        if (colors) out << ' ' << int(rgb(i, 0)) << ' ' << int(rgb(i, 1)) << ' ' << int(rgb(i, 2));
        out << '\n';
      }
      for (Eigen::Index f = 0; f < F.rows(); ++f)
        out << "3 " << F(f, 0) << ' ' << F(f, 1) << ' ' << F(f, 2) << '\n';
    } else {
      std::string buf;
      buf.reserve(V.rows() * 27 + F.rows() * 13);
      auto putf = [&](double d) {
        float f = static_cast<float>(d);
        buf.append(reinterpret_cast<const char*>(&f), 4);
      };
      for (Eigen::Index i = 0; i < V.rows(); ++i) {
        for (int k = 0; k < 3; ++k) putf(V(i, k));
        if (normals) for (int k = 0; k < 3; ++k) putf(N(i, k));
        if (colors) for (int k = 0; k < 3; ++k) buf.push_back(static_cast<char>(rgb(i, k)));
      }
      for (Eigen::Index f = 0; f < F.rows(); ++f) {
        buf.push_back(3);
        for (int k = 0; k < 3; ++k) {
          int32_t v = F(f, k);
          buf.append(reinterpret_cast<const char*>(&v), 4);
        }
      }
      out.write(buf.data(), buf.size());
    }
  });
}

void write_obj(const fs::path& path, const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  write_atomically(path, [&](std::ostream& out) {
    // std::to_chars with general format and precision 9 writes exactly what printf's %.9g
    // writes (C++17 [charconv.to.chars]), without the locale and format-string parsing that
    // made snprintf most of a body's writing time. One buffer sized for the worst case.
    std::string buf(static_cast<size_t>(V.rows()) * 3 * 26 + static_cast<size_t>(F.rows()) * 3 * 13 + 16, '\0');
    char* p = buf.data();
    char* const end = buf.data() + buf.size();
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
      *p++ = 'v';
      for (int k = 0; k < 3; ++k) {
        *p++ = ' ';
        p = std::to_chars(p, end, V(i, k), std::chars_format::general, 9).ptr;
      }
      *p++ = '\n';
    }
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
      *p++ = 'f';
      for (int k = 0; k < 3; ++k) {
        *p++ = ' ';
        p = std::to_chars(p, end, F(f, k) + 1).ptr;
      }
      *p++ = '\n';
    }
    out.write(buf.data(), p - buf.data());
  });
}

}  // namespace

Mesh parse_mesh(const std::string& bytes, const std::string& format, const std::string& source) {
  Mesh m;
  if (format == "obj") {
    ObjContents obj = parse_obj(bytes, source);
    m.V = std::move(obj.V);
    m.F = triangulate(obj.polygons);
  } else if (format == "ply") {
    PlyContents ply = parse_ply(bytes, source);
    m.V = std::move(ply.V);
    m.F = triangulate(ply.faces);
  } else if (format == "off") {
    ObjContents off = parse_off(bytes, source);
    m.V = std::move(off.V);
    m.F = triangulate(off.polygons);
  } else {
    throw InputError("'" + source + "': unknown mesh format '" + format +
                     "' (expected obj, ply or off)");
  }
  if (m.F.rows() == 0) throw InputError("'" + source + "': the file has no faces");
  if (!m.V.allFinite())
    throw InputError("'" + source + "': a vertex has a NaN or infinite coordinate");
  return m;
}

PointCloud parse_ply_point_cloud(const std::string& bytes, const std::string& source) {
  PlyContents ply = parse_ply(bytes, source);
  PointCloud c;
  c.P = std::move(ply.V);
  c.N = std::move(ply.N);
  if (!c.P.allFinite() || (c.has_normals() && !c.N.allFinite()))
    throw InputError("'" + source + "': a point has a NaN or infinite coordinate or normal");
  return c;
}

Mesh read_mesh(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec))
    throw InputError("cannot read '" + path.string() + "': it is a folder, not a mesh file");
  const std::string ext = lower_ext(path);
  if (ext != ".obj" && ext != ".ply" && ext != ".off")
    throw InputError("'" + path.string() + "': unknown mesh format '" + ext +
                     "' (expected .obj, .ply or .off)");
  return parse_mesh(read_text_file(path), ext.substr(1), path.string());
}

void write_mesh(const fs::path& path, const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                const Eigen::MatrixX3d& colors, bool ascii) {
  if (!V.allFinite())
    throw NumericalError("refusing to write '" + path.string() + "': NaN or infinite vertex");
  const std::string ext = lower_ext(path);
  if (ext == ".obj")
    write_obj(path, V, F);
  else if (ext == ".ply")
    write_ply(path, V, Eigen::MatrixX3d(), F, colors, ascii);
  else if (ext == ".off")
    write_off(path, V, F);
  else
    throw InputError("'" + path.string() + "': unknown mesh format '" + ext +
                     "' (expected .obj, .ply or .off)");
}

PointCloud read_point_cloud(const fs::path& path) {
  const std::string ext = lower_ext(path);
  if (ext == ".ply") return parse_ply_point_cloud(read_text_file(path), path.string());
  if (ext == ".obj" || ext == ".off") {
    PointCloud c;
    c.P = ext == ".obj" ? read_obj_contents(path).V
                        : parse_off(read_text_file(path), path.string()).V;
    if (!c.P.allFinite())
      throw InputError("'" + path.string() + "': a point has a NaN or infinite coordinate");
    return c;
  }
  throw InputError("'" + path.string() + "': unknown point-cloud format '" + ext +
                   "' (expected .ply, .obj or .off)");
}

void write_point_cloud(const fs::path& path, const PointCloud& cloud, bool ascii) {
  if (!cloud.P.allFinite() || (cloud.has_normals() && !cloud.N.allFinite()))
    throw NumericalError("refusing to write '" + path.string() + "': NaN or infinite point");
  write_ply(path, cloud.P, cloud.N, Eigen::MatrixX3i(), Eigen::MatrixX3d(), ascii);
}

}  // namespace bodymodel
