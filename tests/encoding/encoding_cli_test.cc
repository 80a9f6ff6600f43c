// Command-line tests: encode → decode round trip through files, interpolate, bad input.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "core/data_path.h"
#include "core/geometry.h"
#include "core/io/mesh_io.h"
#include "core/io/npz.h"
#include "encoding_test_util.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct CliResult {
  int code;
  std::string err;
};

CliResult run(const std::string& args, const fs::path& dir) {
  const fs::path err = dir / "stderr.txt";
  const std::string cmd = std::string(BODYMODEL_EXE) + " " + args + " 2> " + err.string() + " > /dev/null";
  const int status = std::system(cmd.c_str());
  std::ifstream in(err);
  std::stringstream ss;
  ss << in.rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ss.str()};
}

class EncodingCli : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(BODYMODEL_EXE)) GTEST_SKIP() << "bodymodel not built";
    dir_ = fs::temp_directory_path() / ("bodymodel_encoding_cli_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    if (!dir_.empty()) fs::remove_all(dir_, ec);
  }
  fs::path dir_;
};

std::string horse(int i) {
  char name[64];
  std::snprintf(name, sizeof name, "animations/horse-gallop/horse-gallop-%02d.obj", i);
  return data_file(name).string();
}

TEST_F(EncodingCli, EncodeDecodeRoundTripThroughFiles) {
  const std::string npz = (dir_ / "enc.npz").string();
  CliResult r = run("encode " + horse(1) + " " + horse(7) + " " + horse(30) + " --out " + npz, dir_);
  ASSERT_EQ(r.code, 0) << r.err;
  const Npz file = Npz::load(npz);
  for (const char* key : {"encodings", "mean", "template_vertices", "template_faces", "names", "layout"})
    EXPECT_TRUE(file.has(key)) << key;
  EXPECT_EQ(file.matrix("encodings").rows(), 3);
  EXPECT_EQ(file.matrix("encodings").cols(), 15 * 16843);
  r = run("decode " + npz + " --template " + horse(1) + " --out " + (dir_ / "dec").string(), dir_);
  ASSERT_EQ(r.code, 0) << r.err;
  for (int i : {1, 7, 30}) {
    const Mesh original = read_mesh(horse(i));
    const Mesh decoded = read_mesh(dir_ / "dec" / fs::path(horse(i)).filename());
    ASSERT_EQ(decoded.V.rows(), original.V.rows());
    // OBJ files hold ~9 significant digits, so the file round trip is exact to ~1e-8.
    EXPECT_LT(testing::max_error_after_alignment(decoded.V, original.V) /
                  bounding_box_diagonal(original.V), 1e-6) << "frame " << i;
  }
}

TEST_F(EncodingCli, InterpolateWritesStepsAndRejectsBadInput) {
  CliResult r = run("interpolate " + horse(1) + " " + horse(20) + " --steps 3 --out " +
                  (dir_ / "rre").string(), dir_);
  ASSERT_EQ(r.code, 0) << r.err;
  for (int s = 0; s < 3; ++s) EXPECT_TRUE(fs::exists(dir_ / "rre" / ("rre_00" + std::to_string(s) + ".obj")));
  // The ends reproduce the inputs.
  const Mesh end = read_mesh(dir_ / "rre" / "rre_002.obj");
  EXPECT_LT(testing::max_error_after_alignment(end.V, read_mesh(horse(20)).V), 1e-4);
  // Wrong topology: a camel against the horse template → exit 2 and a one-line message.
  const std::string camel = data_file("animations/camel-poses/camel-01.obj").string();
  r = run("encode " + horse(1) + " " + camel + " --out " + (dir_ / "bad.npz").string(), dir_);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("expected 8431 vertices"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "bad.npz"));
  // Non-manifold template (the camel has edges shared by 4 triangles).
  r = run("interpolate " + camel + " " + camel + " --out " + (dir_ / "x").string(), dir_);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("non-manifold"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace bodymodel
