#include "tools/pipeline/dressed_pictures.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>

#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>  // declarations only: the implementation is in skinning/gltf_export.cc

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "tools/report/html.h"

namespace bodymodel {

namespace fs = std::filesystem;

namespace {

// Element i, component c of an accessor as a double (float, or unsigned integer indices).
struct AccessorView {
  const unsigned char* data = nullptr;
  size_t stride = 0, count = 0;
  int component = 0, components = 1;
  double at(size_t i, int c) const {
    const unsigned char* p = data + i * stride;
    switch (component) {
      case TINYGLTF_COMPONENT_TYPE_FLOAT: { float f; std::memcpy(&f, p + 4 * c, 4); return f; }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: { uint32_t u; std::memcpy(&u, p + 4 * c, 4); return u; }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { uint16_t u; std::memcpy(&u, p + 2 * c, 2); return u; }
      default: return p[c];
    }
  }
};

AccessorView accessor_view(const tinygltf::Model& m, int index, const fs::path& glb) {
  auto bad = [&](const std::string& what) { return InputError("'" + glb.string() + "': accessor " + std::to_string(index) + ": " + what); };
  if (index < 0 || index >= static_cast<int>(m.accessors.size())) throw bad("missing");
  const tinygltf::Accessor& a = m.accessors[index];
  if (a.bufferView < 0 || a.bufferView >= static_cast<int>(m.bufferViews.size())) throw bad("no buffer view");
  const tinygltf::BufferView& v = m.bufferViews[a.bufferView];
  if (v.buffer < 0 || v.buffer >= static_cast<int>(m.buffers.size())) throw bad("no buffer");
  AccessorView r;
  r.component = a.componentType;
  r.components = tinygltf::GetNumComponentsInType(a.type);
  const int size = tinygltf::GetComponentSizeInBytes(a.componentType);
  if (r.components < 1 || size < 1) throw bad("unknown type");
  r.stride = v.byteStride ? v.byteStride : static_cast<size_t>(size * r.components);
  r.count = a.count;
  const size_t offset = v.byteOffset + a.byteOffset;
  const size_t span = a.count ? (a.count - 1) * r.stride + size_t(size) * r.components : 0;
  if (a.byteOffset + span > v.byteLength || offset + span > m.buffers[v.buffer].data.size())
    throw bad("runs past its buffer view");
  r.data = m.buffers[v.buffer].data.data() + offset;
  return r;
}

double srgb_of_linear(double c) {
  c = std::clamp(c, 0.0, 1.0);
  return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1 / 2.4) - 0.055;
}

// One primitive appended to `out` with its own copy of the vertices it indexes.
void append_primitive(const tinygltf::Model& m, const tinygltf::Primitive& prim, const fs::path& glb, ColouredMesh& out) {
  if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != -1) return;
  auto pos_it = prim.attributes.find("POSITION");
  if (pos_it == prim.attributes.end() || prim.indices < 0) return;
  const AccessorView P = accessor_view(m, pos_it->second, glb), I = accessor_view(m, prim.indices, glb);
  if (P.components != 3 || P.component != TINYGLTF_COMPONENT_TYPE_FLOAT)
    throw InputError("'" + glb.string() + "': POSITION is not float VEC3");
  Eigen::Vector3d colour(0.78, 0.76, 0.74);
  if (prim.material >= 0 && prim.material < static_cast<int>(m.materials.size())) {
    const auto& f = m.materials[prim.material].pbrMetallicRoughness.baseColorFactor;
    if (f.size() >= 3) colour << srgb_of_linear(f[0]), srgb_of_linear(f[1]), srgb_of_linear(f[2]);
  }
  const Eigen::Index v0 = out.V.rows(), f0 = out.F.rows();
  out.V.conservativeResize(v0 + static_cast<Eigen::Index>(P.count), 3);
  out.colors.conservativeResize(out.V.rows(), 3);
  for (size_t i = 0; i < P.count; ++i) {
    for (int c = 0; c < 3; ++c) out.V(v0 + static_cast<Eigen::Index>(i), c) = P.at(i, c);
    out.colors.row(v0 + static_cast<Eigen::Index>(i)) = colour.transpose();
  }
  const size_t nf = I.count / 3;
  out.F.conservativeResize(f0 + static_cast<Eigen::Index>(nf), 3);
  for (size_t t = 0; t < nf; ++t)
    for (int k = 0; k < 3; ++k) {
      const double idx = I.at(3 * t + k, 0);
      if (idx >= static_cast<double>(P.count))
        throw InputError(fmt::format("'{}': triangle index {} past its {} vertices", glb.string(), idx, P.count));
      out.F(f0 + static_cast<Eigen::Index>(t), k) = static_cast<int>(v0 + static_cast<Eigen::Index>(idx));
    }
}

// Each triangle with its own three corners, so the renderer shades it flat (its facets show).
ColouredMesh flat(const ColouredMesh& m) {
  ColouredMesh r;
  r.V.resize(3 * m.F.rows(), 3);
  r.colors.resize(3 * m.F.rows(), 3);
  r.F.resize(m.F.rows(), 3);
  for (Eigen::Index f = 0; f < m.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      r.V.row(3 * f + k) = m.V.row(m.F(f, k));
      r.colors.row(3 * f + k) = m.colors.row(m.F(f, k));
      r.F(f, k) = static_cast<int>(3 * f + k);
    }
  return r;
}

// The head: front view and a view 40° to one side (the +x side), framed on the top 17 % of
// the body (the head and a little neck), centred on the vertices of its top 12 %.
Image head_closeup(const ColouredMesh& m, int size) {
  const double top = m.V.col(1).maxCoeff(), h = top - m.V.col(1).minCoeff();
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  int n = 0;
  for (Eigen::Index i = 0; i < m.V.rows(); ++i)
    if (m.V(i, 1) > top - 0.12 * h) c += m.V.row(i).transpose(), ++n;
  c /= std::max(n, 1);
  Camera cam;
  cam.frame_min = Eigen::Vector3d(c.x() - 0.085 * h, top - 0.17 * h, c.z() - 0.085 * h);
  cam.frame_max = Eigen::Vector3d(c.x() + 0.085 * h, top + 0.005 * h, c.z() + 0.085 * h);
  cam.margin = 0.03;
  Image img(2 * size, size);
  img.paste(render_mesh(m.V, m.F, m.colors, size, size, cam), 0, 0);
  const double a = 40 * M_PI / 180;
  cam.forward = Eigen::Vector3d(-std::sin(a), 0, -std::cos(a));
  img.paste(render_mesh(m.V, m.F, m.colors, size, size, cam), size, 0);
  return img;
}

bool has_hair(const fs::path& outfit_json) {
  std::error_code ec;
  if (!fs::is_regular_file(outfit_json, ec)) return false;
  const nlohmann::json j = nlohmann::json::parse(read_text_file(outfit_json), nullptr, false);
  if (j.is_discarded() || !j.contains("items") || !j["items"].is_array()) return false;
  for (const auto& it : j["items"])
    if (it.is_object() && it.value("slot", "") == "hair") return true;
  return false;
}

}  // namespace

std::vector<ColouredMesh> read_glb_meshes(const fs::path& glb) {
  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  if (!loader.LoadBinaryFromFile(&m, &err, &warn, glb.string()))
    throw InputError("'" + glb.string() + "': not a readable glb" + (err.empty() ? "" : ": " + err));
  std::vector<ColouredMesh> meshes;
  for (const tinygltf::Mesh& mesh : m.meshes) {
    ColouredMesh cm;
    for (const tinygltf::Primitive& prim : mesh.primitives) append_primitive(m, prim, glb, cm);
    if (cm.F.rows() > 0) meshes.push_back(std::move(cm));
  }
  if (meshes.empty()) throw InputError("'" + glb.string() + "': no triangle mesh");
  return meshes;
}

DressedCrowdPictures dressed_crowd_pictures(const fs::path& crowd_dir, int count) {
  DressedCrowdPictures r;
  std::vector<ColouredMesh> lod0;
  std::vector<int> index;
  std::error_code ec;
  for (int i = 0; i < count; ++i) {
    const fs::path anim = crowd_dir / fmt::format("char_{:03d}", i) / "anim";
    if (!fs::is_regular_file(anim / "dressed.glb", ec)) continue;
    lod0.push_back(read_glb_meshes(anim / "dressed.glb").front());
    index.push_back(i);
    if (r.featured < 0 && has_hair(anim / "outfit.json")) r.featured = i;
  }
  if (lod0.empty()) throw InputError("no dressed.glb under '" + crowd_dir.string() + "/char_NNN/anim/'");
  if (r.featured < 0) r.featured = index.front();
  const int per_row = std::min<int>(10, static_cast<int>(lod0.size()));
  const int rows = (static_cast<int>(lod0.size()) + per_row - 1) / per_row, cw = 150, ch = 380;
  r.lineup = Image(per_row * cw, rows * ch);
  for (int k = 0; k < rows; ++k) {
    std::vector<ColouredMesh> row(lod0.begin() + k * per_row,
                                  lod0.begin() + std::min<int>(static_cast<int>(lod0.size()), (k + 1) * per_row));
    r.lineup.paste(render_row(row, cw, ch), 0, k * ch);
  }
  const std::vector<ColouredMesh> levels =
      read_glb_meshes(crowd_dir / fmt::format("char_{:03d}", r.featured) / "anim" / "dressed.glb");
  std::vector<ColouredMesh> flat_levels;
  for (const ColouredMesh& l : levels) {
    flat_levels.push_back(flat(l));
    r.level_triangles.push_back(static_cast<int>(l.F.rows()));
  }
  r.lods = render_row(flat_levels, 220, 520);
  r.closeup = head_closeup(levels.front(), 320);
  return r;
}

void save_dressed_crowd_pictures(const DressedCrowdPictures& p, const fs::path& dir) {
  p.lineup.save_png(dir / "crowd_dressed.png");
  p.lods.save_png(dir / "crowd_lods.png");
  p.closeup.save_png(dir / "crowd_closeup.png");
}

std::string dressed_crowd_html(const fs::path& out, const DressedCrowdPictures& p) {
  std::string b = html_figure(out / "pictures" / "crowd_dressed.png", "pictures/crowd_dressed.png",
                              "The crowd dressed by the default outfits (<code>crowd --outfits default</code>), as "
                              "exported in each <code>char_NNN/anim/dressed.glb</code> (level 0, rest pose).");
  std::string tri;
  for (int t : p.level_triangles) tri += (tri.empty() ? "" : " / ") + std::to_string(t);
  b += "<div class=\"pair\">\n";
  b += html_figure(out / "pictures" / "crowd_lods.png", "pictures/crowd_lods.png",
                   fmt::format("Levels of detail of char_{:03d} in its glb: {} triangles (flat-shaded so the "
                               "triangles show).", p.featured, tri));
  b += html_figure(out / "pictures" / "crowd_closeup.png", "pictures/crowd_closeup.png",
                   fmt::format("char_{:03d}'s head: eyes, brows, lashes and hair fitted to its body.", p.featured));
  b += "</div>\n";
  b += html_table_from_csv(out / "crowd" / "outfits.csv", "crowd/outfits.csv");
  b += "<p>Per character: the outfit drawn (asset:colour), the frames where the body pokes through a garment "
       "(over 2 mm on more than 1 % of its vertices) as its glb plays them, the glb's size, the same frames without "
       "the per-frame garment corrections and the number of morph targets holding them. Each character's "
       "<code>anim/dressed.glb</code> holds it dressed, its three levels of detail and the clip.</p>\n";
  std::error_code ec;
  // crowd writes the page without the three.js modules it imports when they are not installed.
  if (fs::is_regular_file(out / "crowd" / "crowd.html", ec) && fs::is_directory(out / "crowd" / "three", ec))
    b += "<p><b><a href=\"crowd/crowd.html\">Crowd viewer</a></b>: 1000 animated instances of these characters "
         "with levels of detail by distance (three.js). It must be served over http, not opened from the file "
         "system: <code>cd crowd &amp;&amp; python3 -m http.server</code>, then open "
         "<code>http://localhost:8000/crowd.html</code>.</p>\n";
  return b;
}

}  // namespace bodymodel
