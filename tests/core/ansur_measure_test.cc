// ANSUR II measurements (core/ansur_measure.h) on MakeHuman bodies: known answers from shapes
// forced onto the template (cylinders), exact scale and translation behaviour, the posed span
// against full-body skinning and the arm chain's lengths, smoothness under modifiers, and the
// default male and female against the survey's means (docs/measurements.md has the table).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include "core/ansur_measure.h"
#include "core/data_path.h"
#include "core/error.h"
#include "core/landmarks.h"
#include "core/measure.h"
#include "core/survey_columns.h"
#include "makehuman_fixture.h"

namespace bodymodel {
namespace {

constexpr double kPi = 3.14159265358979323846;

const AnsurMeasurer& measurer() {
  static const AnsurMeasurer m = [] {
    const MakeHuman& mh = shared_makehuman();
    const MakeHuman::Body ref = mh.body(MacroSettings{});
    return AnsurMeasurer(mh.body_faces(), mh.body_weights(), ref.mesh.V, ref.skeleton);
  }();
  return m;
}

int column(const std::string& name) {
  const auto& n = AnsurMeasurer::names();
  return static_cast<int>(std::find(n.begin(), n.end(), name) - n.begin());
}

Eigen::VectorXd measure(const Eigen::MatrixX3d& V) {
  return measurer().measure(V, shared_makehuman().skeleton_from_body(V));
}

MakeHuman::Body body(double gender, double weight = 0.5) {
  MacroSettings s;
  s.gender = gender;
  s.weight = weight;
  return shared_makehuman().body(s);
}

TEST(AnsurMeasure, NamesAreTheSurveysColumns) {
  std::ifstream in(data_file("anthropometry/ansur2/ansur2_male.csv"));
  ASSERT_TRUE(in.good());
  std::string header;
  std::getline(in, header);
  std::map<std::string, int> columns;
  std::stringstream ss(header);
  for (std::string c; std::getline(ss, c, ',');) columns[c] = 1;
  ASSERT_EQ(AnsurMeasurer::names().size(), 23u);
  for (const auto& n : AnsurMeasurer::names()) EXPECT_TRUE(columns.count(n)) << n;
}

// The torso round the navel forced onto a vertical cylinder of radius R: the waist girth is the
// perimeter of a polygon inscribed in that circle and the waist depth its diameter.
TEST(AnsurMeasure, WaistOfACylinderIsItsCircumference) {
  Eigen::MatrixX3d V = body(0.5).mesh.V;
  const double navel_y = V(ansur_landmarks().omphalion, 1), R = 150, cz = 20;
  for (Eigen::Index v = 0; v < V.rows(); ++v) {
    if (std::abs(V(v, 1) - navel_y) > 120 || std::abs(V(v, 0)) > 200) continue;
    const Eigen::Vector2d r(V(v, 0), V(v, 2) - cz);
    V(v, 0) = R * r.x() / r.norm();
    V(v, 2) = cz + R * r.y() / r.norm();
  }
  const Eigen::VectorXd m = measure(V);
  EXPECT_NEAR(m(column("waistcircumference")), 2 * kPi * R, 0.005 * 2 * kPi * R);
  EXPECT_LE(m(column("waistcircumference")), 2 * kPi * R + 1e-6);  // inscribed
  EXPECT_NEAR(m(column("waistdepth")), 2 * R, 2.0);
}

// The shank round the calf landmark forced onto a cylinder of radius r about the knee→ankle
// axis: the calf girth is measured square to that axis.
TEST(AnsurMeasure, CalfOfACylinderAboutTheShankIsItsCircumference) {
  const MakeHuman::Body b = body(0.5);
  Eigen::MatrixX3d V = b.mesh.V;
  const Skeleton s = shared_makehuman().skeleton_from_body(V);
  const Eigen::Vector3d knee = s.heads.row(s.index("lowerleg01.R")).transpose();
  const Eigen::Vector3d ankle = s.heads.row(s.index("foot.R")).transpose();
  const Eigen::Vector3d axis = (ankle - knee).normalized();
  const double at = (V.row(ansur_landmarks().calf).transpose() - knee).dot(axis), r = 50;
  for (Eigen::Index v = 0; v < V.rows(); ++v) {
    const Eigen::Vector3d p = V.row(v).transpose() - knee;
    const double t = p.dot(axis);
    const Eigen::Vector3d radial = p - t * axis;
    if (std::abs(t - at) > 60 || radial.norm() > 90 || V(v, 0) > -50) continue;
    V.row(v) = (knee + t * axis + r * radial.normalized()).transpose();
  }
  EXPECT_NEAR(measure(V)(column("calfcircumference")), 2 * kPi * r, 0.01 * 2 * kPi * r);
}

TEST(AnsurMeasure, ScaleAndTranslationActAsTheyMust) {
  const Eigen::MatrixX3d V = body(1.0).mesh.V;
  const Eigen::VectorXd m = measure(V);
  const Eigen::VectorXd scaled = measure(1.1 * V);
  Eigen::MatrixX3d moved = V;
  moved.rowwise() += Eigen::RowVector3d(100, 50, -30);
  const Eigen::VectorXd shifted = measure(moved);
  for (int k = 0; k < m.size(); ++k) {
    const double power = AnsurMeasurer::names()[k] == "weightkg" ? 3 : 1;
    EXPECT_NEAR(scaled(k), std::pow(1.1, power) * m(k), 1e-3 * m(k)) << AnsurMeasurer::names()[k];
    EXPECT_NEAR(shifted(k), m(k), 1e-6 * m(k)) << AnsurMeasurer::names()[k];
  }
}

TEST(AnsurMeasure, HeightsAreLandmarkHeightsAndWeightIsMeasureBodys) {
  const MakeHuman::Body b = body(0.0);
  const Eigen::MatrixX3d& V = b.mesh.V;
  const Eigen::VectorXd m = measure(V);
  const AnsurLandmarks& L = ansur_landmarks();
  const double floor = V.col(1).minCoeff();
  EXPECT_NEAR(m(column("stature")), V.col(1).maxCoeff() - floor, 1e-9);
  EXPECT_NEAR(m(column("acromialheight")), V(L.acromion_r, 1) - floor, 1e-9);
  EXPECT_NEAR(m(column("crotchheight")), V(L.crotch, 1) - floor, 1e-9);
  EXPECT_NEAR(m(column("axillaheight")), V(L.axilla_r, 1) - floor, 1e-9);
  EXPECT_NEAR(m(column("weightkg")), measure_body(V, b.mesh.F).weight_kg, 1e-6);
  // The default body is left-right symmetric: biacromial breadth = twice one acromion's |x|.
  EXPECT_NEAR(m(column("biacromialbreadth")), 2 * std::abs(V(L.acromion_r, 0)), 0.5);
}

// Span on the arms posed straight out: the same as skinning every vertex of the body with that
// pose, the fingertips level with the shoulder joints, and equal to the shoulder joints'
// distance plus both arm chains' lengths (a straight arm is its segments in line).
TEST(AnsurMeasure, SpanIsTheOutstretchedFingertipsDistance) {
  const MakeHuman& mh = shared_makehuman();
  const MakeHuman::Body b = body(0.5);
  const Skeleton s = mh.skeleton_from_body(b.mesh.V);
  const Pose pose = measurer().outstretched_arms_pose(b.mesh.V, s);
  const Eigen::MatrixX3d posed = linear_blend_skinning(b.mesh.V, mh.body_weights(), forward_kinematics(s, pose));
  const AnsurLandmarks& L = ansur_landmarks();
  const Eigen::Vector3d tip_r = posed.row(L.fingertip_r).transpose(), tip_l = posed.row(L.fingertip_l).transpose();
  const double span = measure(b.mesh.V)(column("span"));
  EXPECT_NEAR(span, (tip_l - tip_r).norm(), 1e-6);
  // The default body is symmetric, and so is its pose: mirror-image fingertips.
  EXPECT_NEAR(tip_l.x(), -tip_r.x(), 1.0);
  EXPECT_NEAR(tip_l.y(), tip_r.y(), 1.0);
  EXPECT_NEAR(tip_l.z(), tip_r.z(), 1.0);
  double chain = 0;
  for (const char* side : {".R", ".L"}) {
    const std::string sfx = side;
    const Eigen::Vector3d sh = s.heads.row(s.index("upperarm01" + sfx)).transpose();
    const Eigen::Vector3d el = s.heads.row(s.index("lowerarm01" + sfx)).transpose();
    const Eigen::Vector3d wr = s.heads.row(s.index("wrist" + sfx)).transpose();
    const Eigen::Vector3d tip = b.mesh.V.row(sfx == ".R" ? L.fingertip_r : L.fingertip_l).transpose();
    chain += (el - sh).norm() + (wr - el).norm() + (tip - wr).norm();
    EXPECT_NEAR((sfx == ".R" ? tip_r : tip_l).y(), sh.y(), 1.0) << side;
  }
  const double shoulders = (s.heads.row(s.index("upperarm01.L")) - s.heads.row(s.index("upperarm01.R"))).norm();
  EXPECT_NEAR(span, shoulders + chain, 1.0);
  // In the rest A-pose the fingertips are far closer together than outstretched.
  EXPECT_LT((b.mesh.V.row(L.fingertip_l) - b.mesh.V.row(L.fingertip_r)).norm(), 0.75 * span);
}

// Finite differences along MakeHuman modifiers see no jumps: the second difference over three
// equal steps stays far below the first.
TEST(AnsurMeasure, MeasurementsAreSmoothAlongModifiers) {
  const MakeHuman& mh = shared_makehuman();
  const Eigen::MatrixX3d V = body(0.5).mesh.V;
  const long fallbacks = measurer().fallback_count();
  for (int modifier : {0, 5, 11}) {
    const Eigen::MatrixX3d dV = mh.measure_modifier_offsets(modifier, true).topRows(V.rows());
    const double h = 0.02;
    const Eigen::VectorXd m0 = measure(V), m1 = measure(V + h * dV), m2 = measure(V + 2 * h * dV);
    for (int k = 0; k < m0.size(); ++k)
      EXPECT_LE(std::abs(m2(k) - 2 * m1(k) + m0(k)), 0.05 + 0.2 * std::abs(m1(k) - m0(k)))
          << mh.measure_modifier_names()[modifier] << " " << AnsurMeasurer::names()[k];
  }
  EXPECT_EQ(measurer().fallback_count(), fallbacks) << "a section left its tube on a near-default body";
}

// MakeHuman's default man and woman against the survey's means: every measurement within
// [0.65, 1.35] of the mean (docs/measurements.md lists the ratios: the default bodies are lighter
// and slimmer than soldiers). A wrong loop, landmark or unit lands far outside.
TEST(AnsurMeasure, DefaultBodiesAreNearTheSurveyMeans) {
  for (const char* sex : {"male", "female"}) {
    std::ifstream in(data_file(std::string("anthropometry/ansur2/ansur2_") + sex + ".csv"));
    ASSERT_TRUE(in.good());
    std::string line;
    std::getline(in, line);
    std::vector<std::string> header;
    std::stringstream hs(line);
    for (std::string c; std::getline(hs, c, ',');) header.push_back(c);
    std::map<std::string, double> sum;
    int rows = 0;
    while (std::getline(in, line)) {
      std::stringstream ls(line);
      std::string cell;
      for (size_t k = 0; k < header.size() && std::getline(ls, cell, ','); ++k)
        if (std::find(AnsurMeasurer::names().begin(), AnsurMeasurer::names().end(), header[k]) !=
            AnsurMeasurer::names().end())
          sum[header[k]] += std::stod(cell);
      ++rows;
    }
    ASSERT_GT(rows, 1000);
    const Eigen::VectorXd m = measure(body(std::string(sex) == "male" ? 1.0 : 0.0).mesh.V);
    for (size_t k = 0; k < AnsurMeasurer::names().size(); ++k) {
      const std::string& name = AnsurMeasurer::names()[k];
      const double mean = sum[name] / rows * (name == "weightkg" ? 0.1 : 1.0);
      const double ratio = m(static_cast<Eigen::Index>(k)) / mean;
      std::printf("%-7s %-28s body %8.1f  ANSUR mean %8.1f  ratio %.3f\n", sex, name.c_str(), m(k), mean, ratio);
      EXPECT_GT(ratio, 0.65) << sex << " " << name;
      EXPECT_LT(ratio, 1.35) << sex << " " << name;
    }
  }
}

// On bodies far from the default the loops may leave their tubes; either way a measurer built on
// the default body gives the values of one built on that very body (whose tubes hold its loops).
TEST(AnsurMeasure, TubesGiveTheSameValuesOnExtremeBodies) {
  const MakeHuman& mh = shared_makehuman();
  for (int which = 0; which < 4; ++which) {
    MacroSettings s;
    const double gender[] = {1, 0, 1, 0}, weight[] = {1, 0, 1, 1}, height[] = {1, 0, 0, 1}, muscle[] = {1, 0, 0, 0.5};
    s.gender = gender[which], s.weight = weight[which], s.height = height[which], s.muscle = muscle[which];
    s.age = which == 2 ? 1.0 : 0.5;
    const MakeHuman::Body b = mh.body(s);
    const AnsurMeasurer own(mh.body_faces(), mh.body_weights(), b.mesh.V, b.skeleton);
    const Skeleton sk = mh.skeleton_from_body(b.mesh.V);
    const Eigen::VectorXd m = measurer().measure(b.mesh.V, sk), expected = own.measure(b.mesh.V, sk);
    ASSERT_TRUE(m.allFinite()) << which;
    for (int k = 0; k < m.size(); ++k)
      EXPECT_NEAR(m(k), expected(k), 1e-6 * expected(k)) << which << " " << AnsurMeasurer::names()[k];
    if (which != 0) continue;
    // Tubes that miss the loops: built on a body whose navel was pulled 250 mm up, the waist tube
    // lies round the chest, so the default woman's waist is cut on the whole mesh, and her
    // values are the default measurer's.
    const MakeHuman::Body woman = body(0.0);
    Eigen::MatrixX3d pulled = woman.mesh.V;
    pulled(ansur_landmarks().omphalion, 1) += 250;
    const AnsurMeasurer off(mh.body_faces(), mh.body_weights(), pulled, woman.skeleton);
    const Skeleton ws = mh.skeleton_from_body(woman.mesh.V);
    const Eigen::VectorXd far = off.measure(woman.mesh.V, ws), near = measurer().measure(woman.mesh.V, ws);
    EXPECT_GT(off.fallback_count(), 0);
    for (int k = 0; k < far.size(); ++k) EXPECT_NEAR(far(k), near(k), 1e-6 * near(k)) << AnsurMeasurer::names()[k];
  }
}

// A short heavy man's nipples lie level with his armpits: the horizontal plane there cuts where
// the arms join the torso. The chest girth is the torso's (the tape runs under the arms), not a
// loop round both arms, which measured more than the shoulder girth above it.
TEST(AnsurMeasure, ChestLevelWithTheArmpitsLeavesTheArmsOut) {
  MacroSettings s;
  s.gender = 1, s.weight = 1, s.muscle = 0, s.height = 0;
  const MakeHuman::Body b = shared_makehuman().body(s);
  const AnsurLandmarks& L = ansur_landmarks();
  ASSERT_LT(std::abs(b.mesh.V(L.nipple_r, 1) - b.mesh.V(L.axilla_r, 1)), 20.0);  // the case at hand
  const Eigen::VectorXd m = measure(b.mesh.V);
  EXPECT_LT(m(column("chestcircumference")), 0.97 * m(column("shouldercircumference")));
  EXPECT_LT(m(column("chestcircumference")), 1.1 * m(column("waistcircumference")));
}

TEST(AnsurMeasure, ANonTemplateMeshIsRefusedNamingIt) {
  const Eigen::MatrixX3d V = Eigen::MatrixX3d::Random(100, 3);
  try {
    ansur2_columns(measurer(), V, shared_makehuman().skeleton_from_body(body(0.5).mesh.V), "'cube.obj'");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'cube.obj'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("13380"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace bodymodel
