// MakeHuman asset bindings: how a clothes / hair / eyes / teeth file (.mhclo) or a body proxy
// (.proxy) ties each vertex of its OBJ to the hm08 body, and the asset's material (.mhmat).
//
// A binding row gives, for asset vertex i, three hm08 vertices v, three weights w and an offset d:
//   x_i = Σ_k w_k · body[v_k] + S · d          S = diag(|body[a_x].x − body[b_x].x| / den_x, …)
// where the x_scale / y_scale / z_scale lines give (a, b, den) per axis. A row with one index is
// an exact copy of that body vertex. MakeHuman's reader (makehuman/shared/proxy.py) is the
// reference; docs/assets.md describes the format and what we accept.
#pragma once

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace bodymodel {

// One x_scale / y_scale / z_scale line: the offset's axis is scaled by the body's extent between
// hm08 vertices a and b along that axis, divided by `denominator` (file units, decimetres).
struct AssetScale {
  int a = -1, b = -1;
  double denominator = 1;
};

struct AssetBinding {
  std::string name, uuid, description, basemesh = "hm08";
  std::string obj_file;                  // the asset's mesh, relative to the binding's folder
  std::string material_file;             // "" when the file names none
  std::string vertex_bone_weights_file;  // the asset's own weights file (shoes), "" if none
  std::vector<std::string> tags;
  int z_depth = 50;   // MakeHuman's render order (50 when the file gives none)
  int max_pole = 0;   // 0 when the file gives none
  bool proxy = false; // a .proxy file: a replacement body mesh, not a garment

  Eigen::MatrixX3i vertices;  // #A by 3 hm08 vertex indices
  Eigen::MatrixX3d weights;   // #A by 3 (an exact row is 1 0 0)
  Eigen::MatrixX3d offsets;   // #A by 3, file units (decimetres) before scaling
  // The three scale lines, or none (all three or none: MakeHuman needs the full set).
  std::optional<std::array<AssetScale, 3>> scales;
  std::vector<int> deleted_vertices;  // hm08 vertices the asset hides, sorted, unique

  int vertex_count() const { return static_cast<int>(vertices.rows()); }
  int max_vertex_index() const;  // the largest hm08 index the binding reads (rows and scales)
};

// Parses a .mhclo / .proxy text. `source` names it in errors; `body_vertex_count` bounds every
// index (hm08: 19158). Throws InputError "'<source>' line N: ..." for a malformed line, an index
// out of range, a non-finite number, a partial set of scale lines, a zero scale denominator, a
// basemesh other than hm08, shear lines (not supported) or no binding rows.
AssetBinding parse_asset_binding(std::string_view text, const std::string& source,
                                 int body_vertex_count = 19158);
// Reads a file (InputError if it cannot be read); `proxy` is set for the .proxy extension.
AssetBinding read_asset_binding(const std::filesystem::path& path, int body_vertex_count = 19158);

// A MakeHuman material (.mhmat): the parameters we use. Textures are file names as written.
struct AssetMaterial {
  std::string name;
  Eigen::Vector3d diffuse_color{1, 1, 1}, ambient_color{1, 1, 1}, specular_color{1, 1, 1};
  Eigen::Vector3d emissive_color{0, 0, 0};
  double shininess = 0.2, opacity = 1, translucency = 0;  // MakeHuman's defaults
  bool transparent = false, backface_cull = true;
  // "diffuse", "normalmap", "aomap", "bump", "displacementmap", ... → file name
  std::map<std::string, std::string> textures;
  // A metallic-roughness stand-in for glTF: 1 − shininess (our approximation: MakeHuman's
  // shading is a Phong/litsphere model with no roughness parameter).
  double roughness() const { return 1 - shininess; }
};

// Parses a .mhmat text. Unknown keys (shader settings) are skipped; a colour, number or
// boolean that does not parse, or is out of range, throws InputError "'<source>' line N: ...".
AssetMaterial parse_asset_material(std::string_view text, const std::string& source);
AssetMaterial read_asset_material(const std::filesystem::path& path);

}  // namespace bodymodel
