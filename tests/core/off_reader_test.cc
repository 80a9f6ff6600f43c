// The OFF reader (SCAPE and FAUST registrations are OFF): a real file's layout, and one clear
// error for each way a file can be wrong.
#include <gtest/gtest.h>

#include <fstream>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/mesh_io.h"
#include "support/fixtures.h"

using namespace bodymodel;

namespace {
std::string error_of(const std::string& text) {
  try {
    parse_mesh(text, "off", "t.off");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(OffReader, ReadsTrianglesCommentsAndCountsOnTheHeaderLine) {
  const std::string a = "OFF\n# a comment\n4 2 5\n0 0 0\n1 0 0\n0 1 0\n0 0 1.5  # apex\n\n3 0 1 2\n3 0 2 3\n";
  const Mesh m = parse_mesh(a, "off", "a.off");
  ASSERT_EQ(m.V.rows(), 4);
  ASSERT_EQ(m.F.rows(), 2);
  EXPECT_EQ(m.V(3, 2), 1.5);
  EXPECT_EQ(m.F(1, 0), 0);
  EXPECT_EQ(m.F(1, 2), 3);
  const Mesh b = parse_mesh("OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 2 1 0\n", "off", "b.off");
  EXPECT_EQ(b.F(0, 0), 2);
  // Through read_mesh / parse_mesh by extension, like the OBJ and PLY readers.
  fixtures::TempDir dir;
  std::ofstream(dir / "c.off") << a;
  EXPECT_EQ(read_mesh(dir / "c.off").F, m.F);
}

TEST(OffReader, RejectsBadFilesWithOneLineNamingTheLine) {
  EXPECT_NE(error_of("").find("empty file"), std::string::npos);
  // Counts the file cannot hold are refused before anything is allocated.
  EXPECT_NE(error_of("COFF\n3 1 0\n").find("more than the file's"), std::string::npos);
  EXPECT_NE(error_of("OFF\n").find("counts line"), std::string::npos);
  EXPECT_NE(error_of("OFF\nx 1 0\n").find("expected the counts line"), std::string::npos);
  EXPECT_NE(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n").find("ends after 2 vertices"), std::string::npos);
  EXPECT_NE(error_of("OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n").find("line 4: vertex 1 needs 3 coordinates"),
            std::string::npos);
  EXPECT_NE(error_of("OFF\n3 1 0\n0 0 0\n1 0 nan?\n0 1 0\n3 0 1 2\n").find("is not a number"), std::string::npos);
  // core/io/off.h keeps polygons (read_mesh triangulates them as fans, as for OBJ and PLY) and
  // skips a face's colour; a face of fewer than 3 vertices is an error.
  EXPECT_EQ(error_of("OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2 3\n"), "");
  EXPECT_EQ(parse_mesh("OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2 3\n", "off", "q.off").F.rows(), 2);
  EXPECT_NE(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n").find("a face needs at least 3"),
            std::string::npos);
  EXPECT_NE(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 1 2 3\n").find("0-based"), std::string::npos);
  EXPECT_EQ(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 255 0 0\n"), "");
  EXPECT_NE(error_of("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").find("ends after 1 faces"),
            std::string::npos);
  EXPECT_NE(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n").find("unexpected data after the last face"), std::string::npos);
  // The message names the file and the line.
  EXPECT_NE(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n").find("'t.off' line 6"), std::string::npos);
}

TEST(OffReader, ReadsScape) {
  const Mesh m = read_mesh(data_file("scape/mesh000.off"));
  EXPECT_EQ(m.V.rows(), 12500);
  EXPECT_EQ(m.F.rows(), 24998);
  EXPECT_EQ(m.F.minCoeff(), 0);
  EXPECT_EQ(m.F.maxCoeff(), 12499);
}
