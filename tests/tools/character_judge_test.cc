// Judging rigs on poses that are not the model's own (tools/pipeline/character_judge.h), on a
// small synthetic limb: a tube around a chain of four bones, skinned with smooth weights.
//   - the pose fit recovers known joint rotations and a rigid placement from the posed mesh;
//   - inverting linear blend skinning returns the rest mesh;
//   - judged on poses made by the true weights, the true rig (as LBS and written as MWE) fits
//     them to numerical precision while a rig with rigid (nearest-bone) weights cannot: the
//     ordering of rigs the judge is for;
//   - bad input: --unpose without --in is one clear line and a non-zero exit.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "core/rotation.h"
#include "support/run_cli.h"
#include "tools/pipeline/character.h"
#include "tools/pipeline/character_judge.h"

namespace bodymodel {
namespace {

struct Limb {
  Skeleton sk;
  Eigen::MatrixX3d V;
  Eigen::MatrixX3i F;  // the tube's side (open at both ends)
  Eigen::MatrixXd W;   // smooth weights
  Eigen::MatrixXd Wr;  // rigid: each vertex on its nearest bone only
  std::vector<char> driven;
};

// Bones 0 (root) … 3 along +y, 100 mm each; a tube of radius 30 mm, 24 rings of 12 vertices.
Limb make_limb() {
  Limb l;
  const int B = 4;
  l.sk.names = {"root", "a", "b", "c"};
  l.sk.parents = {-1, 0, 1, 2};
  l.sk.heads.resize(B, 3);
  l.sk.tails.resize(B, 3);
  for (int b = 0; b < B; ++b) {
    l.sk.heads.row(b) << 0, 100.0 * b, 0;
    l.sk.tails.row(b) << 0, 100.0 * (b + 1), 0;
  }
  const int rings = 24, around = 12;
  l.V.resize(rings * around, 3);
  l.W = Eigen::MatrixXd::Zero(rings * around, B);
  l.Wr = Eigen::MatrixXd::Zero(rings * around, B);
  for (int r = 0; r < rings; ++r) {
    const double y = 400.0 * (r + 0.5) / rings;
    for (int k = 0; k < around; ++k) {
      const int v = r * around + k;
      const double a = 2 * M_PI * k / around;
      l.V.row(v) << 30 * std::cos(a), y, 30 * std::sin(a);
      // Hat functions centred on the bones' middles: weights blend over each joint.
      double sum = 0;
      for (int b = 0; b < B; ++b) {
        const double w = std::max(0.0, 1.0 - std::abs(y - (100.0 * b + 50)) / 100.0);
        l.W(v, b) = w;
        sum += w;
      }
      if (sum == 0) l.W(v, y < 50 ? 0 : B - 1) = sum = 1;
      l.W.row(v) /= sum;
      l.Wr(v, std::min(B - 1, static_cast<int>(y / 100))) = 1;
    }
  }
  l.F.resize(2 * (rings - 1) * around, 3);
  for (int r = 0, f = 0; r + 1 < rings; ++r)
    for (int k = 0; k < around; ++k) {
      const int a = r * around + k, b = r * around + (k + 1) % around;
      l.F.row(f++) << a, b + around, b;
      l.F.row(f++) << a, a + around, b + around;
    }
  l.driven.assign(B, 1);
  return l;
}

Pose known_pose(int bones, double scale) {
  Pose p = Pose::rest(bones);
  p.rotations[1] = rotation_from_vector(scale * Eigen::Vector3d(0.5, 0.1, 0.2));
  p.rotations[2] = rotation_from_vector(scale * Eigen::Vector3d(-0.2, 0.3, 0.6));
  p.rotations[3] = rotation_from_vector(scale * Eigen::Vector3d(0.1, -0.4, -0.3));
  return p;
}

Eigen::Affine3d known_placement() {
  Eigen::Affine3d G = Eigen::Affine3d::Identity();
  G.linear() = rotation_from_vector(Eigen::Vector3d(0.1, 0.35, -0.2));
  G.translation() << 120, -40, 75;
  return G;
}

Eigen::MatrixX3d posed(const SkinningRig& rig, const Skeleton& sk, const Pose& p, const Eigen::Affine3d& G) {
  const Eigen::MatrixX3d X = evaluate_rig(rig, forward_kinematics(sk, p));
  return (X * G.linear().transpose()).rowwise() + G.translation().transpose();
}

TEST(CharacterJudge, PoseFitRecoversKnownRotationsAndPlacement) {
  const Limb l = make_limb();
  const SkinningRig rig = lbs_rig_from_weights(l.V, l.W, 4);
  const Pose truth = known_pose(4, 1.0);
  const Eigen::MatrixX3d Y = posed(rig, l.sk, truth, known_placement());
  // From the rest pose, as a judged pose without a pose file starts.
  const RigPoseFit f = fit_rig_pose(rig, l.sk, l.driven, Y, Pose::rest(4));
  EXPECT_LT(f.rms_mm, 1e-3);
  for (int b = 1; b < 4; ++b) EXPECT_LT(rotation_angle_deg(f.pose.rotations[b], truth.rotations[b]), 0.01) << b;
  EXPECT_LT(rotation_angle_deg(f.placement.linear(), known_placement().linear()), 0.01);
  EXPECT_LT((f.placement.translation() - known_placement().translation()).norm(), 1e-3);
}

TEST(CharacterJudge, InverseSkinningReturnsTheRestMesh) {
  const Limb l = make_limb();
  SkinWeights W = l.W.sparseView();
  BoneTransforms M = forward_kinematics(l.sk, known_pose(4, 1.0));
  for (auto& m : M) m = known_placement() * m;
  const Eigen::MatrixX3d Y = linear_blend_skinning(l.V, W, M);
  const Eigen::MatrixX3d X = inverse_linear_blend_skinning(Y, l.W, M);
  EXPECT_LT((X - l.V).rowwise().norm().maxCoeff(), 1e-9);
}

TEST(CharacterJudge, TrueRigsFitRealPosesAndRigidWeightsDoNot) {
  const Limb l = make_limb();
  const SkinningRig truth = lbs_rig_from_weights(l.V, l.W, 4);
  const SkinningRig as_mwe = lbs_as_mwe(truth);
  const SkinningRig rigid = lbs_rig_from_weights(l.V, l.Wr, 4);
  std::vector<JudgePose> poses;
  for (double s : {0.5, 1.0}) {
    JudgePose p;
    p.name = "s" + std::to_string(s);
    p.target = posed(truth, l.sk, known_pose(4, s), known_placement());
    p.start = Pose::rest(4);
    p.scan = Mesh{p.target, l.F};   // the pose's own surface as its scan
    poses.push_back(p);
  }
  const std::vector<JudgeRow> rows =
      judge_rigs_on_poses({{"truth", &truth}, {"mwe", &as_mwe}, {"rigid", &rigid}}, l.sk, l.driven, l.F, poses);
  ASSERT_EQ(rows.size(), 3u * 3u);
  auto all = [&](const std::string& m) {
    for (auto& r : rows)
      if (r.method == m && r.pose == "all") return r;
    ADD_FAILURE() << m;
    return JudgeRow{};
  };
  EXPECT_EQ(all("truth").poses, 2);
  EXPECT_LT(all("truth").max_mm, 1e-2);
  EXPECT_LT(all("mwe").max_mm, 1e-2);
  // Rigid weights crease at the joints: millimetres, not microns, whatever the pose fit does.
  EXPECT_GT(all("rigid").mean_mm, 0.5);
  EXPECT_GT(all("rigid").max_mm, 5.0);
  // The same ordering in the surface distance to the scans, which ignores sliding along it.
  EXPECT_LT(all("truth").scan_two_sided_mm, 0.05);
  EXPECT_GT(all("rigid").scan_two_sided_mm, 10 * all("truth").scan_two_sided_mm);
  EXPECT_GT(all("rigid").scan_two_sided_mm, 0.2);
  // The CSV carries a row per rig and pose plus the pooled rows.
  const std::string csv = judge_csv(rows, poses);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 1 + 9);
}

TEST(CharacterJudge, UnposeWithoutABodyIsOneClearLine) {
  const auto r = fixtures::run_cli("character no-model.npz --unpose --out /tmp/bodymodel_judge_never");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--unpose needs --in"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace bodymodel
