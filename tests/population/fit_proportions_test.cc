// fit_proportions: a body from any subset of measurements, every MakeHuman modifier, a population
// prior (population/fit_proportions.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <random>

#include "core/data_path.h"
#include "core/error.h"
#include "core/landmarks.h"
#include "core/measure.h"
#include "population/ansur_fit.h"
#include "population/fit_proportions.h"

using namespace bodymodel;

namespace {

const MakeHuman& makehuman() {
  static const MakeHuman mh = MakeHuman::load();
  return mh;
}

int landmark(const std::string& name) {
  for (const auto& [n, v] : body_landmarks())
    if (n == name) return v;
  return -1;
}

// A small measurement set with answers independent of the fitter: heights and distances between
// template vertices (mm), a girth through core/measure.h, and the weight from the volume.
MeasurementSet test_set() {
  MeasurementSet s;
  s.names = {"stature", "weightkg", "biacromial", "crotchheight", "hipwidth", "waistgirth", "armlength", "kneeheight"};
  const Eigen::MatrixX3i F = makehuman().body_faces();
  s.measure = [F](const Eigen::MatrixX3d& V) {
    Eigen::VectorXd m(8);
    const double floor = V.col(1).minCoeff();
    auto dist = [&](const char* a, const char* b) { return (V.row(landmark(a)) - V.row(landmark(b))).norm(); };
    m(0) = V.col(1).maxCoeff() - floor;
    double vol = 0;
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      vol += V.row(F(f, 0)).dot(V.row(F(f, 1)).cross(V.row(F(f, 2)))) / 6.0;
    m(1) = vol * 1e-6 * 1.01;
    m(2) = dist("l_shoulder", "r_shoulder");
    m(3) = V(survey_landmarks().crotch[0], 1) - floor;
    m(4) = dist("l_hip", "r_hip");
    m(5) = girth_at_height(V, F, V(landmark("navel"), 1));
    m(6) = dist("r_shoulder", "r_wrist");
    m(7) = V(landmark("r_knee"), 1) - floor;
    return m;
  };
  return s;
}

}  // namespace

TEST(MeasurementPrior, ConditionalOfAKnownGaussian) {
  // x1 ~ N(10, 4), x2 = 2 x1 + N(0, 1): E[x2 | x1 = 12] = 24, sd 1; x3 independent stays.
  MeasurementPrior p;
  p.names = {"a", "b", "c"};
  p.mean = Eigen::Vector3d(10, 20, 5);
  p.covariance.setZero(3, 3);
  p.covariance(0, 0) = 4, p.covariance(0, 1) = p.covariance(1, 0) = 8, p.covariance(1, 1) = 17, p.covariance(2, 2) = 9;
  Eigen::VectorXd e, sd;
  p.condition({"a"}, Eigen::VectorXd::Constant(1, 12.0), e, sd);
  EXPECT_NEAR(e(0), 12, 1e-12);
  EXPECT_NEAR(e(1), 24, 1e-9);
  EXPECT_NEAR(sd(1), 1, 1e-9);
  EXPECT_NEAR(e(2), 5, 1e-12);
  EXPECT_NEAR(sd(2), 3, 1e-12);
  EXPECT_THROW(p.condition({"zz"}, Eigen::VectorXd::Constant(1, 1.0), e, sd), InputError);
}

TEST(ShapeModifiers, LoadPairAndMoveTheBodyLinearly) {
  const auto& mods = makehuman().shape_modifiers();
  if (mods.empty()) GTEST_SKIP() << "no body-shape targets in the MakeHuman data";
  EXPECT_GT(mods.size(), 100u);
  const int k = makehuman().shape_modifier_index("armslegs/l-upperarm-fat-decr|incr");
  ASSERT_GE(k, 0);
  ASSERT_GE(mods[k].mirror, 0);
  EXPECT_EQ(mods[mods[k].mirror].name, "armslegs/r-upperarm-fat-decr|incr");
  Eigen::VectorXd shape = Eigen::VectorXd::Zero(mods.size());
  const Eigen::MatrixX3d V0 = makehuman().build_vertices(MacroSettings{}, {}, shape, {});
  shape(k) = 0.5;
  const Eigen::MatrixX3d Vh = makehuman().build_vertices(MacroSettings{}, {}, shape, {});
  shape(k) = 1.0;
  const Eigen::MatrixX3d V1 = makehuman().build_vertices(MacroSettings{}, {}, shape, {});
  EXPECT_GT((V1 - V0).norm(), 1.0);
  EXPECT_NEAR(((Vh - V0) * 2 - (V1 - V0)).norm(), 0.0, 1e-9);
  shape(k) = 2.0;
  EXPECT_THROW(makehuman().build_vertices(MacroSettings{}, {}, shape, {}), InputError);
}

TEST(FitProportions, ReproducesTheMeasurementsOfAShapedBody) {
  // Bodies with random macros AND random shape modifiers, measured by an independent set; the fit
  // to every measurement must measure within 1 mm / 0.1 kg, with no flipped triangle.
  if (makehuman().shape_modifiers().empty()) GTEST_SKIP() << "no body-shape targets";
  const ProportionFitter fitter(makehuman(), test_set());
  const MeasurementSet set = test_set();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.2, 0.8), m(-0.5, 0.5);
  for (int person = 0; person < 2; ++person) {
    MacroSettings s;
    s.gender = person;
    s.muscle = u(rng), s.weight = u(rng), s.height = u(rng), s.proportions = u(rng);
    Eigen::VectorXd shape = Eigen::VectorXd::Zero(makehuman().shape_modifiers().size());
    for (const char* n : {"torso/torso-scale-horiz-decr|incr", "hip/hip-scale-horiz-decr|incr",
                          "armslegs/r-upperarm-scale-vert-decr|incr", "armslegs/l-upperarm-scale-vert-decr|incr"})
      shape(makehuman().shape_modifier_index(n)) = m(rng);
    const Eigen::MatrixX3d V =
        makehuman().build_vertices(s, {}, shape, {}).topRows(MakeHuman::kBodyVertexCount);
    const Eigen::VectorXd truth = set.measure(V);
    std::vector<ProportionTarget> targets;
    for (size_t k = 0; k < set.names.size(); ++k) targets.push_back({set.names[k], truth(k)});
    const ProportionFit fit = fitter.fit(person ? Sex::male : Sex::female, 30, targets, {});
    for (size_t k = 0; k < set.names.size(); ++k)
      EXPECT_NEAR(fit.measured(k), truth(k), set.names[k] == "weightkg" ? 0.1 : 1.0) << set.names[k];
    EXPECT_EQ(fit.flipped_triangles, 0);
  }
}

TEST(FitProportions, RefusesBadTargets) {
  if (makehuman().shape_modifiers().empty()) GTEST_SKIP() << "no body-shape targets";
  const ProportionFitter fitter(makehuman(), test_set());
  EXPECT_THROW(fitter.fit(Sex::male, 30, {{"nosuch", 1}}, {}), InputError);
  EXPECT_THROW(fitter.fit(Sex::male, 30, {{"stature", 1700}, {"stature", 1700}}, {}), InputError);
  EXPECT_THROW(fitter.fit(Sex::male, 30, {{"stature", NAN}}, {}), InputError);
  EXPECT_THROW(fitter.fit(Sex::unknown, 30, {{"stature", 1700}}, {}), InputError);
  EXPECT_THROW(fitter.fit(Sex::male, 12, {{"stature", 1700}}, {}), InputError);
}

namespace {

std::filesystem::path ansur_file(const char* name) {
  return data_file(std::filesystem::path("anthropometry") / "ansur2" / name);
}

}  // namespace

TEST(AnsurFit, GivenColumnsAreMetAndTheOthersFollowThePopulation) {
  // Shared soldiers, the prior and the regression learned from the others: fitted to the 18
  // columns, each within its tolerance, no folded triangle; fitted to five, the eight
  // measurements of the bar within 1.1x the regression's error.
  const auto men = ansur_file("ansur2_male.csv");
  if (!std::filesystem::exists(men) || makehuman().shape_modifiers().empty()) GTEST_SKIP() << men << " not found";
  const AnsurTable table = read_ansur(men);
  const MeasurementSet set = ansur_measurement_set(makehuman());
  const ProportionFitter fitter(makehuman(), set);
  AnsurFitOptions o;
  o.rows = {3, 400, 1200, 2000, 2900, 3100};
  o.given = default_ansur_columns();
  const AnsurFitRun all = fit_ansur_rows(fitter, set, table, table, o, false);
  for (const auto& s : all.summary)
    if (s.given) EXPECT_EQ(s.within, 1.0) << s.name << " rmse " << s.rmse_body;
  EXPECT_EQ(all.flipped_people, 0);
  EXPECT_EQ(all.self_intersecting_people, 0);
  o.given = {"stature", "weightkg", "chestcircumference", "waistcircumference", "buttockcircumference"};
  const AnsurFitRun five = fit_ansur_rows(fitter, set, table, table, o, false);
  double body = 0, regression = 0;
  for (const auto& s : five.summary)
    for (const char* n : {"thighcircumference", "neckcircumferencebase", "shouldercircumference", "biacromialbreadth",
                          "hipbreadth", "crotchheight", "span", "sleeveoutseam"})
      if (s.name == n) {
        EXPECT_LE(s.rmse_body, 1.1 * s.rmse_regression + 1.0) << s.name;
        body += s.rmse_body * s.rmse_body, regression += s.rmse_regression * s.rmse_regression;
      }
  EXPECT_GT(regression, 0);
  EXPECT_LE(body, 1.1 * 1.1 * regression);
}

TEST(AnsurFit, HeavyThighsArePushedApartInsteadOfThroughEachOther) {
  // Three shared women whose fitted bodies, fitted to the 18 columns, crossed themselves at the
  // crotch (inner thighs) or under the breasts beyond MakeHuman's own body even after the refits:
  // with the intersection repair none does, and every given column is still met.
  const auto women = ansur_file("ansur2_female.csv");
  if (!std::filesystem::exists(women) || makehuman().shape_modifiers().empty()) GTEST_SKIP() << women << " not found";
  const AnsurTable table = read_ansur(women);
  const MeasurementSet set = ansur_measurement_set(makehuman());
  AnsurFitOptions o;
  for (const char* id : {"16121", "18052", "25838"}) {
    const auto it = std::find(table.ids.begin(), table.ids.end(), id);
    ASSERT_NE(it, table.ids.end()) << id;
    o.rows.push_back(static_cast<int>(it - table.ids.begin()));
  }
  o.given = default_ansur_columns();
  ProportionFitOptions without;
  without.intersection_repair = false;
  const AnsurFitRun before = fit_ansur_rows(ProportionFitter(makehuman(), set, without), set, table, table, o, false);
  EXPECT_GE(before.self_intersecting_people, 1);
  const AnsurFitRun after = fit_ansur_rows(ProportionFitter(makehuman(), set), set, table, table, o, false);
  EXPECT_EQ(after.self_intersecting_people, 0);
  EXPECT_EQ(after.flipped_people, 0);
  for (const auto& s : after.summary)
    if (s.given) EXPECT_EQ(s.within, 1.0) << s.name << " rmse " << s.rmse_body;
}

TEST(AnsurFit, FittingEverySoldierOfThePriorFileIsRefusedWithAClearLine) {
  // The prior leaves out the soldiers being fitted: fitting the whole file leaves none to learn
  // it from, which must say what to do instead of failing deep inside.
  const auto men = ansur_file("ansur2_male.csv");
  if (!std::filesystem::exists(men) || makehuman().shape_modifiers().empty()) GTEST_SKIP() << men << " not found";
  const AnsurTable table = read_ansur(men);
  const MeasurementSet set = ansur_measurement_set(makehuman());
  const ProportionFitter fitter(makehuman(), set);
  AnsurFitOptions o;
  o.given = {"stature"};
  try {
    fit_ansur_rows(fitter, set, table, table, o, false);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--prior"), std::string::npos) << e.what();
  }
}
