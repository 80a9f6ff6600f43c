// Names read from input files never reach the file system unsanitised (issue 27, defect 1): the
// name checks and the sanitiser (core/io/file_names.h), and the encoding file reader that turns
// stored mesh names into the file names `decode` writes (encoding/encoding_file.h).
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "core/error.h"
#include "core/io/file_names.h"
#include "encoding/encoding_file.h"
#include "fuzz/tiny_files.h"

namespace bodymodel {
namespace {

const std::vector<std::string> kHostile = {
    "../../../../tmp/escaped", "/tmp/abs", "a/b", "a\\b", std::string("nul\0x", 5), "..", ".", "",
    ".hidden", "tab\there", "C:evil", "\x1b[31mred", std::string(300, 'n'), "../", "/",
};

TEST(FileNames, HostileNamesAreRefusedOrMadePlain) {
  for (const auto& n : kHostile) {
    SCOPED_TRACE(n);
    EXPECT_NE(file_name_problem(n), "");
    EXPECT_THROW(check_file_name(n, "scans.csv:2", "scan id"), InputError);
    const std::string s = sanitized_file_name(n, "fallback");
    EXPECT_EQ(file_name_problem(s), "") << s;
  }
  for (const std::string ok : {"s000_p0", "horse-gallop-01", "körper", "a.b", "a..b"}) {
    EXPECT_EQ(file_name_problem(ok), "") << ok;
    EXPECT_EQ(sanitized_file_name(ok, "x"), ok);
  }
  EXPECT_EQ(sanitized_file_name("../../../../tmp/escaped", "x"), "tmp_escaped");
  EXPECT_EQ(sanitized_file_name("/tmp/abs", "x"), "tmp_abs");
  EXPECT_EQ(sanitized_file_name(".hidden", "x"), "hidden");
  EXPECT_EQ(sanitized_file_name("/", "x"), "x");
  EXPECT_EQ(sanitized_file_name("..", "x"), "x");
  EXPECT_EQ(sanitized_file_name(std::string("nul\0x", 5), "x"), "nul_x");
  try {
    check_file_name(std::string("a\0b", 3), "scans.csv:3", "scan id");
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "scans.csv:3: scan id 'a\\x00b' is not a plain file name (it holds a NUL character)");
  }
}

TEST(FileNames, UniqueNamesKeepEveryItem) {
  const auto names = unique_file_names({"body", "body", "Body", "", "/", "body_2"}, "decoded");
  ASSERT_EQ(names.size(), 6u);
  std::set<std::string> lower;
  for (auto n : names) {
    EXPECT_EQ(file_name_problem(n), "") << n;
    for (auto& c : n) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    lower.insert(n);
  }
  EXPECT_EQ(lower.size(), names.size());  // distinct even on a case-insensitive file system
  EXPECT_EQ(names[0], "body");
  EXPECT_EQ(names[1], "body_3");  // "body_2" is the last item's own name (issue 40: 1, 1, 1_2)
  EXPECT_EQ(names[5], "body_2");
  EXPECT_EQ(names[3], "decoded_003");
}

TEST(FileNames, PathLabelKeepsOnlyTheLastComponent) {
  EXPECT_EQ(path_label("/home/someone/db/"), "db");
  EXPECT_EQ(path_label("../reg"), "reg");
  EXPECT_EQ(path_label("model.npz"), "model.npz");
  EXPECT_EQ(path_label("/"), "");
  EXPECT_EQ(path_label("a/b/.."), "a");
}

// An encoding file (a tetrahedron template, 3 rows) whose names are `names` (one per line).
Npz encoding_with_names(const std::string& names) {
  EncodingFile e;
  e.template_vertices = tiny::tetra_vertices();
  e.template_faces = tiny::tetra_faces();
  e.encodings = Eigen::MatrixXd::Zero(3, 60);
  e.mean = Eigen::VectorXd::Zero(60);
  Npz z = encoding_to_npz(e, "layout");
  z.put_text("names", names);
  return z;
}

TEST(FileNames, EncodingFileNamesArePlainAndDistinct) {
  const EncodingFile e = parse_encoding_npz(
      encoding_with_names("../../../../tmp/escaped\n/tmp/abs\nbody\n"), "x.npz");
  ASSERT_EQ(e.file_names.size(), 3u);
  EXPECT_EQ(e.names[0], "../../../../tmp/escaped");  // as stored
  for (const auto& n : e.file_names) EXPECT_EQ(file_name_problem(n), "") << n;
  // Two rows of one name (encode of body.obj and body.ply) give two files.
  const EncodingFile twice = parse_encoding_npz(encoding_with_names("body\nbody\n"), "x.npz");
  EXPECT_EQ(twice.file_names, (std::vector<std::string>{"body", "body_2", "decoded_002"}));
  // Separators, more names than rows, Windows line ends.
  const EncodingFile odd = parse_encoding_npz(encoding_with_names("a/b\\c\r\nx\r\ny\r\nz\r\n"), "x.npz");
  EXPECT_EQ(odd.file_names, (std::vector<std::string>{"a_b_c", "x", "y"}));
  // A NUL in a name: made '_' in memory; in a file it ends the stored text (numpy strings are
  // NUL-padded), and the rows after it get numbers.
  const Npz with_nul = encoding_with_names(std::string("a\0/etc/x\nb\n", 11));
  EXPECT_EQ(parse_encoding_npz(with_nul, "x.npz").file_names, (std::vector<std::string>{"a__etc_x", "b", "decoded_002"}));
  const EncodingFile nul = parse_encoding_npz(Npz::parse(with_nul.serialize(), "x.npz"), "x.npz");
  EXPECT_EQ(nul.file_names, (std::vector<std::string>{"a", "decoded_001", "decoded_002"}));
}

TEST(FileNames, EncodingFileArraysAreCheckedBeforeUse) {
  Npz z = encoding_with_names("a\nb\nc\n");
  Eigen::MatrixXi F = z.int_matrix("template_faces");
  F(1, 2) = 9;
  z.put("template_faces", F);
  try {
    parse_encoding_npz(z, "x.npz");
    ADD_FAILURE() << "accepted a face past the vertices";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'template_faces' row 1 names vertex 9"), std::string::npos) << e.what();
  }
  Npz w = encoding_with_names("a\nb\nc\n");
  w.put("encodings", Eigen::MatrixXd(Eigen::MatrixXd::Zero(3, 59)));
  EXPECT_THROW(parse_encoding_npz(w, "x.npz"), InputError);
}

}  // namespace
}  // namespace bodymodel
