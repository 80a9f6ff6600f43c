// The one id-to-file-name rule (core/io/file_names.h) as every verb that names files after data
// uses it (issue 40, round 3): ids that are paths, repeated ids whose renaming collided with
// another id ({1, 1, 1_2} wrote two meshes for three people), bytes that are not UTF-8.
#include <gtest/gtest.h>

#include <cctype>
#include <set>
#include <string>
#include <vector>

#include "core/io/file_names.h"

namespace bodymodel {
namespace {

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

void expect_distinct_plain(const std::vector<std::string>& in, const std::vector<std::string>& out) {
  ASSERT_EQ(out.size(), in.size());
  std::set<std::string> seen;
  for (size_t i = 0; i < out.size(); ++i) {
    EXPECT_EQ(file_name_problem(out[i]), "") << i << ": " << out[i];
    EXPECT_TRUE(seen.insert(lower(out[i])).second) << "two items share '" << out[i] << "'";
  }
}

TEST(FileNames, RenamedDuplicatesNeverTakeAnotherItemsName) {
  const std::vector<std::string> ids = {"1", "1", "1_2"};
  const auto names = unique_file_names(ids, "person");
  expect_distinct_plain(ids, names);
  EXPECT_EQ(names[0], "1");
  EXPECT_EQ(names[2], "1_2") << "the person whose id is 1_2 keeps it";
  EXPECT_EQ(names[1], "1_3");
  // Every order, and suffixes of suffixes, and sanitised names meeting plain ones.
  for (const std::vector<std::string>& case_ids :
       {std::vector<std::string>{"1_2", "1", "1"}, {"a", "a", "a", "a_2", "a_3", "a_2"}, {"a/b", "a_b", "a_b"},
        {"../x", "x", "/x", "x_2"}, {"A", "a", "a_2", "A_2"}, {"", "", "person_000"}}) {
    SCOPED_TRACE(case_ids.size());
    const auto out = unique_file_names(case_ids, "person");
    expect_distinct_plain(case_ids, out);
  }
}

TEST(FileNames, BytesThatAreNotUtf8AreRefusedOrReplaced) {
  EXPECT_TRUE(valid_utf8("körper"));
  EXPECT_TRUE(valid_utf8(""));
  for (const std::string bad : {"a\xff", "\xc3", "\xc0\xaf", "\xed\xa0\x80", "\xf4\x90\x80\x80", "\xe2\x82"}) {
    SCOPED_TRACE(bad);
    EXPECT_FALSE(valid_utf8(bad));
    EXPECT_NE(file_name_problem(bad), "");
    EXPECT_TRUE(valid_utf8(utf8_or_replaced(bad)));
    const std::string s = sanitized_file_name(bad, "x");
    EXPECT_EQ(file_name_problem(s), "") << s;
  }
  EXPECT_EQ(sanitized_file_name("m\xfcller", "x"), "m_ller");
  EXPECT_EQ(utf8_or_replaced("m\xfcller"), "m\xEF\xBF\xBDller");
  EXPECT_EQ(utf8_or_replaced("körper"), "körper");
  EXPECT_EQ(file_name_problem("a\xff"), "it holds bytes that are not UTF-8");
}

TEST(FileNames, PathsInIdsStayInTheirFolder) {
  const std::vector<std::string> ids = {"../../../../tmp/x/ESCAPED", "/tmp/x/ESCAPED", "a/b", "..", ".", "smith, j"};
  const auto names = unique_file_names(ids, "person");
  expect_distinct_plain(ids, names);
  EXPECT_EQ(names[0], "tmp_x_ESCAPED");
  EXPECT_EQ(names[1], "tmp_x_ESCAPED_2");
  EXPECT_EQ(names[2], "a_b");
  EXPECT_EQ(names[5], "smith, j") << "a comma is a plain file name; the CSV quotes it";
  // Long names stay within the limit with their suffix.
  const std::vector<std::string> long_ids(3, std::string(250, 'n'));
  const auto cut = unique_file_names(long_ids, "person");
  expect_distinct_plain(long_ids, cut);
}

}  // namespace
}  // namespace bodymodel
