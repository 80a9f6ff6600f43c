// CSV rows (core/io/csv.h): the cells as the project's readers expect them, and the one
// dialect every table is written and read in (issue 40, round 3: ids holding commas broke rows;
// a spreadsheet's byte-order mark hid the first column).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "core/error.h"
#include "core/io/csv.h"

namespace bodymodel {
namespace {

using Cells = std::vector<std::string>;

TEST(SplitCsvLine, CellsTrimmedOfCarriageReturnsAndTrailingSpacesWithEmptyCellsKept) {
  EXPECT_EQ(split_csv_line("mesh,subject,pose"), (Cells{"mesh", "subject", "pose"}));
  EXPECT_EQ(split_csv_line("a,,b"), (Cells{"a", "", "b"}));
  EXPECT_EQ(split_csv_line("a,b,"), (Cells{"a", "b", ""})) << "a trailing comma is an empty last cell";
  EXPECT_EQ(split_csv_line("a ,b\r"), (Cells{"a", "b"})) << "Windows line ends and padding";
  EXPECT_EQ(split_csv_line(" x"), (Cells{" x"})) << "leading spaces are part of the cell";
  EXPECT_EQ(split_csv_line("one"), (Cells{"one"}));
  EXPECT_EQ(split_csv_line("\r"), (Cells{""}));
  EXPECT_TRUE(split_csv_line("").empty());
}

TEST(Csv, FieldsAreQuotedOnlyWhenTheyMustBe) {
  EXPECT_EQ(csv_field("plain"), "plain");
  EXPECT_EQ(csv_field(""), "");
  EXPECT_EQ(csv_field("smith, j"), "\"smith, j\"");
  EXPECT_EQ(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(csv_field("two\nlines"), "\"two\nlines\"");
  EXPECT_EQ(csv_field("cr\r"), "\"cr\r\"");
  EXPECT_EQ(csv_field("trailing "), "\"trailing \"") << "a read trims unquoted trailing spaces";
  EXPECT_EQ(csv_row({"a", "b,c", ""}), "a,\"b,c\",");
  EXPECT_EQ(csv_field("\xEF\xBB\xBF" "x"), "\"\xEF\xBB\xBF" "x\"") << "a mark a read would drop";
}

TEST(Csv, EveryFieldRoundTrips) {
  const std::vector<std::string> hostile = {
      "smith, j", "\"", "\"\"", "a\"b", "multi\nline\r\nfield", " lead", "trail ", ",", "", "\xff\xfe",
      std::string("nul\0x", 5), "\xEF\xBB\xBF" "bom"};
  std::string text = csv_row({"id", "value"}) + "\n";
  for (const auto& h : hostile) text += csv_row({h, "1"}) + "\n";
  const auto rows = parse_csv(text, "t.csv");
  ASSERT_EQ(rows.size(), hostile.size() + 1);
  for (size_t i = 0; i < hostile.size(); ++i) {
    ASSERT_EQ(rows[i + 1].fields.size(), 2u) << i;
    EXPECT_EQ(rows[i + 1].fields[0], hostile[i]) << i;
    EXPECT_EQ(rows[i + 1].fields[1], "1") << i;
  }
}

TEST(Csv, ReaderTakesQuotesBomCrlfAndCountsLines) {
  const std::string text = "\xEF\xBB\xBFid,name\r\n1,\"smith, j\"\r\n\r\n2,\"two\r\nlines\"\r\n3,plain \r\n";
  const auto rows = parse_csv(text, "people.csv");
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[0].fields, (Cells{"id", "name"})) << "the byte-order mark is not part of the first name";
  EXPECT_EQ(rows[1].fields, (Cells{"1", "smith, j"}));
  EXPECT_EQ(rows[2].fields, (Cells{"2", "two\r\nlines"}));
  EXPECT_EQ(rows[3].fields, (Cells{"3", "plain"}));
  EXPECT_EQ(rows[0].line, 1);
  EXPECT_EQ(rows[1].line, 2);
  EXPECT_EQ(rows[2].line, 4) << "the blank line counts";
  EXPECT_EQ(rows[3].line, 6) << "the quoted line end counts";
  // A line read on its own (getline readers) loses the mark and understands quotes too.
  EXPECT_EQ(split_csv_line("\xEF\xBB\xBFmesh,subject,pose"), (Cells{"mesh", "subject", "pose"}));
  EXPECT_EQ(split_csv_line("\"a,b\",c"), (Cells{"a,b", "c"}));
  EXPECT_EQ(split_csv_line("\"open,c"), (Cells{"open,c"})) << "an open quote runs to the end of the line";
}

TEST(Csv, AnOpenQuoteIsNamedWithItsLine) {
  try {
    parse_csv("id,name\n1,ok\n2,\"never closed\n3,x\n", "p.csv");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "'p.csv' line 3: a quoted field is not closed (a '\"' without its closing '\"')");
  }
}

}  // namespace
}  // namespace bodymodel
