// NaN coordinates fed to encode, decode, register and skin fit: each verb stops with one line
// "bodymodel: error: ..." that says what is not finite and where, exits 2, and writes nothing.
#include <gtest/gtest.h>

#include <fstream>

#include "core/io/atomic_write.h"
#include "core/io/libigl_formats.h"
#include "core/io/mesh_io.h"
#include "core/io/npz.h"
#include "reliability/cli_helpers.h"
#include "support/fixtures.h"

namespace bodymodel {
namespace {

using namespace reliability;

// An OBJ of `m` written by hand with vertex `bad` set to NaN (the library's writer refuses NaN;
// files from elsewhere may hold it).
void write_obj_with_nan(const fs::path& p, const Mesh& m, int bad) {
  std::ofstream f(p);
  for (int i = 0; i < m.V.rows(); ++i)
    if (i == bad) f << "v nan 0 0\n";
    else f << "v " << m.V(i, 0) << " " << m.V(i, 1) << " " << m.V(i, 2) << "\n";
  for (int i = 0; i < m.F.rows(); ++i)
    f << "f " << m.F(i, 0) + 1 << " " << m.F(i, 1) + 1 << " " << m.F(i, 2) + 1 << "\n";
}

// Runs the verb; expects exit 2 and exactly one error line containing every `needles` entry.
void expect_one_line_error(const std::vector<std::string>& args, const fs::path& log,
                           const std::vector<std::string>& needles) {
  std::string out;
  const int code = run_bodymodel(args, log, &out);
  EXPECT_EQ(code, 2) << out;
  const auto lines = error_lines(out);
  ASSERT_EQ(lines.size(), 1u) << out;
  for (const auto& n : needles) EXPECT_NE(lines[0].find(n), std::string::npos) << lines[0] << " lacks " << n;
}

TEST(NanInputs, EncodeAndDecodeRefuseNaN) {
  fixtures::TempDir dir;
  const Mesh a = fixtures::uv_sphere(100, 8, 12);
  Mesh b = a;
  b.V.col(1) *= 1.3;
  write_mesh(dir / "a.obj", a.V, a.F);
  write_mesh(dir / "b.obj", b.V, b.F);
  write_obj_with_nan(dir / "bad.obj", b, 7);
  expect_one_line_error({"encode", (dir / "a.obj").string(), (dir / "bad.obj").string(), "--out",
                         (dir / "enc.npz").string()},
                        dir / "log", {"bad.obj", "NaN"});
  EXPECT_FALSE(fs::exists(dir / "enc.npz"));
  expect_one_line_error({"encode", (dir / "bad.obj").string(), (dir / "a.obj").string(), "--out",
                         (dir / "enc.npz").string()},
                        dir / "log", {"bad.obj", "NaN"});  // as the template
  EXPECT_FALSE(fs::exists(dir / "enc.npz"));

  std::string out;
  ASSERT_EQ(run_bodymodel({"encode", (dir / "a.obj").string(), (dir / "b.obj").string(), "--out",
                           (dir / "enc.npz").string()},
                          dir / "log", &out),
            0)
      << out;
  const Npz good = Npz::load(dir / "enc.npz");
  for (const std::string key : {"encodings", "mean", "template_vertices"}) {
    Npz z = good;
    Eigen::MatrixXd M = z.matrix(key);
    M(0, M.cols() > 1 ? 1 : 0) = std::numeric_limits<double>::quiet_NaN();
    if (key == "mean") z.put(key, Eigen::VectorXd(M.col(0)));
    else z.put(key, M);
    z.save(dir / "nan.npz");
    SCOPED_TRACE(key);
    // The message names the file, the array and, for an encoding row, the item it decodes to.
    std::vector<std::string> needles = {"nan.npz", "'" + key + "'", "NaN"};
    if (key == "encodings") needles.push_back("row 0 ('a')");
    expect_one_line_error({"decode", (dir / "nan.npz").string(), "--out", (dir / "dec").string()},
                          dir / "log", needles);
    EXPECT_TRUE(files_under(dir / "dec").empty());
  }
}

TEST(NanInputs, SkinFitRefusesNaN) {
  fixtures::TempDir dir;
  const Mesh rest = fixtures::cylinder(20, 100, 8, 4);
  fs::create_directories(dir / "poses");
  fs::create_directories(dir / "T");
  write_mesh(dir / "rest.obj", rest.V, rest.F);
  Eigen::MatrixXd T(8, 3);  // two bones, identity
  T << 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0;
  for (int p = 0; p < 3; ++p) {
    Mesh m = rest;
    m.V.col(0) += Eigen::VectorXd::Constant(m.V.rows(), 5.0 * p);
    T(7, 0) = 5.0 * p;
    T(3, 0) = 5.0 * p;
    const std::string name = "p" + std::to_string(p);
    write_mesh(dir / "poses" / (name + ".obj"), m.V, m.F);
    std::ofstream f(dir / "T" / (name + ".Tmat"));
    f << T.format(Eigen::IOFormat(Eigen::FullPrecision, Eigen::DontAlignCols, " ", "\n")) << "\n";
  }
  const std::vector<std::string> fit = {"skin", "fit", "--poses", (dir / "poses").string(),
                                        "--transforms", (dir / "T").string(), "--method", "ssd",
                                        "--out", (dir / "rig.npz").string()};
  auto with_rest = [&](const fs::path& r) {
    std::vector<std::string> a = fit;
    a.push_back("--rest");
    a.push_back(r.string());
    return a;
  };
  write_obj_with_nan(dir / "nan_rest.obj", rest, 3);
  expect_one_line_error(with_rest(dir / "nan_rest.obj"), dir / "log", {"nan_rest.obj", "NaN"});
  EXPECT_FALSE(fs::exists(dir / "rig.npz"));

  write_obj_with_nan(dir / "poses" / "p1.obj", rest, 5);
  expect_one_line_error(with_rest(dir / "rest.obj"), dir / "log", {"p1.obj", "NaN"});
  EXPECT_FALSE(fs::exists(dir / "rig.npz"));
  write_mesh(dir / "poses" / "p1.obj", rest.V, rest.F);

  write_text_file(dir / "T" / "p2.Tmat", "1 0 0\n0 1 0\n0 0 1\nnan 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 0\n");
  expect_one_line_error(with_rest(dir / "rest.obj"), dir / "log", {"p2.Tmat", "not finite"});
  EXPECT_FALSE(fs::exists(dir / "rig.npz"));
}

TEST(NanInputs, RegisterRefusesNaNScansAndLandmarks) {
  fixtures::TempDir dir;
  const fs::path db = dir / "db";
  fs::create_directories(db / "scans");
  write_text_file(db / "scans.csv", "scan_id,subject_id,pose\nx,s0,standard\n");
  const Mesh s = fixtures::uv_sphere(300, 12, 16);
  {
    std::ofstream f(db / "scans" / "x.ply");
    f << "ply\nformat ascii 1.0\nelement vertex " << s.V.rows()
      << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    for (int i = 0; i < s.V.rows(); ++i)
      f << (i == 4 ? std::string("nan") : std::to_string(s.V(i, 0))) << " " << s.V(i, 1) << " "
        << s.V(i, 2) << "\n";
  }
  write_text_file(db / "scans" / "x.landmarks.json", "{}");
  const std::vector<std::string> reg = {"register", db.string(), "--out", (dir / "reg").string()};
  expect_one_line_error(reg, dir / "log", {"x.ply", "NaN"});
  EXPECT_FALSE(fs::exists(dir / "reg" / "x.ply"));
  EXPECT_FALSE(fs::exists(dir / "reg" / "x.pose.csv"));

  write_point_cloud(db / "scans" / "x.ply", PointCloud{s.V, Eigen::MatrixX3d()});
  // JSON has no NaN; an overflowing number is the nearest a landmark file can get.
  write_text_file(db / "scans" / "x.landmarks.json", R"({"chin": [0, 1e999, 0]})");
  expect_one_line_error(reg, dir / "log", {"x.landmarks.json"});
  EXPECT_FALSE(fs::exists(dir / "reg" / "x.ply"));
}

}  // namespace
}  // namespace bodymodel
