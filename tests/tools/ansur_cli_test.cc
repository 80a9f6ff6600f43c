// ANSUR II files at the command line: bad files refused by every verb that reads them before
// anything is written, and synth-db's subjects.csv carrying each soldier's recorded values as
// labels (ansur2_*) beside the values measured on the body.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "core/data_path.h"
#include "core/io/atomic_write.h"
#include "model/database.h"
#include "population/ansur.h"
#include "support/fixtures.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

// The 23 columns the project measures, with a plausible man's values (mm; weightkg in tenths).
const std::vector<std::pair<std::string, std::string>> kColumns = {
    {"stature", "1756"}, {"weightkg", "815"}, {"chestcircumference", "1020"}, {"waistcircumference", "900"},
    {"buttockcircumference", "1000"}, {"thighcircumference", "600"}, {"calfcircumference", "380"},
    {"bicepscircumferenceflexed", "340"}, {"forearmcircumferenceflexed", "300"}, {"neckcircumferencebase", "400"},
    {"shouldercircumference", "1200"}, {"biacromialbreadth", "400"}, {"hipbreadth", "350"}, {"chestdepth", "250"},
    {"waistdepth", "240"}, {"acromialheight", "1430"}, {"axillaheight", "1320"}, {"crotchheight", "840"},
    {"iliocristaleheight", "1070"}, {"kneeheightmidpatella", "500"}, {"span", "1800"}, {"sleeveoutseam", "600"},
    {"shoulderelbowlength", "370"}};

// An ANSUR-like file of two men; `edit(column, row, value)` may change a cell (row 0 = the header).
std::string ansur_text(const std::function<std::string(const std::string&, int, const std::string&)>& edit) {
  std::string text;
  for (int row = 0; row < 3; ++row) {
    text += row == 0 ? "subjectid" : std::to_string(row);
    for (const auto& [name, value] : kColumns) text += "," + edit(name, row, row == 0 ? name : value);
    text += row == 0 ? ",Gender,Age\n" : ",Male,30\n";
  }
  return text;
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);)
    if (!l.empty()) out.push_back(l);
  return out;
}

// Missing, renamed, in kilograms, out of range: one line naming the column (and the row where a
// row is wrong), exit 2, no output folder, from fit-measurements, synth-db and eval-regressors alike.
TEST(AnsurCli, BadFilesAreRefusedWithOneLineBeforeAnythingIsWritten) {
  fixtures::TempDir d;
  struct Case {
    std::string name, text, expect;
  };
  const auto keep = [](const std::string&, int, const std::string& v) { return v; };
  std::string missing = ansur_text(keep);
  {  // drop the chest column: its header cell and each row's cell (the third field)
    std::string out;
    for (const auto& l : lines_of(missing)) {
      std::vector<std::string> cells;
      std::stringstream ss(l);
      for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
      cells.erase(cells.begin() + 3);
      std::string joined;
      for (size_t i = 0; i < cells.size(); ++i) joined += (i ? "," : "") + cells[i];
      out += joined + "\n";
    }
    missing = out;
  }
  const std::vector<Case> cases = {
      {"missing", missing, "no column 'chestcircumference'"},
      {"renamed",
       ansur_text([](const std::string& c, int row, const std::string& v) {
         return row == 0 && c == "chestcircumference" ? std::string("chestcirc") : v;
       }),
       "no column 'chestcircumference'"},
      {"kilograms",
       ansur_text([](const std::string& c, int row, const std::string& v) {
         return row > 0 && c == "weightkg" ? std::string(row == 1 ? "81.5" : "60.2") : v;
       }),
       "column 'weightkg'"},
      {"range",
       ansur_text([](const std::string& c, int row, const std::string& v) {
         return row == 2 && c == "stature" ? std::string("17560") : v;
       }),
       "line 3, column 'stature'"},
  };
  for (const auto& c : cases) {
    const fs::path file = d / (c.name + ".csv");
    write_text_file(file, c.text);
    for (const std::string& verb : {"fit-measurements --people", "synth-db --subjects 2 --population",
                                    "eval-regressors --labels chestcircumference,span --folds 2 --table"}) {
      const fs::path out = d / (c.name + "_out");
      const fixtures::CliResult r = fixtures::run_cli(verb + " '" + file.string() + "' --out '" + out.string() + "'");
      EXPECT_EQ(r.exit_code, 2) << c.name << " " << verb << ": " << r.output;
      EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.name << " " << verb << ": " << r.output;
      EXPECT_EQ(lines_of(r.output).size(), 1u) << c.name << " " << verb << ": " << r.output;
      EXPECT_FALSE(fs::exists(out)) << c.name << " " << verb;
    }
  }
}

// synth-db on the shared ANSUR files: each subject's ansur2_<column> is the soldier's own recorded
// value (looked up by subjectid in the file), the body's measured column is beside it, and both
// are model labels while the soldier's id is not.
TEST(AnsurCli, SynthDbLabelsAreTheSoldiersRecordedValues) {
  const fs::path dir = data_file("anthropometry") / "ansur2";
  const fs::path women = dir / "ansur2_female.csv", men = dir / "ansur2_male.csv";
  if (!fs::exists(women) || !fs::exists(men)) GTEST_SKIP() << dir << " not found";
  fixtures::TempDir d;
  const fixtures::CliResult r = fixtures::run_cli(
      "synth-db --population '" + women.string() + "," + men.string() +
      "' --population-measurements stature,weightkg --subjects 4 --poses-per-subject 0 --truth-only --seed 3 "
      "--jobs 2 --out '" + (d / "db").string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const AnsurTable tables[2] = {read_ansur(women), read_ansur(men)};
  const SubjectTable subjects = read_subject_table(d / "db" / "subjects.csv");
  std::map<std::string, int> label;
  for (size_t k = 0; k < subjects.labels.size(); ++k) label[subjects.labels[k].name] = static_cast<int>(k);
  EXPECT_EQ(label.count("subjectid"), 0u);  // an id, not a label
  for (const char* c : {"ansur2_stature", "ansur2_weightkg", "ansur2_span", "ansur2_chestcircumference", "span"})
    ASSERT_EQ(label.count(c), 1u) << c;
  // The soldier of each subject, from subjects.csv's subjectid column (text, not a label).
  const std::vector<std::string> rows = lines_of(read_text_file(d / "db" / "subjects.csv"));
  std::vector<std::string> header;
  {
    std::stringstream ss(rows[0]);
    for (std::string c; std::getline(ss, c, ',');) header.push_back(c);
  }
  const auto id_col = std::find(header.begin(), header.end(), "subjectid") - header.begin();
  ASSERT_LT(static_cast<size_t>(id_col), header.size());
  ASSERT_EQ(rows.size(), 5u);
  int recorded_cells = 0, span_differs = 0;
  for (int s = 0; s < 4; ++s) {
    std::vector<std::string> cells;
    std::stringstream ss(rows[size_t(s) + 1]);
    for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
    const AnsurTable& t = tables[s % 2];  // the files alternate: women first
    const auto it = std::find(t.ids.begin(), t.ids.end(), cells[size_t(id_col)]);
    ASSERT_NE(it, t.ids.end()) << cells[size_t(id_col)];
    const Eigen::Index row = it - t.ids.begin();
    EXPECT_EQ(subjects.values(s, label["sex"]), s % 2);
    for (const auto& [name, k] : label) {
      if (name.rfind("ansur2_", 0) != 0) continue;
      const double recorded = t.values(row, t.column(name.substr(7)));
      EXPECT_NEAR(subjects.values(s, k), recorded, name == "ansur2_weightkg" ? 0.006 : 0.06) << name << " of " << s;
      ++recorded_cells;
    }
    // Fitted to stature: the body measures it; not fitted to span: the label is the soldier's, not the body's.
    EXPECT_NEAR(subjects.values(s, label["stature"]), subjects.values(s, label["ansur2_stature"]), 5.0);
    span_differs += std::abs(subjects.values(s, label["span"]) - subjects.values(s, label["ansur2_span"])) > 1.0;
  }
  EXPECT_EQ(recorded_cells, 4 * 23);
  EXPECT_GE(span_differs, 1);
}

}  // namespace
}  // namespace bodymodel
