// Ground truth: frames generated from elephant-ddm-rig's true transforms and LBS weights; fitting
// SSD with the true transforms must recover the weights (max abs error ≤ 0.01, issue 7).
#include <gtest/gtest.h>

#include <algorithm>

#include "core/data_path.h"
#include "core/io/libigl_formats.h"
#include "core/io/mesh_io.h"
#include "skinning/fit_lbs.h"

namespace bodymodel {
namespace {

TEST(ElephantGroundTruth, SsdFitRecoversTheTrueWeights) {
  const auto dir = data_file("animations/elephant-ddm-rig");
  const Mesh rest = read_mesh(dir / "elephant.obj");
  const Eigen::MatrixXd W = read_dmat(dir / "elephant-weights.dmat");
  const std::vector<BoneTransforms> anim = read_transform_animation(dir / "elephant-anim.dmat");
  ASSERT_EQ(W.rows(), rest.V.rows());
  ASSERT_EQ(W.cols(), 24);
  ASSERT_EQ(anim.size(), 457u);
  SkinningExamples ex;
  ex.rest = rest.V;
  for (size_t f = 0; f < anim.size(); f += 3) {   // 153 frames (with 25, one vertex whose two
    // bones barely differ in the sampled frames misses by 0.06)
    // U_f = Σ_j w_ij [v_i 1] B_j(f), written out here independently of the skinning library.
    Eigen::MatrixX3d U = Eigen::MatrixX3d::Zero(rest.V.rows(), 3);
    for (int j = 0; j < 24; ++j)
      U += (W.col(j).asDiagonal() * ((rest.V * anim[f][j].linear().transpose()).rowwise() +
                                     anim[f][j].translation().transpose()));
    ex.transforms.push_back(anim[f]);
    ex.poses.push_back(U);
  }
  EXPECT_LT((ex.poses[0] - rest.V).cwiseAbs().maxCoeff(), 1e-9);   // frame 0 is the identity
  // Influence sets: the true support (weights above 1e-6), up to 16 bones.
  const SkinningRig support = lbs_rig_from_weights(rest.V, W, 16, 1e-6);
  LbsFitSummary s;
  const SkinningRig fitted = fit_lbs(ex, support.influences, {}, &s);
  EXPECT_LT(s.rms_residual, 1e-3);
  // Some bones move identically over the whole animation (0 = 14 = 19 and 2 = 3 = 6 = 10, to
  // 4e-15): only the sum of their weights is determined by any frames. Compare per group.
  std::vector<int> group(24);
  for (int a = 0; a < 24; ++a) {
    group[a] = a;
    for (int b = 0; b < a && group[a] == a; ++b) {
      double d = 0;
      for (const auto& fr : anim) d = std::max(d, (fr[a].matrix() - fr[b].matrix()).cwiseAbs().maxCoeff());
      if (d < 1e-9) group[a] = group[b];
    }
  }
  int merged = 0;
  for (int j = 0; j < 24; ++j) merged += group[j] != j;
  EXPECT_EQ(merged, 5);
  auto grouped = [&](const Eigen::MatrixXd& M) {
    Eigen::MatrixXd G = Eigen::MatrixXd::Zero(M.rows(), 24);
    for (int j = 0; j < 24; ++j) G.col(group[j]) += M.col(j);
    return G;
  };
  const double err = (grouped(dense_weights(fitted)) - grouped(W)).cwiseAbs().maxCoeff();
  RecordProperty("max_abs_weight_error", std::to_string(err));
  EXPECT_LE(err, 0.01);
  // With influences chosen automatically (8 per vertex) the recovered weights stay close.
  LbsFitOptions o;
  o.max_influences = 8;
  const SkinningRig automatic = fit_lbs(ex, {}, o);
  const Eigen::MatrixXd diff = (grouped(dense_weights(automatic)) - grouped(W)).cwiseAbs();
  RecordProperty("auto_influence_max_abs_error", std::to_string(diff.maxCoeff()));
  EXPECT_LT(diff.rowwise().maxCoeff().mean(), 0.01);
}

}  // namespace
}  // namespace bodymodel
