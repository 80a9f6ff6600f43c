// What a glTF player shows between two keys of a dressed character's clip (assets/dress.h
// pose_between_keys, corrections_between_keys), and the visible-skin pass of body_distance
// (assets/penetration.h): known answers on small hand-made cases.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "assets/dress.h"
#include "assets/penetration.h"
#include "core/geometry.h"

namespace bodymodel {
namespace {

Skeleton chain() {
  Skeleton s;
  s.names = {"root", "upper", "lower"};
  s.parents = {-1, 0, 1};
  s.heads.resize(3, 3);
  s.heads << 0, 0, 0, 0, 100, 0, 0, 250, 0;
  return s;
}

Eigen::Matrix3d about(const Eigen::Vector3d& axis, double degrees) {
  return Eigen::AngleAxisd(degrees * M_PI / 180, axis.normalized()).toRotationMatrix();
}

// Half-way between keys a player slerps each joint's local rotation and interpolates the root's
// translation: forward kinematics of the half-angle pose. A blend of the bone maps themselves
// (what a per-vertex lerp of the two keys' skinned positions gives) is not that pose.
TEST(BetweenKeys, PoseIsTheHalfAnglePose) {
  const Skeleton s = chain();
  Pose a = Pose::rest(3), b = Pose::rest(3), half = Pose::rest(3);
  a.rotations[0] = about({0, 1, 0}, 10);
  b.rotations[0] = about({0, 1, 0}, 70);
  half.rotations[0] = about({0, 1, 0}, 40);
  a.rotations[1] = about({0, 0, 1}, 0);
  b.rotations[1] = about({0, 0, 1}, 120);
  half.rotations[1] = about({0, 0, 1}, 60);
  a.rotations[2] = b.rotations[2] = half.rotations[2] = about({1, 0, 0}, 35);
  a.root_translation = {0, 0, 0};
  b.root_translation = {40, -20, 100};
  half.root_translation = {20, -10, 50};
  const BoneTransforms A = forward_kinematics(s, a), Bm = forward_kinematics(s, b), H = forward_kinematics(s, half);
  const BoneTransforms mid = pose_between_keys(s, A, Bm, 0.5);
  double worst = 0, lerp_off = 0;
  for (int j = 0; j < 3; ++j) {
    worst = std::max(worst, (mid[j].matrix() - H[j].matrix()).cwiseAbs().maxCoeff());
    lerp_off = std::max(lerp_off, (0.5 * (A[j].matrix() + Bm[j].matrix()) - H[j].matrix()).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst, 1e-9);
  EXPECT_GT(lerp_off, 1.0);   // the naive blend is far off: the test can tell them apart
  for (int j = 0; j < 3; ++j) {
    EXPECT_LT((pose_between_keys(s, A, Bm, 0)[j].matrix() - A[j].matrix()).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LT((pose_between_keys(s, A, Bm, 1)[j].matrix() - Bm[j].matrix()).cwiseAbs().maxCoeff(), 1e-9);
  }
}

// The weights channel is LINEAR: half of each neighbouring key's target; a key without a target
// contributes nothing.
TEST(BetweenKeys, CorrectionsAreTheNeighboursBlended) {
  ClipCorrections c;
  c.frames.resize(3);
  GarmentCorrection g;
  g.part = 1;
  g.vertex = {4};
  g.delta = Eigen::RowVector3d(2, 0, 0);
  c.frames[0].push_back(g);
  g.delta = Eigen::RowVector3d(0, 6, 0);
  c.frames[1].push_back(g);
  const ClipCorrections m = corrections_between_keys(c, 0.25);
  ASSERT_EQ(m.frames.size(), 2u);
  Eigen::RowVector3d sum0 = Eigen::RowVector3d::Zero(), sum1 = Eigen::RowVector3d::Zero();
  for (const GarmentCorrection& x : m.frames[0]) sum0 += x.delta.row(0);
  for (const GarmentCorrection& x : m.frames[1]) sum1 += x.delta.row(0);
  EXPECT_LT((sum0 - Eigen::RowVector3d(1.5, 1.5, 0)).norm(), 1e-12);
  EXPECT_LT((sum1 - Eigen::RowVector3d(0, 4.5, 0)).norm(), 1e-12);
}

// A closed box (12 triangles, outward) with its top face "hidden"; a point inside near the
// hidden top: its closest skin is hidden, but it lies inside the visible skin (the other faces),
// so the second pass counts it, 3 mm deep along the side it is closest to among the visible
// faces. A point outside next to the hidden top stays uncounted.
TEST(BetweenKeys, PointsInsideVisibleSkinAreCountedWhenTheirClosestSkinIsHidden) {
  Eigen::MatrixX3d V(8, 3);
  V << 0, 0, 0, 100, 0, 0, 100, 100, 0, 0, 100, 0, 0, 0, 100, 100, 0, 100, 100, 100, 100, 0, 100, 100;
  Eigen::MatrixX3i F(12, 3);
  F << 0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7;
  // Hide only the top (z = 100) face's corners would hide every side face too; instead add a
  // separate top cap over its own vertices so the sides stay visible.
  Eigen::MatrixX3d V2(12, 3);
  V2 << V, V.bottomRows(4);
  Eigen::MatrixX3i F2 = F;
  F2.row(2) << 8, 9, 10;
  F2.row(3) << 8, 10, 11;
  std::vector<char> hidden(12, 0);
  for (int v = 8; v < 12; ++v) hidden[v] = 1;
  Eigen::MatrixX3d P(2, 3);
  P << 50, 3, 99,    // inside, 1 mm under the hidden top, 3 mm from the visible side y = 0
      50, 50, 101;   // outside, over the hidden top
  const BodyDistance plain = [&] {   // the first pass alone: the closest skin is hidden
    BodyDistance d = body_distance(P, V2, F2);
    return d;
  }();
  EXPECT_NEAR(plain.signed_distance[0], -1.0, 1e-9);
  const BodyDistance d = body_distance(P, V2, F2, hidden);
  EXPECT_TRUE(d.visible[0]);
  EXPECT_NEAR(d.signed_distance[0], -3.0, 1e-6);
  EXPECT_NEAR(d.normal(0, 1), -1.0, 0.2);
  EXPECT_FALSE(d.visible[1]);
  EXPECT_EQ(penetration_of(d, 2.0).penetrating, 1);
}

}  // namespace
}  // namespace bodymodel
