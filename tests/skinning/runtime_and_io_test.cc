// The float32 runtime evaluator against the double reference, and the .npz rig round trip.
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include "core/error.h"
#include "core/geometry.h"
#include "skinning/fit_animation_space.h"
#include "skinning/fit_lbs.h"
#include "skinning/fit_mwe.h"
#include "skinning/rig_io.h"
#include "skinning/runtime_skinning.h"
#include "synthetic_tube.h"

namespace bodymodel {
namespace {

struct Rigs {
  testing::SyntheticTube t;
  SkinningExamples ex;
  SkinningRig lbs, as, mwe;
};

Rigs make_rigs() {
  Rigs r;
  r.t = testing::make_tube();
  std::mt19937 rng(8);
  const SkinningRig truth = lbs_rig_from_weights(r.t.V, r.t.W, 3, 0.0);
  r.ex.rest = r.t.V;
  for (int p = 0; p < 12; ++p) {
    r.ex.transforms.push_back(testing::random_chain_pose(rng));
    Eigen::MatrixX3d P = evaluate_rig(truth, r.ex.transforms.back());
    P.col(1).array() += 0.01 * std::sin(p);   // something SSD cannot fit exactly
    r.ex.poses.push_back(P);
  }
  LbsFitOptions o;
  o.max_influences = 3;
  r.lbs = fit_lbs(r.ex, {}, o);
  r.as = fit_animation_space(r.ex, &r.lbs);
  r.mwe = fit_mwe(r.ex, &r.lbs);
  return r;
}

TEST(RuntimeSkinner, MatchesTheDoublePrecisionReference) {
  const Rigs r = make_rigs();
  std::mt19937 rng(99);
  const BoneTransforms M = testing::random_chain_pose(rng);
  const Eigen::MatrixX3d N = vertex_normals(r.t.V, r.t.F);
  for (const SkinningRig* rig : {&r.lbs, &r.as, &r.mwe}) {
    const RuntimeSkinner skinner(*rig, N);
    const Eigen::MatrixX3d ref = evaluate_rig(*rig, M);
    for (int threads : {1, 2}) {
      const Eigen::MatrixX3f X = skinner.pose(M, threads);
      EXPECT_LT((X.cast<double>() - ref).cwiseAbs().maxCoeff(), 1e-5) << skinning_method_name(rig->method);
    }
    // Normals: unit length, and for LBS close to the deformed mesh's own normals.
    std::vector<float> nx(r.t.V.rows()), ny(r.t.V.rows()), nz(r.t.V.rows());
    skinner.pose_normals(M, nx.data(), ny.data(), nz.data());
    const Eigen::MatrixX3d Nref = vertex_normals(ref, r.t.F);
    double mean_angle = 0;
    for (Eigen::Index i = 0; i < r.t.V.rows(); ++i) {
      const Eigen::Vector3d n(nx[i], ny[i], nz[i]);
      EXPECT_NEAR(n.norm(), 1.0, 1e-5);
      mean_angle += std::acos(std::clamp(n.dot(Nref.row(i).transpose()), -1.0, 1.0));
    }
    mean_angle *= 180 / M_PI / r.t.V.rows();
    EXPECT_LT(mean_angle, 10.0) << skinning_method_name(rig->method);
  }
}

// Every slot count 1..8 (each has its own unrolled kernel), unused slots (−1) included, for all
// three methods, against the double-precision reference.
TEST(RuntimeSkinner, EverySlotCountMatchesTheReference) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1, 1);
  const int n = 1001, B = 7;   // an odd count: the last block is partial
  BoneTransforms M(B, Eigen::Affine3d::Identity());
  for (int b = 0; b < B; ++b) {
    M[b].linear() = Eigen::AngleAxisd(2 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()).toRotationMatrix();
    M[b].translation() = Eigen::Vector3d(u(rng), u(rng), u(rng));
  }
  for (int K = 1; K <= 8; ++K)
    for (SkinningMethod method : {SkinningMethod::lbs, SkinningMethod::animation_space, SkinningMethod::mwe}) {
      SkinningRig rig;
      rig.method = method;
      rig.bone_count = B;
      rig.rest = Eigen::MatrixX3d::Random(n, 3);
      rig.influences.resize(n, K);
      const int c = coefficients_per_influence(method);
      rig.coefficients.resize(n, K * c);
      for (int i = 0; i < n; ++i) {
        double sum = 0;
        for (int k = 0; k < K; ++k) {
          rig.influences(i, k) = (k > 0 && (i + k) % 5 == 0) ? -1 : (i + 3 * k) % B;
          for (int q = 0; q < c; ++q) {
            rig.coefficients(i, k * c + q) = rig.influences(i, k) < 0 ? 0.0 : 0.1 + 0.9 * std::abs(u(rng));
          }
          sum += rig.coefficients(i, k * c);
        }
        if (method == SkinningMethod::lbs) rig.coefficients.row(i) /= sum;
      }
      const Eigen::MatrixX3d ref = evaluate_rig(rig, M);
      const RuntimeSkinner skinner(rig);
      for (int threads : {1, 2}) {
        const Eigen::MatrixX3f X = skinner.pose(M, threads);
        EXPECT_LT((X.cast<double>() - ref).cwiseAbs().maxCoeff(), 1e-5 * (1 + ref.cwiseAbs().maxCoeff()))
            << skinning_method_name(method) << " K=" << K << " threads=" << threads;
      }
    }
}

TEST(RuntimeSkinner, RejectsTooManyInfluencesAndWrongBoneCounts) {
  const Rigs r = make_rigs();
  SkinningRig wide = r.lbs;
  wide.bone_count = 9;
  wide.influences = Eigen::MatrixXi::Constant(wide.rest.rows(), 9, 0);
  for (int k = 0; k < 9; ++k) wide.influences.col(k).setConstant(k);
  wide.coefficients = Eigen::MatrixXd::Constant(wide.rest.rows(), 9, 1.0 / 9);
  EXPECT_THROW(RuntimeSkinner{wide}, InputError);
  const RuntimeSkinner s(r.lbs);
  EXPECT_THROW(s.pose(BoneTransforms(2, Eigen::Affine3d::Identity())), InputError);
}

TEST(RigIo, NpzRoundTripKeepsEveryCoefficient) {
  const Rigs r = make_rigs();
  const auto dir = std::filesystem::temp_directory_path() / ("bodymodel_rig_io_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  for (const SkinningRig* rig : {&r.lbs, &r.as, &r.mwe}) {
    const auto path = dir / (skinning_method_name(rig->method) + ".npz");
    save_rig(path, *rig, r.t.F, r.ex.transforms);
    Eigen::MatrixX3i F;
    std::vector<BoneTransforms> poses;
    const SkinningRig back = load_rig(path, &F, &poses);
    EXPECT_EQ(back.method, rig->method);
    EXPECT_EQ(back.influences, rig->influences);
    EXPECT_EQ((back.coefficients - rig->coefficients).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_EQ(F, r.t.F);
    ASSERT_EQ(poses.size(), r.ex.transforms.size());
    EXPECT_EQ((poses[3][1].matrix() - r.ex.transforms[3][1].matrix()).cwiseAbs().maxCoeff(), 0.0);
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bodymodel
