// What a glTF player shows between two keys of a dressed character's clip (assets/dress.h
// pose_between_keys, corrections_between_keys, refine_between_keys), and the visible-skin pass of body_distance
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

// A UV sphere (outward faces) of radius r around c.
void sphere(const Eigen::Vector3d& c, double r, int rings, int seg, Eigen::MatrixX3d& V, Eigen::MatrixX3i& F) {
  V.resize(2 + (rings - 1) * seg, 3);
  V.row(0) = (c + Eigen::Vector3d(0, 0, r)).transpose();
  V.row(1) = (c - Eigen::Vector3d(0, 0, r)).transpose();
  for (int i = 1; i < rings; ++i)
    for (int j = 0; j < seg; ++j) {
      const double t = M_PI * i / rings, p = 2 * M_PI * j / seg;
      V.row(2 + (i - 1) * seg + j) = (c + r * Eigen::Vector3d(std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t))).transpose();
    }
  std::vector<Eigen::Vector3i> f;
  auto at = [&](int i, int j) { return 2 + (i - 1) * seg + (j % seg); };
  for (int j = 0; j < seg; ++j) {
    f.emplace_back(0, at(1, j), at(1, j + 1));
    f.emplace_back(1, at(rings - 1, j + 1), at(rings - 1, j));
    for (int i = 1; i + 1 < rings; ++i) {
      f.emplace_back(at(i, j), at(i + 1, j), at(i + 1, j + 1));
      f.emplace_back(at(i, j), at(i + 1, j + 1), at(i, j + 1));
    }
  }
  F.resize(static_cast<Eigen::Index>(f.size()), 3);
  for (size_t k = 0; k < f.size(); ++k) F.row(static_cast<Eigen::Index>(k)) = f[k].transpose();
}

SkinWeights all_on(Eigen::Index rows, int bone, int bones) {
  SkinWeights W(rows, bones);
  for (Eigen::Index i = 0; i < rows; ++i) W.insert(i, bone) = 1;
  W.makeCompressed();
  return W;
}

// A "garment" (a small shell, radius 25) carried by a joint that turns 90° about z between two
// keys sweeps past a "body" (a sphere, radius 30) that sits where the joint's turn is half done:
// at the keys the two are 150 mm apart (nothing to correct), half-way the shell lies wholly
// inside the body. The keys' corrections (none) blended leave it there, so a sample is added
// half-way with the shell pushed out; at the quarter points (the new half-ways) nothing is over.
// With no halving allowed the half-way point stays over and nothing is added.
TEST(BetweenKeys, ASampleIsAddedWhereTheBlendOfTheKeysLeavesTheGarmentInside) {
  Skeleton s;
  s.names = {"root", "arm"};
  s.parents = {-1, 0};
  s.heads = Eigen::MatrixX3d::Zero(2, 3);
  const Eigen::Vector3d mid = 200 * Eigen::Vector3d(std::cos(M_PI / 4), std::sin(M_PI / 4), 0);
  DressedPart shell;
  shell.name = "shell";
  shell.garment = true;
  sphere({200, 0, 0}, 25, 12, 24, shell.V, shell.F);
  shell.weights = all_on(shell.V.rows(), 1, 2);
  Eigen::MatrixX3d body;
  Eigen::MatrixX3i body_F;
  sphere(mid, 30, 16, 32, body, body_F);
  const SkinWeights body_W = all_on(body.rows(), 0, 2);
  Pose a = Pose::rest(2), b = Pose::rest(2);
  b.rotations[1] = about({0, 0, 1}, 90);
  const std::vector<BoneTransforms> frames = {forward_kinematics(s, a), forward_kinematics(s, b)};
  const std::vector<DressedPart> parts = {shell};
  const ClipCorrections keys = clip_corrections(parts, body, body_F, body_W, {}, frames);
  ASSERT_TRUE(keys.frames.at(0).empty() && keys.frames.at(1).empty());
  EXPECT_LT((pose_at(s, frames, 0.5)[1].linear() - about({0, 0, 1}, 45)).cwiseAbs().maxCoeff(), 1e-9);
  RefineOptions o;
  o.max_halvings = 0;
  const SampledCorrections none = refine_between_keys(parts, body, body_F, body_W, {}, s, frames, keys, o);
  EXPECT_EQ(none.added, 0);
  EXPECT_EQ(none.times, (std::vector<double>{0, 1}));
  ASSERT_EQ(none.between.fraction.rows(), 1);
  EXPECT_EQ(none.between.frames_over(0.01), 1);
  EXPECT_GT(none.between.fraction(0, 0), 0.99);   // the whole shell inside
  o.max_halvings = 3;
  const SampledCorrections r = refine_between_keys(parts, body, body_F, body_W, {}, s, frames, keys, o);
  EXPECT_EQ(r.added, 1);
  EXPECT_EQ(r.times, (std::vector<double>{0, 0.5, 1}));
  ASSERT_EQ(r.corrections.frames.size(), 3u);
  EXPECT_TRUE(r.corrections.frames[0].empty() && r.corrections.frames[2].empty());
  ASSERT_EQ(r.corrections.frames[1].size(), 1u);
  EXPECT_EQ(r.corrections.frames[1][0].vertex.size(), static_cast<size_t>(shell.V.rows()));
  EXPECT_EQ(r.between_keys.frames_over(0.01), 1);   // before the sample: as the keys alone
  ASSERT_EQ(r.between.fraction.rows(), 2);
  EXPECT_EQ(r.between.frames_over(0.01), 0);
  // The sample plays at its own time: the shell as corrected there is out of the body.
  ClipCorrections at_half;
  at_half.frames.push_back(r.corrections.frames[1]);
  const ClipPenetration p = clip_penetration(parts, body, body_F, body_W, {}, {pose_at(s, frames, 0.5)}, 2.0, &at_half);
  EXPECT_EQ(p.fraction(0, 0), 0.0);
}

}  // namespace
}  // namespace bodymodel
