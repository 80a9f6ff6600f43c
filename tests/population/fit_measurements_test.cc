// fit_measurements: a MakeHuman body from a person's measurements (population/fit_measurements.h).
#include <gtest/gtest.h>

#include "core/error.h"
#include "population/fit_measurements.h"

using namespace bodymodel;

namespace {

const MakeHuman& makehuman() {
  static const MakeHuman mh = MakeHuman::load();
  return mh;
}

// RMS vertex distance after removing the mean offset (MakeHuman bodies are not floor-aligned).
double rms_without_offset(const Eigen::MatrixX3d& a, const Eigen::MatrixX3d& b) {
  Eigen::MatrixX3d d = a - b;
  d.rowwise() -= d.colwise().mean();
  return std::sqrt(d.rowwise().squaredNorm().mean());
}

}  // namespace

TEST(FitMeasurements, RecoversSlidersFromABodysOwnMeasurements) {
  // Bodies made with known sliders, measured; the fit from those measurements alone must measure
  // the same and come back close to the body (measured: 2.7–11.9 mm RMS, sliders within 0.2).
  std::vector<MacroSettings> truth(3);
  truth[0].gender = 0, truth[0].age = 0.6, truth[0].muscle = 0.4, truth[0].weight = 0.8, truth[0].height = 0.6;
  truth[1].gender = 1, truth[1].age = 0.75, truth[1].muscle = 0.3, truth[1].weight = 0.9, truth[1].height = 0.4;
  truth[2].gender = 0, truth[2].age = 0.5, truth[2].muscle = 0.2, truth[2].weight = 1.0, truth[2].height = 0.3;
  const MakeHuman::Body average = makehuman().body(MacroSettings{});
  for (size_t i = 0; i < truth.size(); ++i) {
    const MacroSettings& s = truth[i];
    const MakeHuman::Body body = makehuman().body(s);
    const Sex sex = s.gender > 0.5 ? Sex::male : Sex::female;
    const BodyMeasurements m = measure_body(body.mesh.V, body.mesh.F, sex);
    PersonSpec person;
    person.sex = sex;
    person.age_years = s.age_years();
    for (const char* n : {"height_cm", "weight_kg", "waist_iliac_cm", "hips_cm", "arm_circumference_cm"})
      person.targets.push_back({n, measurement_value(m, n)});
    const MeasurementFit f = fit_measurements(makehuman(), person);
    EXPECT_TRUE(f.reached) << i << ": " << f.reason;
    for (const auto& r : f.residuals) EXPECT_LT(std::abs(r.residual()), 0.25) << i << " " << r.name;
    // The returned body is the one measured (fit.measured is measure_body of fit.V).
    const BodyMeasurements again = measure_body(f.V, makehuman().body_faces(), sex);
    EXPECT_DOUBLE_EQ(again.hips_cm, f.measured.hips_cm);
    const double rms = rms_without_offset(f.V, body.mesh.V);
    EXPECT_LT(rms, 15.0) << i;
    EXPECT_LT(rms, 0.5 * rms_without_offset(average.mesh.V, body.mesh.V)) << i;
    EXPECT_NEAR(f.sliders.weight, s.weight, 0.25) << i;
    EXPECT_NEAR(f.sliders.height, s.height, 0.25) << i;
    EXPECT_NEAR(f.sliders.age, s.age, 0.02) << i;
    EXPECT_FALSE(f.extrapolated) << i;  // inside MakeHuman's range, the fit stays there
  }
}

TEST(FitMeasurements, UnreachablePersonGetsClosestBodyAndAReason) {
  // A 150 cm man of 40 kg with a 130 cm waist: no MakeHuman body is that; the closest one comes
  // back with the measurements that miss named.
  PersonSpec p;
  p.sex = Sex::male;
  p.age_years = 50;
  p.targets = {{"height_cm", 150}, {"weight_kg", 40}, {"waist_iliac_cm", 130}};
  const MeasurementFit f = fit_measurements(makehuman(), p);
  EXPECT_FALSE(f.reached);
  EXPECT_NE(f.reason.find("waist_iliac_cm"), std::string::npos) << f.reason;
  EXPECT_EQ(f.V.rows(), MakeHuman::kBodyVertexCount);
  EXPECT_NEAR(f.residuals[0].achieved, 150, 2.0);  // what can be met still is
}

TEST(FitMeasurements, BadTargetsAreRefused) {
  PersonSpec p;
  p.sex = Sex::female;
  p.age_years = 40;
  p.targets = {{"waist_iliac_cm", 20}};
  EXPECT_THROW(fit_measurements(makehuman(), p), InputError);  // impossible waist
  p.targets = {{"wasit_cm", 80}};
  EXPECT_THROW(fit_measurements(makehuman(), p), InputError);  // unknown name
  p.targets = {{"height_cm", 160}, {"height_cm", 161}};
  EXPECT_THROW(fit_measurements(makehuman(), p), InputError);  // twice
  p.targets = {{"height_cm", 160}};
  p.age_years = 95;
  EXPECT_THROW(fit_measurements(makehuman(), p), InputError);  // outside MakeHuman's ages
}
