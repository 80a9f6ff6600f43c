// Fitting SSD / Animation Space / MWE on synthetic rigs with known answers, and bad input.
#include <gtest/gtest.h>

#include <random>

#include "core/error.h"
#include "skinning/fit_animation_space.h"
#include "skinning/fit_lbs.h"
#include "skinning/fit_mwe.h"
#include "synthetic_tube.h"

namespace bodymodel {
namespace {

using testing::make_tube;
using testing::random_chain_pose;

using testing::bulging_examples;
using testing::lbs_examples;

TEST(FitLbs, RecoversKnownWeightsWithTrueInfluences) {
  const auto t = make_tube();
  const SkinningExamples ex = lbs_examples(t, 8, 7);
  Eigen::MatrixXi I(t.V.rows(), 3);
  for (Eigen::Index i = 0; i < I.rows(); ++i) I.row(i) << 0, 1, 2;
  LbsFitSummary s;
  const SkinningRig rig = fit_lbs(ex, I, {}, &s);
  const Eigen::MatrixXd W = dense_weights(rig);
  EXPECT_LT((W - t.W).cwiseAbs().maxCoeff(), 1e-5);
  EXPECT_LT(s.rms_residual, 1e-6);
  for (Eigen::Index i = 0; i < W.rows(); ++i) {
    EXPECT_NEAR(W.row(i).sum(), 1.0, 1e-12);
    EXPECT_GE(W.row(i).minCoeff(), 0.0);
  }
}

TEST(FitLbs, AutomaticInfluencesStillRecoverWeights) {
  const auto t = make_tube();
  const SkinningExamples ex = lbs_examples(t, 8, 3);
  LbsFitOptions o;
  o.max_influences = 2;   // the tube's vertices have at most 2 non-zero weights
  const SkinningRig rig = fit_lbs(ex, {}, o);
  EXPECT_LT((dense_weights(rig) - t.W).cwiseAbs().maxCoeff(), 1e-4);
}

TEST(FitLbs, NonNegativeLeastSquaresMatchesKnownSolution) {
  // min ‖x − (1, −2, 3)‖² with x ≥ 0 → (1, 0, 3).
  const Eigen::MatrixXd H = Eigen::MatrixXd::Identity(3, 3);
  const Eigen::VectorXd x = nonnegative_least_squares(H, Eigen::Vector3d(1, -2, 3));
  EXPECT_NEAR(x(0), 1, 1e-12);
  EXPECT_NEAR(x(1), 0, 1e-12);
  EXPECT_NEAR(x(2), 3, 1e-12);
}

TEST(FitAnimationSpace, ReproducesTrainingPosesOfAnAnimationSpaceRig) {
  const auto t = make_tube();
  std::mt19937 rng(11);
  // A true AS rig: SSD weights times ṽ plus a random perturbation of each p_k.
  SkinningRig truth = lbs_rig_from_weights(t.V, t.W, 3, 0.0);
  const SkinningRig as = testing::animation_space_truth(t, rng, 0.02);
  SkinningExamples ex;
  ex.rest = t.V;
  for (int p = 0; p < 10; ++p) {
    ex.transforms.push_back(random_chain_pose(rng));
    ex.poses.push_back(evaluate_rig(as, ex.transforms.back()));
  }
  const SkinningRig lbs = fit_lbs(ex, truth.influences);
  AnimationSpaceFitOptions o;
  o.ridge = 1e-9;
  AnimationSpaceFitSummary s;
  fit_animation_space(ex, &lbs, o, &s);
  LbsFitSummary ls;
  fit_lbs(ex, truth.influences, {}, &ls);
  EXPECT_LT(s.rms_residual, 1e-5);
  EXPECT_GT(ls.rms_residual, 100 * s.rms_residual);   // SSD cannot represent it
}

TEST(FitMwe, ReproducesTrainingPosesOfAnMweRigWithoutRegularisation) {
  const auto t = make_tube();
  std::mt19937 rng(5);
  SkinningRig truth = lbs_as_mwe(lbs_rig_from_weights(t.V, t.W, 3, 0.0));
  std::normal_distribution<double> g(0, 0.05);
  for (Eigen::Index i = 0; i < truth.coefficients.rows(); ++i)
    for (Eigen::Index c = 0; c < truth.coefficients.cols(); ++c)
      if (truth.coefficients(i, c) > 0) truth.coefficients(i, c) += g(rng);
  SkinningExamples ex;
  ex.rest = t.V;
  for (int p = 0; p < 20; ++p) {   // ≥ 4n + 1 = 13 poses: every MWE weight is determined
    ex.transforms.push_back(random_chain_pose(rng));
    ex.poses.push_back(evaluate_rig(truth, ex.transforms.back()));
  }
  MweFitOptions o;
  o.ridge_scale = 0;
  o.variance_kept = 1.0;
  o.singular_value_tolerance = 1e-14;
  MweFitSummary s;
  const SkinningRig lbs = fit_lbs(ex, lbs_rig_from_weights(t.V, t.W, 3, 0.0).influences, {});
  fit_mwe(ex, &lbs, o, &s);
  EXPECT_LT(s.rms_residual, 1e-6);
}

TEST(FitMwe, RegularisedFitBeatsSsdOnUnseenPosesOfABulgingTube) {
  const auto t = make_tube();
  const SkinningExamples train = bulging_examples(t, 12, 21);
  const SkinningExamples test = bulging_examples(t, 10, 99);
  const SkinningRig lbs = fit_lbs(train, {}, {});
  MweFitSummary ms;
  const SkinningRig mwe = fit_mwe(train, &lbs, {}, &ms);
  const SkinningRig as = fit_animation_space(train, &lbs, {});
  double e_lbs, e_mwe, e_as;
  rig_residuals(lbs, test, &e_lbs, nullptr);
  rig_residuals(mwe, test, &e_mwe, nullptr);
  rig_residuals(as, test, &e_as, nullptr);
  EXPECT_LT(ms.rms_residual, 0.5 * e_lbs);   // fits the training bulge
  EXPECT_LT(e_mwe, e_lbs);                   // and generalises better than SSD
  EXPECT_LT(e_as, e_lbs);
}

TEST(FitMwe, DuplicatePosesAreAveraged) {
  // Two copies of one pose with different targets: the fit must land on their average.
  const auto t = make_tube(5, 6);
  std::mt19937 rng(2);
  SkinningExamples ex = lbs_examples(t, 14, 4);
  ex.transforms.push_back(ex.transforms[0]);
  ex.poses.push_back(ex.poses[0].array() + 0.01);
  ex.poses[0].array() -= 0.01;
  MweFitOptions o;
  o.ridge_scale = 0;
  o.variance_kept = 1.0;
  MweFitSummary s;
  const SkinningRig mwe = fit_mwe(ex, nullptr, o, &s);
  EXPECT_EQ(s.unique_poses_min, 14);
  const Eigen::MatrixX3d X = evaluate_rig(mwe, ex.transforms[0]);
  EXPECT_LT((X - (ex.poses[0].array() + 0.01).matrix()).cwiseAbs().maxCoeff(), 1e-6);
}

TEST(FitErrors, BadInputIsRejectedWithClearMessages) {
  const auto t = make_tube(5, 6);
  SkinningExamples ex = lbs_examples(t, 4, 1);
  {
    SkinningExamples bad = ex;
    bad.poses[2].conservativeResize(bad.poses[2].rows() - 1, 3);
    try {
      fit_lbs(bad);
      FAIL() << "no error";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("pose 2 has"), std::string::npos) << e.what();
    }
  }
  {
    SkinningExamples bad = ex;
    bad.transforms[1][2].linear() *= 1.2;   // a scale: not rigid
    try {
      fit_lbs(bad);
      FAIL() << "no error";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("pose 1 bone 2 is not rigid"), std::string::npos) << e.what();
    }
    EXPECT_NO_THROW(fit_mwe(bad));   // MWE absorbs any affine transform
  }
  {
    SkinningExamples bad = ex;
    bad.poses[3](5, 1) = std::nan("");
    EXPECT_THROW(fit_lbs(bad), InputError);
    EXPECT_THROW(fit_mwe(bad), InputError);
    EXPECT_THROW(fit_animation_space(bad), InputError);
  }
  {
    SkinningExamples bad = ex;
    bad.transforms.pop_back();
    EXPECT_THROW(fit_lbs(bad), InputError);
  }
}

}  // namespace
}  // namespace bodymodel
