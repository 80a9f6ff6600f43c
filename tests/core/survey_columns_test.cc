// core/survey_columns.h and `measure --standard nhanes`: the survey's columns on a body.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/io/mesh_io.h"
#include "core/survey_columns.h"
#include "makehuman_fixture.h"
#include "support/fixtures.h"
#include "support/input_error.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {

TEST(SurveyColumns, NhanesColumnsAreTheSurveyMeasurementsInTheSurveysUnits) {
  const MakeHuman::Body body = shared_makehuman().body(MacroSettings{});
  const BodyMeasurements m = measure_body(body.mesh.V, body.mesh.F, Sex::female);
  const std::vector<SurveyValue> cols = nhanes_columns(m, "body");
  ASSERT_EQ(cols.size(), 7u);
  std::map<std::string, double> v;
  for (const auto& c : cols) v[c.column] = c.value;
  EXPECT_DOUBLE_EQ(v["BMXHT"], m.height_cm);
  EXPECT_DOUBLE_EQ(v["BMXWAIST"], m.waist_iliac_cm);
  EXPECT_DOUBLE_EQ(v["BMXARMC"], m.arm_circumference_cm);
  // A standing adult: centimetres and kilograms, not millimetres.
  EXPECT_GT(v["BMXHT"], 140);
  EXPECT_LT(v["BMXHT"], 200);
  EXPECT_GT(v["BMXWAIST"], 50);
  EXPECT_LT(v["BMXWAIST"], 150);
  for (const auto& c : cols) EXPECT_TRUE(std::isfinite(c.value)) << c.column;
}

TEST(SurveyColumns, AMeshWithoutTheTemplatesTopologyIsRefusedNamingIt) {
  const Mesh s = fixtures::uv_sphere(100, 20, 30);
  const BodyMeasurements m = measure_body(s.V, s.F, Sex::unknown);
  EXPECT_NE(testing::input_error_of([&] { nhanes_columns(m, "'ball.obj'"); }).find("'ball.obj': the NHANES"),
            std::string::npos);
}

TEST(SurveyColumns, MeasurePrintsTheColumnsAsJson) {
  fixtures::TempDir d;
  const MakeHuman::Body body = shared_makehuman().body(MacroSettings{});
  write_mesh(d / "body.ply", body.mesh);
  const fixtures::CliResult r = fixtures::run_cli("measure '" + (d / "body.ply").string() + "' --standard nhanes --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output);
  const BodyMeasurements m = measure_body(body.mesh.V, body.mesh.F, Sex::unknown);
  EXPECT_NEAR(j.at("BMXWAIST").get<double>(), m.waist_iliac_cm, 1e-6);
  EXPECT_NEAR(j.at("BMXHIP").get<double>(), m.hips_cm, 1e-6);
  write_mesh(d / "ball.ply", fixtures::uv_sphere(100, 20, 30));
  const fixtures::CliResult bad = fixtures::run_cli("measure '" + (d / "ball.ply").string() + "' --standard nhanes");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("ball.ply"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace bodymodel
