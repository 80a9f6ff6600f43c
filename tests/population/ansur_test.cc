// ANSUR II files (population/ansur.h): the survey's units, bad files refused naming the row and
// column, and the regression study on the shared soldiers (`eval-regressors --table`).
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <sstream>

#include "core/data_path.h"
#include "core/io/atomic_write.h"
#include "population/ansur.h"
#include "support/fixtures.h"
#include "support/input_error.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

const std::string kHeader = "subjectid,chestcircumference,stature,weightkg,Gender,Age,Branch\n";

std::string message_of(const fs::path& file, const std::string& text, const std::vector<std::string>& required = {}) {
  write_text_file(file, text);
  return testing::input_error_of([&] { read_ansur(file, required); });
}

TEST(Ansur, ReadsTheSurveysUnits) {
  fixtures::TempDir d;
  const fs::path f = d.path / "a.csv";
  write_text_file(f, kHeader + "1,1010,1780,815,Male,30,Army\n2,920,1630,602,Female,25,Army\n");
  const AnsurTable t = read_ansur(f, {"stature", "weightkg"});
  write_text_file(d.path / "b.csv", "SubjectId,stature,weightkg,Gender\n7,1630,602,Female\n");  // the women's file
  EXPECT_EQ(read_ansur(d.path / "b.csv").ids, (std::vector<std::string>{"7"}));
  ASSERT_EQ(t.ids, (std::vector<std::string>{"1", "2"}));
  EXPECT_EQ(t.male, (std::vector<int>{1, 0}));
  EXPECT_DOUBLE_EQ(t.values(0, t.column("weightkg")), 81.5);  // tenths of a kilogram
  EXPECT_DOUBLE_EQ(t.values(1, t.column("stature")), 1630);  // millimetres, as written
  EXPECT_THROW(t.column("Branch"), InputError);               // not a number: not a column of values
}

TEST(Ansur, BadFilesNameTheRowAndColumn) {
  fixtures::TempDir d;
  const fs::path f = d.path / "a.csv";
  EXPECT_NE(message_of(f, "subjectid,chest,stature,weightkg,Gender,Age\n1,1010,1780,815,Male,30\n",
                       {"chestcircumference"})
                .find("no column 'chestcircumference'"),
            std::string::npos);
  const std::string kg = message_of(f, kHeader + "1,1010,1780,81.5,Male,30,Army\n2,920,1630,60.2,Female,25,Army\n");
  EXPECT_NE(kg.find("column 'weightkg'"), std::string::npos) << kg;
  EXPECT_NE(kg.find("tenths of a kilogram"), std::string::npos) << kg;
  const std::string tall = message_of(f, kHeader + "1,1010,1780,815,Male,30,Army\n2,920,16300,602,Female,25,Army\n");
  EXPECT_NE(tall.find("line 3, column 'stature'"), std::string::npos) << tall;
  const std::string word = message_of(f, kHeader + "1,1010,1780,815,Male,30,Army\n2,x,1630,602,Female,25,Army\n");
  EXPECT_NE(word.find("line 3, column 'chestcircumference': 'x' is not a number"), std::string::npos) << word;
  const std::string sex = message_of(f, kHeader + "1,1010,1780,815,M,30,Army\n");
  EXPECT_NE(sex.find("column 'Gender'"), std::string::npos) << sex;
  EXPECT_NE(message_of(f, "id,stature\n1,1700\n").find("not an ANSUR II file"), std::string::npos);
}

fs::path ansur_file(const char* name) { return data_file("anthropometry") / "ansur2" / name; }

TEST(AnsurData, TheSharedSoldiersReadInTheirUnits) {
  const fs::path men = ansur_file("ansur2_male.csv");
  if (!fs::exists(men)) GTEST_SKIP() << men << " not found";
  const AnsurTable t = read_ansur(men, {"stature", "weightkg", "chestcircumference"});
  EXPECT_GT(t.values.rows(), 2000);
  const double weight = t.values.col(t.column("weightkg")).mean(), stature = t.values.col(t.column("stature")).mean();
  EXPECT_GT(weight, 70);  // US Army men: about 85 kg and 1.76 m on average
  EXPECT_LT(weight, 100);
  EXPECT_GT(stature, 1700);
  EXPECT_LT(stature, 1820);
  for (int m : t.male) ASSERT_EQ(m, 1);
}

TEST(AnsurData, LinearRegressionFromSexAgeStatureAndWeight) {
  const fs::path women = ansur_file("ansur2_female.csv");
  if (!fs::exists(women)) GTEST_SKIP() << women << " not found";
  fixtures::TempDir d;
  const fixtures::CliResult r = fixtures::run_cli(
      "eval-regressors --table '" + women.string() +
      "' --labels chestcircumference,crotchheight --regressors simple_linear --folds 5 --out '" +
      (d.path / "r").string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(d.path / "r" / "regressors.csv");
  std::string line;
  std::map<std::string, double> rmse;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string reg, label, unit, value;
    std::getline(ss, reg, ',');
    std::getline(ss, label, ',');
    std::getline(ss, unit, ',');
    std::getline(ss, value, ',');
    rmse[label] = std::stod(value);
  }
  // Cross-validated on the women the data folder shares: a real regression, well above zero
  // (the girth is not determined by the four inputs) and below the spread of the label itself.
  ASSERT_TRUE(rmse.count("chestcircumference") && rmse.count("crotchheight"));
  EXPECT_GT(rmse["chestcircumference"], 15);
  EXPECT_LT(rmse["chestcircumference"], 45);
  EXPECT_GT(rmse["crotchheight"], 10);
  EXPECT_LT(rmse["crotchheight"], 35);
}

}  // namespace
}  // namespace bodymodel
