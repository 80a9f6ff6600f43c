// The crowd's folder (`bodymodel generate`, tools/pipeline/crowd_output.h): it does not depend on
// the number of threads; a rerun skips complete bodies and ends byte-identical to a clean run;
// a folder of other settings is refused.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "model/model_test_util.h"
#include "support/fixtures.h"
#include "tools/pipeline/crowd_output.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;
using testing::shape_test_model;

// One folder per test process, removed when the process exits.
fs::path temp_dir() {
  static const fixtures::TempDir d;
  return d.path;
}

std::string file_bytes(const fs::path& p) { return read_text_file(p); }

// Every file of folder `a` is in `b` with the same bytes, and the other way round.
void expect_same_folders(const fs::path& a, const fs::path& b) {
  int files = 0;
  for (auto& e : fs::directory_iterator(a)) {
    const fs::path other = b / e.path().filename();
    ASSERT_TRUE(fs::exists(other)) << other;
    EXPECT_TRUE(file_bytes(e.path()) == file_bytes(other)) << e.path().filename() << " differs";
    ++files;
  }
  int other_files = 0;
  for ([[maybe_unused]] auto& e : fs::directory_iterator(b)) ++other_files;
  EXPECT_EQ(files, other_files);
}

const std::vector<LabelCondition>& crowd_conditions() {
  static const std::vector<LabelCondition> c = {LabelCondition::exact("sex", 0),
                                                LabelCondition::exact("weight_kg", 65),
                                                LabelCondition::range("height_cm", 160, 180)};
  return c;
}

TEST(CrowdOutput, ThreadCountDoesNotChangeTheCrowdAndARerunSkipsCompleteBodies) {
  auto model = shape_test_model();
  CrowdOutputOptions o;
  o.crowd.seed = 7;
  o.crowd.generate.measure_girths = false;  // the girths are checked by MeasureBanded; keep this fast
  o.crowd.threads = 1;
  const fs::path serial = temp_dir() / "serial", parallel = temp_dir() / "parallel";
  GenerateCrowdSummary s1 = write_crowd(model, crowd_conditions(), 3, serial, o);
  EXPECT_EQ(s1.generated, 3);
  EXPECT_EQ(s1.skipped, 0);
  EXPECT_EQ(s1.constraints_met, 3);
  o.crowd.threads = 2;
  GenerateCrowdSummary s2 = write_crowd(model, crowd_conditions(), 3, parallel, o);
  EXPECT_EQ(s2.constraints_met, 3);
  expect_same_folders(serial, parallel);  // bit-identical meshes, labels.csv and generate.json

  // labels.csv: header + one row per body, measured weights within 2 kg of 65.
  {
    std::ifstream in(serial / "labels.csv");
    std::string line;
    std::getline(in, line);
    int rows = 0;
    while (std::getline(in, line)) {
      ++rows;
      std::vector<std::string> cells;
      std::stringstream ss(line);
      for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
      ASSERT_GE(cells.size(), 5u) << line;
      EXPECT_NEAR(std::stod(cells[4]), 65, 2) << line;
      EXPECT_GE(std::stod(cells[3]), 160) << line;
      EXPECT_LE(std::stod(cells[3]), 180) << line;
    }
    EXPECT_EQ(rows, 3);
  }

  // As if killed mid-run: body 1 deleted, body 2's row not yet in labels.csv.
  fs::remove(parallel / "body_001.obj");
  {
    std::string csv = file_bytes(parallel / "labels.csv");
    csv = csv.substr(0, csv.rfind("\n2,") + 1);
    write_text_file(parallel / "labels.csv", csv);
  }
  GenerateCrowdSummary s3 = write_crowd(model, crowd_conditions(), 3, parallel, o);
  EXPECT_EQ(s3.skipped, 1);
  EXPECT_EQ(s3.generated, 2);
  EXPECT_EQ(s3.constraints_met, 3);
  expect_same_folders(serial, parallel);

  // Nothing left to do: every body skipped, files unchanged.
  GenerateCrowdSummary s4 = write_crowd(model, crowd_conditions(), 3, parallel, o);
  EXPECT_EQ(s4.skipped, 3);
  EXPECT_EQ(s4.generated, 0);
  expect_same_folders(serial, parallel);

  // Another seed into the same folder: refused (naming what differs) unless forced.
  CrowdOutputOptions other = o;
  other.crowd.seed = 8;
  try {
    write_crowd(model, crowd_conditions(), 3, parallel, other);
    FAIL() << "a crowd with another seed was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("seed"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--force"), std::string::npos) << e.what();
  }
  expect_same_folders(serial, parallel);  // refused before touching anything
}

}  // namespace
}  // namespace bodymodel
