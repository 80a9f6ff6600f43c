#include <gtest/gtest.h>

#include <fstream>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "core/io/off.h"
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

TEST(MeshIO, OffRoundTripAndVariants) {
  fixtures::TempDir dir;
  Mesh m = fixtures::uv_sphere(1.2345, 9, 17);
  write_mesh(dir / "a.off", m);
  EXPECT_EQ(read_text_file(dir / "a.off").rfind("OFF\n" + std::to_string(m.V.rows()) + " " +
                                                    std::to_string(m.F.rows()) + " 0\n", 0),
            0u);
  Mesh r = read_mesh(dir / "a.off");
  ASSERT_EQ(r.F, m.F);
  EXPECT_LT((r.V - m.V).cwiseAbs().maxCoeff(), 1e-8);
  // Counts on the header line, comments, blank lines, a quad (triangulated as a fan), COFF
  // colours, upper-case extension.
  write_raw(dir / "b.OFF",
            "OFF 5 2 0\n# a comment\n\n0 0 0\n1 0 0\n1 1 0 # trailing comment\n0 1 0\n0 0 1\n"
            "4 0 1 2 3\n3 0 1 4 255 0 0\n");
  Mesh q = read_mesh(dir / "b.OFF");
  EXPECT_EQ(q.V.rows(), 5);
  ASSERT_EQ(q.F.rows(), 3);
  EXPECT_EQ(q.F.row(1), Eigen::RowVector3i(0, 2, 3));
  write_raw(dir / "c.off", "COFF\n3 1 0\n0 0 0 1 1 1 1\n1 0 0 1 1 1 1\n0 1 0 1 1 1 1\n3 0 1 2\n");
  EXPECT_EQ(read_mesh(dir / "c.off").F.rows(), 1);
  // A point cloud from an OFF: its vertices.
  EXPECT_EQ(read_point_cloud(dir / "a.off").P.rows(), m.V.rows());
}

TEST(MeshIO, BadOffFilesNameTheLineAndTheProblem) {
  fixtures::TempDir dir;
  struct Case {
    std::string name, text, expect;
  };
  const std::vector<Case> cases = {
      {"few_vertices.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n",
       "ends after 3 vertices (the counts line declares 4 vertices and 1 faces)"},
      {"many_vertices.off", "OFF\n2 1 0\n0 0 0\n1 0 0\n0.5 1 0\n3 0 1 2\n",
       "face 0 starts with '0.5', expected its vertex count"},
      {"few_faces.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "ends after 1 faces"},
      {"many_faces.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 2 1\n",
       "line 7: unexpected data after the last face"},
      {"segment.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n",
       "face 0 has 2 vertices; a face needs at least 3"},
      {"short_face.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n",
       "declares 4 vertices but lists 3"},
      {"range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
       "line 6: face 0 refers to vertex 3, expected 0..2"},
      {"nan.off", "OFF\n3 1 0\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n",
       "line 4: vertex 1 has a NaN or infinite coordinate"},
      {"word.off", "OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n", "'x' is not a number"},
      {"counts.off", "OFF\nthree 1 0\n", "expected the counts line"},
      {"huge.off", "OFF\n2000000000 1 0\n0 0 0\n", "more than the file's"},
      {"binary.off", "OFF BINARY\n", "binary OFF is not supported"},
      {"empty.off", "", "empty file"},
      {"negative.off", "OFF\n-3 1 0\n", "expected the counts line"},
  };
  for (const auto& c : cases) {
    write_raw(dir / c.name, c.text);
    const std::string e = error_of([&] { read_mesh(dir / c.name); });
    EXPECT_NE(e.find(c.name), std::string::npos) << c.name << ": " << e;
    EXPECT_NE(e.find(c.expect), std::string::npos) << c.name << ": '" << e << "' lacks '"
                                                   << c.expect << "'";
  }
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
