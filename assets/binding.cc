#include "assets/binding.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <initializer_list>
#include <set>

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {

namespace {

// Joins pieces by appending (chains of + on short strings trip GCC 12's -Wrestrict).
std::string cat(std::initializer_list<std::string_view> parts) {
  std::string out;
  for (std::string_view p : parts) out.append(p);
  return out;
}

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

// The words after the first, joined by one space (names, tags, descriptions).
std::string rest_of(const std::vector<std::string_view>& w) {
  std::string out;
  for (size_t k = 1; k < w.size(); ++k) {
    if (k > 1) out += ' ';
    out += w[k];
  }
  return out;
}

// Reads lines one at a time and builds "'<source>' line N: what" errors.
class LineReader {
 public:
  LineReader(std::string_view text, const std::string& source) : text_(text), source_(source) {}
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    size_t end = text_.find('\n', pos_);
    if (end == std::string_view::npos) end = text_.size();
    line = text_.substr(pos_, end - pos_);
    pos_ = end + 1;
    ++line_no_;
    return true;
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError("'" + source_ + "' line " + std::to_string(line_no_) + ": " + what);
  }
  double number(std::string_view s) const {
    double v = 0;
    const char* b = s.data();
    if (!s.empty() && s[0] == '+') ++b;
    const auto r = std::from_chars(b, s.data() + s.size(), v);
    if (r.ec != std::errc() || r.ptr != s.data() + s.size() || !std::isfinite(v)) {
      fail(cat({"'", s, "' is not a finite number"}));
    }
    return v;
  }
  int integer(std::string_view s, int limit, const char* what) const {
    long long v = 0;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    if (r.ec != std::errc() || r.ptr != s.data() + s.size())
      fail(cat({"'", s, "' is not an integer (", what, ")"}));
    if (v < 0 || v >= limit)
      fail(cat({what, " ", s, " is outside [0, ", std::to_string(limit), ")"}));
    return static_cast<int>(v);
  }
  const std::string& source() const { return source_; }

 private:
  std::string_view text_;
  const std::string& source_;
  size_t pos_ = 0;
  int line_no_ = 0;
};

enum class Block { none, verts, deleted, legacy_weights };

struct BindingBuilder {
  AssetBinding b;
  std::vector<Eigen::Vector3i> idx;
  std::vector<Eigen::Vector3d> w, d;
  std::array<std::optional<AssetScale>, 3> scales;
  std::set<int> deleted;
};

void add_binding_row(const std::vector<std::string_view>& w, const LineReader& in, int n,
                     BindingBuilder& out) {
  if (w.size() == 1) {
    // MakeHuman's exact row: indices (v, 0, 1), weights (1, 0, 0), no offset.
    out.idx.emplace_back(in.integer(w[0], n, "vertex index"), 0, std::min(1, n - 1));
    out.w.emplace_back(1, 0, 0);
    out.d.emplace_back(0, 0, 0);
    return;
  }
  if (w.size() != 6 && w.size() != 9)
    in.fail("a binding row has 1, 6 or 9 numbers (v1 v2 v3 w1 w2 w3 [dx dy dz]), found " +
            std::to_string(w.size()));
  Eigen::Vector3i v;
  Eigen::Vector3d wt, off = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) v[k] = in.integer(w[k], n, "vertex index");
  for (int k = 0; k < 3; ++k) wt[k] = in.number(w[3 + k]);
  if (w.size() == 9)
    for (int k = 0; k < 3; ++k) off[k] = in.number(w[6 + k]);
  out.idx.push_back(v);
  out.w.push_back(wt);
  out.d.push_back(off);
}

// "a b - c d": single vertices and inclusive ranges.
void add_deleted(const std::vector<std::string_view>& w, const LineReader& in, int n,
                 std::set<int>& deleted) {
  for (size_t k = 0; k < w.size(); ++k) {
    if (w[k] == "-") {
      if (k == 0 || k + 1 >= w.size() || w[k - 1] == "-" || w[k + 1] == "-")
        in.fail("a '-' range in delete_verts needs a vertex on each side");
      const int lo = in.integer(w[k - 1], n, "deleted vertex");
      const int hi = in.integer(w[k + 1], n, "deleted vertex");
      if (hi < lo) in.fail("delete_verts range " + std::to_string(lo) + " - " + std::to_string(hi) + " is reversed");
      for (int v = lo; v <= hi; ++v) deleted.insert(v);
    } else {
      deleted.insert(in.integer(w[k], n, "deleted vertex"));
    }
  }
}

void set_scale(const std::vector<std::string_view>& w, const LineReader& in, int n, int axis,
               BindingBuilder& out) {
  if (w.size() != 4) in.fail(cat({"'", w[0], "' needs 3 values (vertex vertex denominator)"}));
  AssetScale s{in.integer(w[1], n, "scale vertex"), in.integer(w[2], n, "scale vertex"), in.number(w[3])};
  if (!(s.denominator > 0)) in.fail(cat({"scale denominator must be positive, found ", w[3]}));
  out.scales[axis] = s;
}

int header_integer(const std::vector<std::string_view>& w, const LineReader& in) {
  if (w.size() != 2) in.fail(cat({"'", w[0], "' needs one integer"}));
  return in.integer(w[1], 1 << 30, std::string(w[0]).c_str());
}

// A keyword line; returns the block that follows it (or `current` for plain header fields).
Block keyword(const std::vector<std::string_view>& w, const LineReader& in, int n, Block current,
              BindingBuilder& out) {
  const std::string_view k = w[0];
  AssetBinding& b = out.b;
  static const std::set<std::string_view> ignored = {
      "author", "license", "homepage", "version", "special_pose", "uvLayer", "backface_culling",
      "transparent", "shapekey", "subsurf", "shrinkwrap", "solidify", "objfile_layer",
      "uvtex_layer", "use_projection", "mask_uv_layer", "texture_uv_layer", "delete",
      "vertexgroup_file"};
  auto file_name = [&] {
    if (w.size() < 2) in.fail(cat({"'", k, "' needs a file name"}));
    return rest_of(w);
  };
  if (k == "verts") return Block::verts;
  if (k == "delete_verts") return Block::deleted;
  if (k == "weights") return Block::legacy_weights;  // per-bone weights of old files: skipped
  if (k == "name") b.name = rest_of(w);
  else if (k == "uuid") b.uuid = rest_of(w);
  else if (k == "description") b.description = rest_of(w);
  else if (k == "tag") b.tags.push_back(rest_of(w));
  else if (k == "basemesh") {
    b.basemesh = rest_of(w);
    if (b.basemesh != "hm08") in.fail("basemesh '" + b.basemesh + "' is not hm08");
  } else if (k == "obj_file") b.obj_file = file_name();
  else if (k == "material") b.material_file = file_name();
  else if (k == "vertexboneweights_file") b.vertex_bone_weights_file = file_name();
  else if (k == "z_depth") b.z_depth = header_integer(w, in);
  else if (k == "max_pole") b.max_pole = header_integer(w, in);
  else if (k == "x_scale" || k == "y_scale" || k == "z_scale") set_scale(w, in, n, k[0] - 'x', out);
  else if (k.find("shear_") != std::string_view::npos)
    in.fail(cat({"'", k, "': shear transforms are not supported (only x/y/z_scale)"}));
  else if (!ignored.count(k)) in.fail(cat({"unknown keyword '", k, "'"}));
  return current;
}

AssetBinding finish(BindingBuilder& in, const std::string& source) {
  AssetBinding b = std::move(in.b);
  const int rows = static_cast<int>(in.idx.size());
  if (rows == 0) throw InputError("'" + source + "': no binding rows after 'verts'");
  const int given = int(in.scales[0].has_value()) + int(in.scales[1].has_value()) + int(in.scales[2].has_value());
  if (given == 3) b.scales = std::array<AssetScale, 3>{*in.scales[0], *in.scales[1], *in.scales[2]};
  else if (given != 0)
    throw InputError("'" + source + "': has " + std::to_string(given) +
                     " of the 3 scale lines (x_scale, y_scale, z_scale); MakeHuman needs all or none");
  b.vertices.resize(rows, 3);
  b.weights.resize(rows, 3);
  b.offsets.resize(rows, 3);
  for (int i = 0; i < rows; ++i) {
    b.vertices.row(i) = in.idx[i].transpose();
    b.weights.row(i) = in.w[i].transpose();
    b.offsets.row(i) = in.d[i].transpose();
  }
  b.deleted_vertices.assign(in.deleted.begin(), in.deleted.end());
  return b;
}

bool is_keyword(std::string_view word) {
  return !word.empty() && (std::isalpha(static_cast<unsigned char>(word[0])) || word[0] == '_');
}

}  // namespace

int AssetBinding::max_vertex_index() const {
  int m = vertices.size() ? vertices.maxCoeff() : -1;
  if (scales)
    for (const AssetScale& s : *scales) m = std::max({m, s.a, s.b});
  return m;
}

AssetBinding parse_asset_binding(std::string_view text, const std::string& source,
                                 int body_vertex_count) {
  if (body_vertex_count < 2) throw InputError("'" + source + "': the body needs at least 2 vertices");
  LineReader in(text, source);
  BindingBuilder out;
  Block block = Block::none;
  std::string_view line;
  while (in.next(line)) {
    const auto w = split_words(line);
    if (w.empty() || w[0][0] == '#') continue;
    // As in MakeHuman, a keyword is recognised anywhere (some files put `material` after
    // `verts 0`); a row of numbers belongs to the last block opened.
    if (is_keyword(w[0])) {
      block = keyword(w, in, body_vertex_count, block, out);
      continue;
    }
    switch (block) {
      case Block::verts: add_binding_row(w, in, body_vertex_count, out); break;
      case Block::deleted: add_deleted(w, in, body_vertex_count, out.deleted); break;
      case Block::legacy_weights: break;
      case Block::none: in.fail("a row of numbers before any 'verts' or 'delete_verts' line");
    }
  }
  return finish(out, source);
}

AssetBinding read_asset_binding(const std::filesystem::path& path, int body_vertex_count) {
  AssetBinding b = parse_asset_binding(read_text_file(path), path.string(), body_vertex_count);
  b.proxy = path.extension() == ".proxy";
  return b;
}

namespace {

bool parse_bool(std::string_view s, const LineReader& in) {
  if (s == "True" || s == "true" || s == "1") return true;
  if (s == "False" || s == "false" || s == "0") return false;
  in.fail(cat({"'", s, "' is not a boolean (True or False)"}));
}

Eigen::Vector3d parse_colour(const std::vector<std::string_view>& w, const LineReader& in) {
  if (w.size() != 4) in.fail(cat({"'", w[0], "' needs 3 numbers (r g b)"}));
  Eigen::Vector3d c;
  for (int k = 0; k < 3; ++k) {
    c[k] = in.number(w[1 + k]);
    if (c[k] < 0) in.fail(cat({"colour component ", w[1 + k], " is negative"}));
  }
  return c;
}

double parse_unit_number(const std::vector<std::string_view>& w, const LineReader& in) {
  if (w.size() != 2) in.fail(cat({"'", w[0], "' needs one number"}));
  const double v = in.number(w[1]);
  if (v < 0 || v > 1) in.fail(cat({"'", w[0], "' must be in [0, 1], found ", w[1]}));
  return v;
}

}  // namespace

AssetMaterial parse_asset_material(std::string_view text, const std::string& source) {
  LineReader in(text, source);
  AssetMaterial m;
  std::string_view line;
  constexpr std::string_view kTexture = "Texture";
  while (in.next(line)) {
    const auto w = split_words(line);
    if (w.empty() || w[0][0] == '#' || w[0].substr(0, 2) == "//") continue;
    const std::string_view k = w[0];
    if (k == "name") m.name = rest_of(w);
    else if (k == "diffuseColor") m.diffuse_color = parse_colour(w, in);
    else if (k == "ambientColor") m.ambient_color = parse_colour(w, in);
    else if (k == "specularColor") m.specular_color = parse_colour(w, in);
    else if (k == "emissiveColor") m.emissive_color = parse_colour(w, in);
    else if (k == "shininess") m.shininess = parse_unit_number(w, in);
    else if (k == "opacity") m.opacity = parse_unit_number(w, in);
    else if (k == "translucency") m.translucency = parse_unit_number(w, in);
    else if (k == "transparent" || k == "backfaceCull") {
      if (w.size() != 2) in.fail(cat({"'", k, "' needs True or False"}));
      (k == "transparent" ? m.transparent : m.backface_cull) = parse_bool(w[1], in);
    } else if (k.size() > kTexture.size() && k.substr(k.size() - kTexture.size()) == kTexture) {
      if (w.size() < 2) in.fail(cat({"'", k, "' needs a file name"}));
      m.textures[std::string(k.substr(0, k.size() - kTexture.size()))] = rest_of(w);
    }
    // Everything else (shader, shaderParam, shaderConfig, sss*, ...) drives MakeHuman's own
    // renderer and has no counterpart here.
  }
  return m;
}

AssetMaterial read_asset_material(const std::filesystem::path& path) {
  return parse_asset_material(read_text_file(path), path.string());
}

}  // namespace bodymodel
