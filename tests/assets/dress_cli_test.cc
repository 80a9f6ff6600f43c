// `bodymodel dress`: a dressed, posed body written as OBJ + MTL and as coloured PLY; bad input
// exits 2 with one line and leaves no file.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>  // declarations only: the implementation is in skinning/gltf_export.cc

#include "core/data_path.h"
#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;
using fixtures::run_cli;

class DressCli : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(BODYMODEL_EXE)) GTEST_SKIP() << "bodymodel not built: " << BODYMODEL_EXE;
    try {
      if (!fs::is_directory(data_root() / "makehuman" / "assets")) GTEST_SKIP() << "makehuman/assets not found";
    } catch (const std::exception& e) {
      GTEST_SKIP() << e.what();
    }
    dir = fs::temp_directory_path() / ("bodymodel_dress_" + std::to_string(::getpid()));
    fs::create_directories(dir);
  }
  void TearDown() override {
    if (!dir.empty()) fs::remove_all(dir);
  }
  fs::path dir;
};

TEST_F(DressCli, WritesObjWithMaterialsAndColouredPly) {
  const auto r = run_cli("dress --gender 1 --outfit male_casualsuit02,shoes01,short02 --pose sit01 --out " +
                         (dir / "man.obj").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("male_casualsuit02"), std::string::npos) << r.output;
  std::ifstream mtl(dir / "man.mtl");
  std::stringstream ss;
  ss << mtl.rdbuf();
  for (const char* part : {"newmtl body", "newmtl male_casualsuit02", "newmtl shoes01", "newmtl short02"})
    EXPECT_NE(ss.str().find(part), std::string::npos) << part;
  const ObjContents obj = read_obj_contents(dir / "man.obj");
  EXPECT_GT(obj.V.rows(), 2000);
  // A sitting person's height in mm (not decimetres).
  EXPECT_GT(obj.V.col(1).maxCoeff() - obj.V.col(1).minCoeff(), 700.0);
  EXPECT_LT(obj.V.col(1).maxCoeff() - obj.V.col(1).minCoeff(), 2000.0);

  ASSERT_EQ(run_cli("dress --outfit female_casualsuit01 --out " + (dir / "w.ply").string()).exit_code, 0);
  EXPECT_TRUE(fs::exists(dir / "w.ply"));
}

TEST_F(DressCli, WritesASkinnedGlbWithAMaterialPerPart) {
  const auto r = run_cli("dress --outfit female_casualsuit02,shoes02,bob02 --pose run01 --out " + (dir / "w.glb").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string bytes = read_text_file(dir / "w.glb");
  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromMemory(&m, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                          static_cast<unsigned>(bytes.size())))
      << err;
  ASSERT_EQ(m.meshes.size(), 1u);
  EXPECT_EQ(m.meshes[0].primitives.size(), 4u);  // body, suit, shoes, hair
  ASSERT_EQ(m.materials.size(), 4u);
  EXPECT_EQ(m.materials[2].name, "shoes02");
  EXPECT_EQ(m.skins.size(), 1u);
  EXPECT_EQ(m.animations.size(), 1u);  // the pose as a one-frame clip
}

TEST_F(DressCli, BadInputExitsTwoAndWritesNothing) {
  auto r = run_cli("dress --outfit no_such_thing --out " + (dir / "x.obj").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("unknown asset 'no_such_thing'"), std::string::npos) << r.output;
  r = run_cli("dress --outfit proxy741 --out " + (dir / "x.obj").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("proxy"), std::string::npos) << r.output;
  r = run_cli("dress --outfit shoes01 --out " + (dir / "x.stl").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_FALSE(fs::exists(dir / "x.obj"));
  EXPECT_FALSE(fs::exists(dir / "x.mtl"));
}

// `crowd --outfits` and `character --outfits` check the outfit file and its assets before
// anything else: one line naming the file and the entry, exit 2, no output folder.
TEST_F(DressCli, BadOutfitFilesExitTwoAndWriteNothing) {
  const fs::path bad = dir / "outfits.json";
  const std::string male = R"("male": {"hair": [{"asset": "short02"}]})";
  std::ofstream(bad) << R"({"female": {"hair": [{"asset": "bob01"}, {"asset": "bob9", "weight": 2}]}, )" << male << "}";
  for (const std::string verb : {"crowd no_model.npz --bvh no.bvh", "character no_model.npz"}) {
    auto r = run_cli(verb + " --outfits " + bad.string() + " --out " + (dir / "out").string());
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_NE(r.output.find("outfits.json': female.hair[1]: unknown asset 'bob9'"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir / "out"));
  }
  std::ofstream(bad) << R"({"female": {"hair": [{"asset": "bob01", "palette": "neon"}]}, )" << male << "}";
  auto r = run_cli("crowd no_model.npz --bvh no.bvh --outfits " + bad.string() + " --out " + (dir / "out").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("female.hair[0]: unknown palette 'neon'"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "out"));
}

}  // namespace
}  // namespace bodymodel
