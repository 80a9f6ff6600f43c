// Skeleton, forward kinematics and linear blend skinning on small fixtures with known answers.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/error.h"
#include "core/skeleton.h"

namespace bodymodel {
namespace {

// A vertical chain: root at the origin → upper (head y=0) → lower (head y=-10) → tip y=-20.
Skeleton chain() {
  Skeleton s;
  s.names = {"root", "upper", "lower"};
  s.parents = {-1, 0, 1};
  s.heads.resize(3, 3);
  s.tails.resize(3, 3);
  s.heads << 0, 0, 0, 0, 0, 0, 0, -10, 0;
  s.tails << 0, 1, 0, 0, -10, 0, 0, -20, 0;
  return s;
}

Eigen::Matrix3d rot_z(double deg) {
  return Eigen::AngleAxisd(deg * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

TEST(Skeleton, FindIndexValidate) {
  Skeleton s = chain();
  EXPECT_EQ(s.find("lower"), 2);
  EXPECT_EQ(s.find("none"), -1);
  EXPECT_EQ(s.index("upper"), 1);
  EXPECT_THROW(s.index("none"), InputError);
  s.validate();
  s.parents[1] = 2;  // child before parent
  EXPECT_THROW(s.validate(), InputError);
  s = chain();
  s.tails.conservativeResize(2, 3);
  EXPECT_THROW(s.validate(), InputError);
}

TEST(Skeleton, ForwardKinematicsOfAChain) {
  const Skeleton s = chain();
  Pose p = Pose::rest(3);
  p.rotations[1] = rot_z(90);   // upper swings the chain: −y → +x
  p.rotations[2] = rot_z(-90);  // lower bends back down
  p.root_translation = Eigen::Vector3d(1, 2, 3);
  const auto Q = world_rotations(s, p);
  EXPECT_LT((Q[2] - Eigen::Matrix3d::Identity()).norm(), 1e-15);
  const BoneTransforms M = forward_kinematics(s, p);
  // Posed head of lower = root translation + Rz(90)·(0,−10,0) = (11, 2, 3).
  const Eigen::Vector3d lower_head = M[2] * Eigen::Vector3d(0, -10, 0);
  EXPECT_LT((lower_head - Eigen::Vector3d(11, 2, 3)).norm(), 1e-12);
  // The tip stays below the lower head (identity world rotation).
  const Eigen::Vector3d tip = M[2] * Eigen::Vector3d(0, -20, 0);
  EXPECT_LT((tip - Eigen::Vector3d(11, -8, 3)).norm(), 1e-12);
  // Rest pose: every transform is the identity.
  for (const auto& T : forward_kinematics(s, Pose::rest(3)))
    EXPECT_LT((T.matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-15);
  EXPECT_THROW(forward_kinematics(s, Pose::rest(2)), InputError);
}

TEST(Skeleton, LinearBlendSkinning) {
  const Skeleton s = chain();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  const int n = 5000;
  Eigen::MatrixX3d V(n, 3);
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < n; ++i) {
    V.row(i) << 2 * u(rng) - 1, -20 * u(rng), 2 * u(rng) - 1;
    const double w = u(rng);
    t.emplace_back(i, 1, w);
    t.emplace_back(i, 2, 1 - w);
  }
  SkinWeights W(n, 3);
  W.setFromTriplets(t.begin(), t.end());
  // Rest pose reproduces the mesh.
  EXPECT_LT((linear_blend_skinning(V, W, forward_kinematics(s, Pose::rest(3))) - V)
                .cwiseAbs()
                .maxCoeff(),
            1e-12);
  // A rigid motion of the root moves every vertex rigidly.
  Pose p = Pose::rest(3);
  p.rotations[0] = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  p.root_translation = Eigen::Vector3d(5, -1, 2);
  const Eigen::MatrixX3d P = linear_blend_skinning(V, W, forward_kinematics(s, p));
  const Eigen::MatrixX3d expected =
      (V * p.rotations[0].transpose()).rowwise() + p.root_translation.transpose();
  EXPECT_LT((P - expected).cwiseAbs().maxCoeff(), 1e-12);
  // Blending: a vertex half on each bone lands at the mean of the two rigid images.
  Pose bend = Pose::rest(3);
  bend.rotations[2] = rot_z(90);
  const BoneTransforms M = forward_kinematics(s, bend);
  const Eigen::Vector3d x(1, -15, 0);
  const Eigen::Vector3d mean = 0.5 * (M[1] * x + M[2] * x);
  Eigen::MatrixX3d one(1, 3);
  one.row(0) = x.transpose();
  SkinWeights half(1, 3);
  half.insert(0, 1) = 0.5;
  half.insert(0, 2) = 0.5;
  EXPECT_LT((linear_blend_skinning(one, half, M).row(0).transpose() - mean).norm(), 1e-12);
  EXPECT_THROW(linear_blend_skinning(one, W, M), InputError);
}

}  // namespace
}  // namespace bodymodel
