// Readers of MakeHuman asset files: .mhclo / .proxy bindings and .mhmat materials, on small
// hand-written files (the format as MakeHuman's proxy.py reads it) and on malformed ones.
#include <gtest/gtest.h>

#include <string>

#include "assets/binding.h"
#include "core/error.h"

namespace bodymodel {
namespace {

const char* kBinding = R"(# a comment
uuid 1234
basemesh hm08
name tiny shirt
tag Casual
tag Male
obj_file tiny.obj
x_scale 1 2 1.5
z_scale 3 4 2.0
y_scale 5 6 0.5
z_depth 31
verts 0
material tiny.mhmat
 10 11 12 0.2 0.3 0.5 0.01 -0.02 0.03
7
20 21 22 0.25 0.25 0.5

delete_verts
1 2 - 5 9
12 - 12
)";

TEST(AssetReader, BindingHeaderRowsAndDeletedVertices) {
  const AssetBinding b = parse_asset_binding(kBinding, "tiny.mhclo", 100);
  EXPECT_EQ(b.name, "tiny shirt");
  EXPECT_EQ(b.uuid, "1234");
  EXPECT_EQ(b.obj_file, "tiny.obj");
  EXPECT_EQ(b.material_file, "tiny.mhmat");  // after `verts`, as in bob01.mhclo
  EXPECT_EQ(b.z_depth, 31);
  ASSERT_EQ(b.tags.size(), 2u);
  EXPECT_EQ(b.tags[1], "Male");
  ASSERT_EQ(b.vertex_count(), 3);
  EXPECT_EQ(b.vertices.row(0), Eigen::RowVector3i(10, 11, 12));
  EXPECT_DOUBLE_EQ(b.weights(0, 2), 0.5);
  EXPECT_DOUBLE_EQ(b.offsets(0, 1), -0.02);
  // An exact row: MakeHuman's (v, 0, 1) with weights (1, 0, 0) and no offset.
  EXPECT_EQ(b.vertices.row(1), Eigen::RowVector3i(7, 0, 1));
  EXPECT_EQ(b.weights.row(1), Eigen::RowVector3d(1, 0, 0));
  // Six numbers: no offset.
  EXPECT_EQ(b.offsets.row(2), Eigen::RowVector3d(0, 0, 0));
  ASSERT_TRUE(b.scales.has_value());
  EXPECT_EQ((*b.scales)[0].a, 1);
  EXPECT_EQ((*b.scales)[1].b, 6);  // y_scale, although listed after z_scale
  EXPECT_DOUBLE_EQ((*b.scales)[2].denominator, 2.0);
  EXPECT_EQ(b.deleted_vertices, (std::vector<int>{1, 2, 3, 4, 5, 9, 12}));
  EXPECT_EQ(b.max_vertex_index(), 22);
}

// Each bad file must fail with InputError naming the file and the line.
void expect_error(const std::string& text, const std::string& needle, int line) {
  try {
    parse_asset_binding(text, "bad.mhclo", 100);
    ADD_FAILURE() << "accepted: " << text;
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("bad.mhclo"), std::string::npos) << msg;
    if (line > 0) {
      EXPECT_NE(msg.find("line " + std::to_string(line)), std::string::npos) << msg;
    }
    EXPECT_NE(msg.find(needle), std::string::npos) << msg;
  }
}

TEST(AssetReader, MalformedBindingsNameFileAndLine) {
  expect_error("verts 0\n1 2 3 0.5 0.5\n", "1, 6 or 9 numbers", 2);
  expect_error("verts 0\n1 2 300 0.2 0.3 0.5\n", "outside [0, 100)", 2);
  expect_error("verts 0\n1 2 -3 0.2 0.3 0.5\n", "outside [0, 100)", 2);
  expect_error("verts 0\n1 2 3 0.2 abc 0.5\n", "not a finite number", 2);
  expect_error("verts 0\n1 2 3 0.2 nan 0.5\n", "not a finite number", 2);
  expect_error("verts 0\n1 2 3 0.2 1e999 0.5\n", "not a finite number", 2);
  expect_error("verts 0\n1.5\n", "not an integer", 2);
  expect_error("name x\n1 2 3 0.2 0.3 0.5\n", "before any 'verts'", 2);
  expect_error("basemesh hm07\nverts 0\n1\n", "not hm08", 1);
  expect_error("shear_x 1 2 0.1 0.2\nverts 0\n1\n", "not supported", 1);
  expect_error("x_scale 1 2 0\nverts 0\n1\n", "positive", 1);
  expect_error("x_scale 1 2\nverts 0\n1\n", "needs 3 values", 1);
  expect_error("colour blue\nverts 0\n1\n", "unknown keyword 'colour'", 1);
  expect_error("z_depth deep\nverts 0\n1\n", "not an integer", 1);
  expect_error("verts 0\n1\ndelete_verts\n5 - 2\n", "reversed", 4);
  expect_error("verts 0\n1\ndelete_verts\n- 2\n", "'-' range", 4);
  expect_error("verts 0\n1\ndelete_verts\n2 - - 4\n", "'-' range", 4);
  expect_error("verts 0\n1\ndelete_verts\n2 - 400\n", "outside [0, 100)", 4);
  // Whole-file checks name the file.
  expect_error("name empty\nverts 0\n", "no binding rows", 0);
  expect_error("x_scale 1 2 1.0\nverts 0\n1\n", "1 of the 3 scale lines", 0);
  expect_error("", "no binding rows", 0);
}

TEST(AssetReader, ProxyExtensionAndMissingFile) {
  EXPECT_THROW(read_asset_binding("/nonexistent/thing.proxy"), InputError);
}

TEST(AssetReader, MaterialColoursNumbersAndTextures) {
  const AssetMaterial m = parse_asset_material(R"(# MakeHuman material
// another comment style
name Shirt_red
diffuseColor 0.8 0.1 0.05
specularColor 1.0 1.0 1.0
shininess 0.3
opacity 0.9
transparent True
backfaceCull False
diffuseTexture textures/shirt diffuse.png
normalmapTexture shirt_normal.png
shader shaders/glsl/litsphere
shaderConfig spec True
)", "shirt.mhmat");
  EXPECT_EQ(m.name, "Shirt_red");
  EXPECT_TRUE(m.diffuse_color.isApprox(Eigen::Vector3d(0.8, 0.1, 0.05)));
  EXPECT_DOUBLE_EQ(m.shininess, 0.3);
  EXPECT_DOUBLE_EQ(m.roughness(), 0.7);
  EXPECT_DOUBLE_EQ(m.opacity, 0.9);
  EXPECT_TRUE(m.transparent);
  EXPECT_FALSE(m.backface_cull);
  EXPECT_EQ(m.textures.at("diffuse"), "textures/shirt diffuse.png");
  EXPECT_EQ(m.textures.at("normalmap"), "shirt_normal.png");
  EXPECT_EQ(m.textures.size(), 2u);
  // Defaults when a key is absent (MakeHuman's).
  const AssetMaterial d = parse_asset_material("name plain\n", "plain.mhmat");
  EXPECT_DOUBLE_EQ(d.shininess, 0.2);
  EXPECT_TRUE(d.diffuse_color.isApprox(Eigen::Vector3d::Ones()));
}

TEST(AssetReader, MalformedMaterialsNameFileAndLine) {
  auto expect_bad = [](const std::string& text, const std::string& needle) {
    try {
      parse_asset_material(text, "bad.mhmat");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("'bad.mhmat' line 2"), std::string::npos) << msg;
      EXPECT_NE(msg.find(needle), std::string::npos) << msg;
    }
  };
  expect_bad("name x\ndiffuseColor 1 1\n", "3 numbers");
  expect_bad("name x\ndiffuseColor 1 -1 1\n", "negative");
  expect_bad("name x\nshininess 1.5\n", "[0, 1]");
  expect_bad("name x\nopacity much\n", "not a finite number");
  expect_bad("name x\ntransparent Maybe\n", "not a boolean");
  expect_bad("name x\ndiffuseTexture\n", "file name");
}

}  // namespace
}  // namespace bodymodel
