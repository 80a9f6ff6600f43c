// Generation: the banded measurement equals measure_body; a crowd does not depend on the
// number of threads; a rerun skips complete bodies and ends byte-identical to a clean run.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "model/generate_crowd.h"
#include "model/morph.h"
#include "model_test_util.h"
#include "support/fixtures.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;
using testing::make_test_subjects;
using testing::shape_test_model;

// One folder per test process, removed when the process exits.
fs::path temp_dir() {
  static const fixtures::TempDir d;
  return d.path;
}

void expect_same_measurements(const BodyMeasurements& a, const BodyMeasurements& b, const std::string& what) {
  const double tol = 1e-9;
  EXPECT_NEAR(a.height_cm, b.height_cm, tol) << what;
  EXPECT_NEAR(a.volume_l, b.volume_l, tol) << what;
  EXPECT_NEAR(a.weight_kg, b.weight_kg, tol) << what;
  EXPECT_NEAR(a.neck_cm, b.neck_cm, tol) << what;
  EXPECT_NEAR(a.chest_cm, b.chest_cm, tol) << what;
  EXPECT_NEAR(a.waist_cm, b.waist_cm, tol) << what;
  EXPECT_NEAR(a.hips_cm, b.hips_cm, tol) << what;
  EXPECT_NEAR(a.neck_at_cm, b.neck_at_cm, tol) << what;
  EXPECT_NEAR(a.chest_at_cm, b.chest_at_cm, tol) << what;
  EXPECT_NEAR(a.waist_at_cm, b.waist_at_cm, tol) << what;
  EXPECT_NEAR(a.hips_at_cm, b.hips_at_cm, tol) << what;
  EXPECT_NEAR(a.body_fat_pct, b.body_fat_pct, tol) << what;
}

// measure_body cuts only each band's triangles; the reference cuts the whole mesh every time.
BodyMeasurements measure_body_every_triangle(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, Sex sex) {
  MeasureOptions o;
  o.cut_band_triangles_only = false;
  return measure_body(V, F, sex, o);
}

TEST(MeasureBanded, EqualsCuttingEveryTriangleOnMaleAndFemaleBodies) {
  const Eigen::MatrixX3i& F = testing::test_makehuman().body_faces();
  auto subjects = make_test_subjects(4, 123);
  for (size_t i = 0; i < subjects.size(); ++i) {
    const Sex sex = subjects[i].male ? Sex::male : Sex::female;
    BodyMeasurements full = measure_body_every_triangle(subjects[i].V, F, sex);
    BodyMeasurements banded = measure_body(subjects[i].V, F, sex);
    expect_same_measurements(full, banded, "subject " + std::to_string(i));
    EXPECT_GT(banded.waist_cm, 40);  // the girths were found, not 0 on both sides
    EXPECT_GT(banded.hips_cm, banded.waist_cm * 0.8);
  }
  // A body rotated off the axis (other sections, other triangles per band).
  Eigen::Matrix3d R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 0.2, 0.5).normalized()).toRotationMatrix();
  Eigen::MatrixX3d V = subjects[0].V * R.transpose();
  expect_same_measurements(measure_body_every_triangle(V, F, Sex::female), measure_body(V, F, Sex::female), "rotated");
  EXPECT_THROW(measure_body(Eigen::MatrixX3d(0, 3), F), InputError);
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

TEST(GenerateCrowd, ThreadCountDoesNotChangeTheCrowdAndARerunSkipsCompleteBodies) {
  auto model = shape_test_model();
  GenerateCrowdOptions o;
  o.seed = 7;
  o.generate.measure_girths = false;  // the girths are checked by MeasureBanded; keep this fast
  o.threads = 1;
  const fs::path serial = temp_dir() / "serial", parallel = temp_dir() / "parallel";
  GenerateCrowdSummary s1 = generate_crowd(model, crowd_conditions(), 3, serial, o);
  EXPECT_EQ(s1.generated, 3);
  EXPECT_EQ(s1.skipped, 0);
  EXPECT_EQ(s1.constraints_met, 3);
  o.threads = 2;
  GenerateCrowdSummary s2 = generate_crowd(model, crowd_conditions(), 3, parallel, o);
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
  GenerateCrowdSummary s3 = generate_crowd(model, crowd_conditions(), 3, parallel, o);
  EXPECT_EQ(s3.skipped, 1);
  EXPECT_EQ(s3.generated, 2);
  EXPECT_EQ(s3.constraints_met, 3);
  expect_same_folders(serial, parallel);

  // Nothing left to do: every body skipped, files unchanged.
  GenerateCrowdSummary s4 = generate_crowd(model, crowd_conditions(), 3, parallel, o);
  EXPECT_EQ(s4.skipped, 3);
  EXPECT_EQ(s4.generated, 0);
  expect_same_folders(serial, parallel);

  // Another seed into the same folder: refused (naming what differs) unless forced.
  GenerateCrowdOptions other = o;
  other.seed = 8;
  try {
    generate_crowd(model, crowd_conditions(), 3, parallel, other);
    FAIL() << "a crowd with another seed was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("seed"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--force"), std::string::npos) << e.what();
  }
  expect_same_folders(serial, parallel);  // refused before touching anything
}

}  // namespace
}  // namespace bodymodel
