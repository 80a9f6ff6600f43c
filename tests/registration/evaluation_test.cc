// registration/evaluation.h on MakeHuman's body: errors with known answers.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "core/makehuman.h"
#include "registration/evaluation.h"

namespace bodymodel {
namespace {

const MakeHuman::Body& body() {
  static const MakeHuman::Body b = MakeHuman::load().body(MacroSettings{});
  return b;
}

const RegistrationEvaluator& evaluator() {
  static const RegistrationEvaluator e(body().mesh, body().skeleton, body().weights);
  return e;
}

TEST(RegistrationEvaluation, BonesFallInTheirBodyRegions) {
  EXPECT_EQ(bone_region("finger2-3.L"), "hands");
  EXPECT_EQ(bone_region("toe1-1.R"), "feet");
  EXPECT_EQ(bone_region("jaw"), "head/face");
  EXPECT_EQ(bone_region("neck01"), "neck");
  EXPECT_EQ(bone_region("upperleg01.L"), "legs");
  EXPECT_EQ(bone_region("lowerarm02.R"), "arms");
  EXPECT_EQ(bone_region("clavicle.L"), "shoulders");
  EXPECT_EQ(bone_region("spine03"), "torso/pelvis");
}

TEST(RegistrationEvaluation, SwingAndTwistSplitAnErrorRotation) {
  const Eigen::Vector3d d = Eigen::Vector3d(1, 2, 0.5).normalized();
  const Eigen::Matrix3d truth = Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.3, -1, 0.2).normalized()).toRotationMatrix();
  // An error about the bone's own axis is all twist.
  const Eigen::Matrix3d twisted = truth * Eigen::AngleAxisd(30 * M_PI / 180, d).toRotationMatrix();
  auto [s1, t1] = swing_twist_deg(twisted, truth, d);
  EXPECT_NEAR(s1, 0, 1e-4);
  EXPECT_NEAR(t1, 30, 1e-6);
  // About an axis perpendicular to it, all swing.
  const Eigen::Vector3d p = d.unitOrthogonal();
  const Eigen::Matrix3d swung = truth * Eigen::AngleAxisd(-20 * M_PI / 180, p).toRotationMatrix();
  auto [s2, t2] = swing_twist_deg(swung, truth, d);
  EXPECT_NEAR(s2, 20, 1e-6);
  EXPECT_NEAR(t2, 0, 1e-4);
}

TEST(RegistrationEvaluation, AShiftedRegistrationHasTheShiftAsItsCorrespondenceError) {
  const Eigen::MatrixX3d& truth = body().mesh.V;
  Eigen::MatrixX3d reg = truth;
  reg.col(2).array() += 3.0;  // 3 mm forward
  const ScanEvaluation e = evaluator().evaluate_scan(reg, truth, truth);
  EXPECT_NEAR(e.errors.correspondence_mean, 3.0, 1e-9);
  EXPECT_NEAR(e.correspondence_p95, 3.0, 1e-9);
  EXPECT_EQ(e.errors.flipped_triangles, 0);
  EXPECT_TRUE(e.flipped.empty());
  EXPECT_LE(e.errors.surface_mean, 3.0 + 1e-9);
  EXPECT_TRUE(std::isnan(e.joint_median));  // no poses given

  RegistrationEvaluator pooled = evaluator();
  pooled.add(e);
  pooled.add(evaluator().evaluate_scan(truth, truth, truth));
  const RegistrationEvaluationSummary s = pooled.summary();
  EXPECT_EQ(s.scans, 2);
  EXPECT_NEAR(s.correspondence_median_of_means, 1.5, 1e-9);  // median of {0, 3}
  EXPECT_EQ(s.flipped, 0);
}

TEST(RegistrationEvaluation, AFoldIsCountedInTheRegionOfItsVertices) {
  const Eigen::MatrixX3d& truth = body().mesh.V;
  const Eigen::MatrixX3i& F = body().mesh.F;
  // Turn one triangle over: its first vertex mirrored through the midpoint of the opposite edge.
  const int f = int(F.rows() / 2);
  Eigen::MatrixX3d reg = truth;
  reg.row(F(f, 0)) = truth.row(F(f, 1)) + truth.row(F(f, 2)) - truth.row(F(f, 0));
  const ScanEvaluation e = evaluator().evaluate_scan(reg, truth, truth);
  ASSERT_GE(e.errors.flipped_triangles, 1);
  bool found = false;
  for (const FlippedTriangle& t : e.flipped) {
    found |= t.triangle == f;
    int votes = 0;
    for (int k = 0; k < 3; ++k) votes += evaluator().vertex_region()[F(t.triangle, k)] == t.region;
    EXPECT_GE(votes, 2) << "triangle " << t.triangle;
    EXPECT_GT(t.angle_deg, 90.0);
  }
  EXPECT_TRUE(found);
}

TEST(RegistrationEvaluation, AJointTurnedAboutItsBoneIsTwist) {
  const Skeleton& sk = evaluator().skeleton();
  PoseRecord truth;
  truth.pose.rotations.assign(sk.bone_count(), Eigen::Matrix3d::Identity());
  PoseRecord reg = truth;
  const int j = evaluator().joints().front();
  const Eigen::Vector3d d = (sk.tails.row(j) - sk.heads.row(j)).transpose().normalized();
  reg.pose.rotations[j] = Eigen::AngleAxisd(12 * M_PI / 180, d).toRotationMatrix();
  const Eigen::MatrixX3d& V = body().mesh.V;
  const ScanEvaluation e = evaluator().evaluate_scan(V, V, V, &reg, &truth);
  ASSERT_EQ(e.joint_deg.size(), evaluator().joints().size());
  EXPECT_NEAR(e.joint_deg[0], 12, 1e-6);
  EXPECT_NEAR(e.twist_deg[0], 12, 1e-6);
  EXPECT_NEAR(e.swing_deg[0], 0, 1e-4);  // acos near 1 loses half the digits
  EXPECT_NEAR(e.joint_max, 12, 1e-6);
}

}  // namespace
}  // namespace bodymodel
