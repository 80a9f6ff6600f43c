// Error metrics on tiny meshes with known answers; bone recovery on a synthetic two-bone tube.
#include <gtest/gtest.h>

#include <random>

#include "core/error.h"
#include "skinning/bone_recovery.h"
#include "skinning/fit_lbs.h"
#include "skinning/skinning_error.h"
#include "synthetic_tube.h"

namespace bodymodel {
namespace {

// Unit square in z = 0 made of two triangles (and its centre, so a vertex can slide in-plane).
void square(Eigen::MatrixX3d* V, Eigen::MatrixX3i* F) {
  V->resize(5, 3);
  *V << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5, 0.5, 0;
  F->resize(4, 3);
  *F << 0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4;
}

TEST(SkinningError, GeometricDeviationIsDistanceToTheSurfaceNotToTheVertex) {
  Eigen::MatrixX3d Y;
  Eigen::MatrixX3i F;
  square(&Y, &F);
  Eigen::MatrixX3d X = Y;
  X(4, 0) += 0.2;   // centre slides within the plane: on the surface, but 0.2 from its vertex
  X(2, 2) += 0.1;   // a corner lifts off the plane by 0.1
  const MeshDeviation d = mesh_deviation(X, Y, F);
  EXPECT_NEAR(d.geometric(4), 0.0, 1e-12);
  EXPECT_NEAR(d.vertex(4), 0.2, 1e-12);
  EXPECT_NEAR(d.geometric(2), 0.1, 1e-12);
  EXPECT_NEAR(d.geometric(0), 0.0, 1e-12);
  for (Eigen::Index i = 0; i < 5; ++i) EXPECT_LE(d.geometric(i), d.vertex(i) + 1e-15);
  // A point beyond the corner: distance to the corner (1,1,0) from (1.3, 1.4, 0) = 0.5.
  ReferenceSurface s(Y, F);
  Eigen::MatrixX3d Q(1, 3);
  Q << 1.3, 1.4, 0;
  EXPECT_NEAR(s.distances(Q)(0), 0.5, 1e-12);
}

TEST(SkinningError, NormalDeviationOfARotatedMeshIsTheRotationAngle) {
  Eigen::MatrixX3d Y;
  Eigen::MatrixX3i F;
  square(&Y, &F);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(30.0 * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::MatrixX3d X = Y * R.transpose();
  const MeshDeviation d = mesh_deviation(X, Y, F);
  for (Eigen::Index i = 0; i < 5; ++i) EXPECT_NEAR(d.normal_deg(i), 30.0, 1e-9);
}

TEST(SkinningError, StatsAndErmsFollowTheirDefinitions) {
  Eigen::MatrixX3d Y;
  Eigen::MatrixX3i F;
  square(&Y, &F);
  Eigen::MatrixX3d X = Y;
  X.col(2).array() += 0.1;   // every vertex 0.1 off: g = e = 0.1
  DeviationStats st;
  st.add(mesh_deviation(X, Y, F));
  st.add(mesh_deviation(Y, Y, F));
  EXPECT_NEAR(st.mean_geometric(), 0.05, 1e-12);
  EXPECT_NEAR(st.max_geometric, 0.1, 1e-12);
  EXPECT_NEAR(st.rms_vertex(), std::sqrt(0.5 * 0.01), 1e-12);
  // E_RMS = 1000 ‖X−Y‖_F / (√(3 n f) d): ‖·‖_F = √(5·0.01), n f = 10, d = √2.
  EXPECT_NEAR(st.e_rms(std::sqrt(2.0)), 1000 * std::sqrt(0.05) / (std::sqrt(30.0) * std::sqrt(2.0)), 1e-9);
}

TEST(BoneRecovery, FindsTwoRigidPartsAndTheirMotion) {
  const auto t = testing::make_tube(21, 12);
  std::mt19937 rng(3);
  // Rigid two-part motion: vertices with x < 1.5 follow bone 0, the rest bone 1.
  Eigen::MatrixXd W = Eigen::MatrixXd::Zero(t.V.rows(), 2);
  for (Eigen::Index i = 0; i < t.V.rows(); ++i) W(i, t.V(i, 0) < 1.5 ? 0 : 1) = 1;
  const SkinningRig truth = lbs_rig_from_weights(t.V, W, 1);
  std::vector<Eigen::MatrixX3d> frames;
  std::vector<BoneTransforms> T;
  for (int p = 0; p < 6; ++p) {
    BoneTransforms M = testing::random_chain_pose(rng, 0.8);
    M.resize(2);
    T.push_back(M);
    frames.push_back(evaluate_rig(truth, M));
  }
  BoneRecoveryOptions o;
  o.bones = 2;
  BoneRecoverySummary s;
  const RecoveredBones rec = recover_bones(t.V, t.F, frames, o, &s);
  EXPECT_LT(s.rms_rigid_residual, 1e-9);
  // The partition matches up to relabelling.
  const int a = rec.vertex_bone(0);
  for (Eigen::Index i = 0; i < t.V.rows(); ++i)
    EXPECT_EQ(rec.vertex_bone(i) == a, t.V(i, 0) < 1.5) << "vertex " << i;
  // Fixed-weight transform fit from a perturbed start recovers the motion.
  const SkinningRig lbs = lbs_rig_from_weights(t.V, W, 1);
  BoneTransforms init(2, Eigen::Affine3d::Identity());
  const BoneTransforms fitted = fit_transforms_with_fixed_weights(lbs, frames[3], init, 3);
  EXPECT_LT((fitted[0].matrix() - T[3][0].matrix()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((fitted[1].matrix() - T[3][1].matrix()).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(BoneRecovery, RejectsBadInput) {
  const auto t = testing::make_tube(4, 4);
  std::vector<Eigen::MatrixX3d> frames{t.V, t.V};
  BoneRecoveryOptions o;
  o.bones = static_cast<int>(t.F.rows()) + 1;
  try {
    recover_bones(t.V, t.F, frames, o);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("triangles"), std::string::npos) << e.what();
  }
  o.bones = 2;
  frames[1].conservativeResize(frames[1].rows() - 1, 3);
  EXPECT_THROW(recover_bones(t.V, t.F, frames, o), InputError);
  frames[1] = t.V;
  frames[1](0, 0) = std::nan("");
  EXPECT_THROW(recover_bones(t.V, t.F, frames, o), InputError);
  // A non-rigid starting transform where a rigid one is required.
  const SkinningRig lbs = lbs_rig_from_weights(t.V, Eigen::MatrixXd::Ones(t.V.rows(), 1), 1);
  BoneTransforms init(1, Eigen::Affine3d::Identity());
  init[0].linear() *= 2.0;
  try {
    fit_transforms_with_fixed_weights(lbs, t.V, init);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not rigid"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace bodymodel
