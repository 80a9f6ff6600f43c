#include <gtest/gtest.h>

#include <fstream>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "core/io/npz.h"
#include "support/fixtures.h"

using namespace bodymodel;
namespace fs = std::filesystem;

namespace {
void write_raw(const fs::path& p, const std::string& s) {
  std::ofstream(p, std::ios::binary) << s;
}
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(MeshIO, ObjAndPlyRoundTrip) {
  fixtures::TempDir dir;
  Mesh m = fixtures::uv_sphere(123.456, 9, 17);
  for (std::string name : {"a.obj", "b.ply"}) {
    write_mesh(dir / name, m);
    Mesh r = read_mesh(dir / name);
    ASSERT_EQ(r.V.rows(), m.V.rows());
    ASSERT_EQ(r.F, m.F);
    // OBJ keeps 9 significant digits; binary PLY stores float32.
    EXPECT_LT((r.V - m.V).cwiseAbs().maxCoeff(), name == "a.obj" ? 1e-6 : 1e-4) << name;
  }
  write_mesh(dir / "c.ply", m.V, m.F, Eigen::MatrixX3d::Constant(m.V.rows(), 3, 0.5), true);
  Mesh c = read_mesh(dir / "c.ply");
  EXPECT_EQ(c.F, m.F);
  EXPECT_LT((c.V - m.V).cwiseAbs().maxCoeff(), 1e-5);
}

TEST(MeshIO, PointCloudWithNormalsRoundTrip) {
  fixtures::TempDir dir;
  PointCloud pc;
  pc.P = Eigen::MatrixX3d::Random(100, 3);
  pc.N = pc.P.rowwise().normalized();
  write_point_cloud(dir / "p.ply", pc);
  PointCloud r = read_point_cloud(dir / "p.ply");
  ASSERT_TRUE(r.has_normals());
  EXPECT_LT((r.P - pc.P).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((r.N - pc.N).cwiseAbs().maxCoeff(), 1e-6);
}

TEST(MeshIO, QuadsAreTriangulatedAndGroupsKept) {
  fixtures::TempDir dir;
  write_raw(dir / "q.obj",
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\ng body\nf 1/1 2/2 3/3 4/4\ng other\n"
            "f 1 2 5\n");
  ObjContents obj = read_obj_contents(dir / "q.obj");
  ASSERT_EQ(obj.polygons.size(), 2u);
  EXPECT_EQ(obj.group_names[obj.polygon_group[0]], "body");
  EXPECT_EQ(obj.group_names[obj.polygon_group[1]], "other");
  Mesh m = read_mesh(dir / "q.obj");
  EXPECT_EQ(m.F.rows(), 3);
}

TEST(MeshIO, BadFilesGiveOneLineErrorsNamingFileAndLine) {
  fixtures::TempDir dir;
  write_raw(dir / "trunc.obj", "v 0 0 0\nv 1 0 0\nv 1 1");
  std::string e = error_of([&] { read_mesh(dir / "trunc.obj"); });
  EXPECT_NE(e.find("trunc.obj' line 3"), std::string::npos) << e;
  write_raw(dir / "range.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 4\n");
  e = error_of([&] { read_mesh(dir / "range.obj"); });
  EXPECT_NE(e.find("line 4"), std::string::npos) << e;
  EXPECT_NE(e.find("vertex 4"), std::string::npos) << e;
  write_raw(dir / "nan.obj", "v 0 0 nope\n");
  EXPECT_NE(error_of([&] { read_mesh(dir / "nan.obj"); }).find("not a number"), std::string::npos);
  write_raw(dir / "x.stl", "solid");
  EXPECT_NE(error_of([&] { read_mesh(dir / "x.stl"); }).find("unknown mesh format"),
            std::string::npos);
  EXPECT_NE(error_of([&] { read_mesh(dir / "missing.obj"); }).find("missing.obj"),
            std::string::npos);
  EXPECT_NE(error_of([&] { read_mesh(dir.path); }).find("folder"), std::string::npos);
  // Binary PLY cut short.
  Mesh m = fixtures::box(1, 1, 1);
  write_mesh(dir / "b.ply", m);
  std::string bytes = read_text_file(dir / "b.ply");
  write_raw(dir / "cut.ply", bytes.substr(0, bytes.size() - 20));
  EXPECT_NE(error_of([&] { read_mesh(dir / "cut.ply"); }).find("cut.ply"), std::string::npos);
  write_raw(dir / "badface.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
            "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n");
  EXPECT_NE(error_of([&] { read_mesh(dir / "badface.ply"); }).find("vertex 9"), std::string::npos);
}

TEST(AtomicWrite, FailureLeavesNoFileUnderTheFinalName) {
  fixtures::TempDir dir;
  EXPECT_THROW(write_atomically(dir / "out.bin",
                                [](std::ostream& o) {
                                  o << "partial";
                                  throw InputError("boom");
                                }),
               InputError);
  EXPECT_FALSE(fs::exists(dir / "out.bin"));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path), fs::directory_iterator()), 0);
  EXPECT_THROW(write_text_file(dir / "no/such/folder/x.txt", "x"), InputError);
}

TEST(Npz, RoundTripAllKinds) {
  fixtures::TempDir dir;
  Npz z;
  Eigen::MatrixXd A = Eigen::MatrixXd::Random(4, 7);
  Eigen::VectorXi ids(3);
  ids << -1, 5, 1 << 30;
  z.put("A", A);
  z.put("ids", ids);
  z.put("scale", 2.5);
  z.put_text("meta", R"({"version": 1, "name": "héllo"})");
  z.save(dir / "m.npz");
  Npz r = Npz::load(dir / "m.npz");
  EXPECT_EQ(r.matrix("A"), A);
  EXPECT_EQ(r.int_vector("ids"), ids);
  EXPECT_EQ(r.scalar("scale"), 2.5);
  EXPECT_EQ(r.text("meta"), R"({"version": 1, "name": "héllo"})");
  EXPECT_THROW(r.matrix("nope"), InputError);
}

TEST(Npz, CorruptFilesAreRejected) {
  fixtures::TempDir dir;
  Npz z;
  z.put("A", Eigen::MatrixXd(Eigen::MatrixXd::Ones(3, 3)));
  std::string bytes = z.serialize();
  EXPECT_THROW(Npz::parse(bytes.substr(0, bytes.size() / 2)), InputError);
  std::string flipped = bytes;
  flipped[30 + 5 + 10] ^= 0x55;  // inside the member's data ("A.npy"): inflate or the CRC must catch it
  EXPECT_THROW(Npz::parse(flipped), InputError);
  EXPECT_THROW(Npz::parse("PK not really a zip file at all......"), InputError);
}
