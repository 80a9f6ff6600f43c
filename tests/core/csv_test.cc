// CSV rows (core/io/csv.h): the cells as the project's readers expect them.
#include <gtest/gtest.h>

#include <string>
#include <vector>

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

}  // namespace
}  // namespace bodymodel
