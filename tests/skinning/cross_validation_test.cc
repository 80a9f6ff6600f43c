// Cross-validation of the regularisation on training examples only, the MWE ridge path, and MWE
// over an Animation Space base.
#include <gtest/gtest.h>

#include <random>

#include "core/error.h"
#include "skinning/cross_validation.h"
#include "skinning/fit_lbs.h"
#include "synthetic_tube.h"

namespace bodymodel {
namespace {

using testing::bulging_examples;
using testing::make_tube;

TEST(CrossValidation, FoldsOfBothSchemes) {
  SkinCrossValidationOptions o;
  o.folds = 3;
  const auto f = cv_folds(7, o);
  ASSERT_EQ(f.size(), 3u);
  EXPECT_EQ(f[0], (std::vector<int>{0, 3, 6}));
  EXPECT_EQ(f[2], (std::vector<int>{2, 5}));
  o.scheme = CvScheme::last;
  EXPECT_EQ(cv_folds(30, o), (std::vector<std::vector<int>>{{20, 21, 22, 23, 24, 25, 26, 27, 28, 29}}));
  o.held_out = 4;
  EXPECT_EQ(cv_folds(6, o)[0], (std::vector<int>{2, 3, 4, 5}));
  o.held_out = 6;
  EXPECT_THROW(cv_folds(6, o), InputError);
  EXPECT_THROW(cv_folds(1, o), InputError);
  o.scheme = CvScheme::none;
  EXPECT_TRUE(cv_folds(6, o).empty());
}

TEST(CrossValidation, MweRidgePathEqualsSeparateFits) {
  const auto t = make_tube(11, 8);
  const SkinningExamples ex = bulging_examples(t, 12, 5);
  const SkinningRig lbs = fit_lbs(ex, {}, {});
  MweFitOptions o;
  const std::vector<double> scales = {0, 1e-9, 1e-6, 1e-3};
  const std::vector<SkinningRig> path = fit_mwe_path(ex, &lbs, o, scales);
  ASSERT_EQ(path.size(), scales.size());
  for (size_t k = 0; k < scales.size(); ++k) {
    o.ridge_scale = scales[k];
    const SkinningRig one = fit_mwe(ex, &lbs, o);
    for (int p = 0; p < ex.pose_count(); ++p)
      EXPECT_LT((evaluate_rig(one, ex.transforms[static_cast<size_t>(p)]) -
                 evaluate_rig(path[k], ex.transforms[static_cast<size_t>(p)]))
                    .cwiseAbs()
                    .maxCoeff(),
                1e-8)
          << "s " << scales[k];
  }
  // A huge ridge leaves the base: MWE over SSD → SSD, MWE over AS → AS.
  o.ridge_scale = 1e6;
  const SkinningRig flat = fit_mwe(ex, &lbs, o);
  o.base = MweBase::animation_space;
  o.base_as_ridge = 1e-3;
  const SkinningRig over_as = fit_mwe(ex, &lbs, o);
  AnimationSpaceFitOptions ao;
  ao.ridge = 1e-3;
  const SkinningRig as = fit_animation_space(ex, &lbs, ao);
  // The tube has vertices with an exactly zero rest coordinate (the first ring, the caps' centres),
  // where the AS offset of that coordinate cannot be folded into MWE weights (W = p/ṽ): there the
  // SSD weight is kept; everywhere else the huge-ridge MWE over AS is AS.
  std::vector<bool> foldable(static_cast<size_t>(t.V.rows()));
  for (Eigen::Index i = 0; i < t.V.rows(); ++i) foldable[static_cast<size_t>(i)] = (t.V.row(i).array() != 0).all();
  for (int p = 0; p < ex.pose_count(); ++p) {
    const auto& M = ex.transforms[static_cast<size_t>(p)];
    EXPECT_LT((evaluate_rig(flat, M) - evaluate_rig(lbs, M)).cwiseAbs().maxCoeff(), 1e-6);
    const Eigen::MatrixX3d D = evaluate_rig(over_as, M) - evaluate_rig(as, M);
    for (Eigen::Index i = 0; i < D.rows(); ++i)
      if (foldable[static_cast<size_t>(i)]) {
        EXPECT_LT(D.row(i).cwiseAbs().maxCoeff(), 1e-6) << "vertex " << i;
      }
  }
}

TEST(CrossValidation, ChoosesStrongRegularisationForNoiseAndWeakForSignal) {
  // Poses of a true Animation Space rig (SSD weights times ṽ plus a perturbation of every p_k):
  // clean, cross-validation must leave the fit free (small λ); drowned in noise ten times the
  // perturbation, it must shrink towards the SSD prior (large λ).
  const auto t = make_tube(11, 8);
  std::mt19937 rng(11);
  const SkinningRig as = testing::animation_space_truth(t, rng, 0.005);
  SkinningExamples clean;
  clean.rest = t.V;
  for (int p = 0; p < 15; ++p) {
    clean.transforms.push_back(testing::random_chain_pose(rng));
    clean.poses.push_back(evaluate_rig(as, clean.transforms.back()));
  }
  SkinningExamples noisy = clean;
  std::normal_distribution<double> n(0, 0.05);
  for (auto& P : noisy.poses)
    for (Eigen::Index i = 0; i < P.size(); ++i) P.data()[i] += n(rng);
  SkinCrossValidationOptions o;
  o.folds = 5;
  o.as_ridges = {1e-6, 1e-3, 1, 1e3};
  LbsFitOptions lo;
  lo.max_influences = 3;
  ModelFitOptions start;
  const CrossValidationResult rc = CrossValidator(clean, lo, o).select(SkinningModel::as, start);
  const CrossValidationResult rn = CrossValidator(noisy, lo, o).select(SkinningModel::as, start);
  EXPECT_EQ(rc.candidates.size(), 4u);
  EXPECT_LE(rc.chosen.animation_space.ridge, 1e-3) << rc.brief();
  EXPECT_GE(rn.chosen.animation_space.ridge, 1.0) << rn.brief();
  // The chosen setting has the smallest held-out error of the table.
  for (const auto& c : rn.candidates) EXPECT_GE(c.error, rn.chosen_error);
  // Nothing to choose for SSD.
  EXPECT_TRUE(CrossValidator(clean, lo, o).select(SkinningModel::ssd, start).candidates.empty());
}

TEST(CrossValidation, TooFewExamplesForAFoldIsAClearError) {
  const auto t = make_tube(5, 6);
  const SkinningExamples ex = bulging_examples(t, 3, 1);
  SkinCrossValidationOptions o;
  o.scheme = CvScheme::last;
  o.held_out = 2;   // leaves one example: AS needs two
  LbsFitOptions lo;
  lo.max_influences = 3;
  try {
    CrossValidator(ex, lo, o).select(SkinningModel::as, {});
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("a fold leaves 1 training example"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace bodymodel
