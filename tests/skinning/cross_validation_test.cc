// Cross-validation of the regularisation on training examples only, the MWE ridge path, and MWE
// over an Animation Space base.
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
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
  // The reported minimum is the table's smallest held-out error; the one-SE rule kept a setting no
  // weaker than it, within one paired standard error of it.
  for (const auto& c : rn.candidates) EXPECT_GE(c.error, rn.minimum_error);
  for (const auto& c : rn.candidates)
    if (c.setting == rn.chosen_setting) {
      EXPECT_LE(rn.chosen_error, rn.minimum_error + c.paired_standard_error);
      for (const auto& m : rn.candidates)
        if (m.setting == rn.minimum_setting) EXPECT_GE(c.strength, m.strength);
    }
  // Nothing to choose for SSD.
  EXPECT_TRUE(CrossValidator(clean, lo, o).select(SkinningModel::ssd, start).candidates.empty());
}

// A hand-made cross-validation table: five ridges (strength = λ) measured on the same four
// held-out examples. The smallest mean is λ 1e-2 (0.100); λ 1e-1 is 0.0025 above it with paired
// differences {0.002, 0.003, 0.002, 0.003} (paired SE 0.00029: outside); λ 1 is 0.0005 above with
// differences {−0.001, 0.002, −0.001, 0.002} (paired SE 0.00087: inside); λ 10 is 0.02 above.
// The examples differ from each other by about ±0.05, so the unpaired SE of the minimum (0.026)
// takes in every candidate and the unpaired rule falls back to the strongest ridge.
std::vector<CvCandidate> hand_made_table() {
  const std::vector<double> base = {0.05, 0.15, 0.06, 0.14};   // mean 0.10
  auto cand = [&](double l, std::vector<double> delta) {
    CvCandidate c;
    c.setting = "λ " + std::to_string(l);
    c.strength = {l};
    for (size_t i = 0; i < base.size(); ++i) c.example_errors.push_back(base[i] + delta[i]);
    for (double e : c.example_errors) c.error += e / double(base.size());
    return c;
  };
  return {cand(1e-3, {0.01, 0.01, 0.012, 0.008}), cand(1e-2, {0, 0, 0, 0}), cand(1e-1, {0.002, 0.003, 0.002, 0.003}),
          cand(1, {-0.001, 0.002, -0.001, 0.002}), cand(10, {0.02, 0.02, 0.02, 0.02})};
}

TEST(CrossValidation, OneStandardErrorRuleKeepsTheMostRegularisedCandidateWithinOneSE) {
  std::vector<CvCandidate> t = hand_made_table();
  EXPECT_EQ(select_candidate(t, CvRule::minimum), 1u);
  // Paired: λ 1 (index 3) is the strongest within one SE of the minimum; λ 1e-1 is not within,
  // which shows the rule does not simply take every candidate up to the strongest one inside.
  EXPECT_EQ(select_candidate(t, CvRule::one_se), 3u);
  EXPECT_NEAR(t[3].paired_standard_error, 0.0017320508 / 2, 1e-9);   // sd {−.001,.002,−.001,.002} / √4
  EXPECT_NEAR(t[2].paired_standard_error, 0.00057735027 / 2, 1e-9);
  EXPECT_DOUBLE_EQ(t[1].paired_standard_error, 0.0);
  EXPECT_GT(t[2].error - t[1].error, t[2].paired_standard_error);
  EXPECT_LE(t[3].error - t[1].error, t[3].paired_standard_error);
  // Unpaired: the pose-to-pose spread (SE 0.026) covers λ 10 too.
  EXPECT_EQ(select_candidate(t, CvRule::one_se_unpaired), 4u);
  EXPECT_NEAR(t[1].standard_error, 0.026140645, 1e-8);
  // Order of the table does not matter: strength decides, not position.
  std::reverse(t.begin(), t.end());
  EXPECT_EQ(t[select_candidate(t, CvRule::one_se)].strength, std::vector<double>{1.0});
  // A lexicographic strength (MWE: s first, then fewer influences): at equal s the second key decides.
  std::vector<CvCandidate> m = hand_made_table();
  m[3].strength = {1, -4};
  m.push_back(m[3]);
  m.back().strength = {1, -2};
  EXPECT_EQ(select_candidate(m, CvRule::one_se), 5u);
  // Another structure (e.g. MWE over SSD instead of AS) is never a fallback, however strong.
  m.push_back(m[1]);
  m.back().strength = {1e6};
  m.back().structure = {1};
  EXPECT_EQ(select_candidate(m, CvRule::one_se), 5u);
  EXPECT_EQ(select_candidate(m, CvRule::one_se_unpaired), 4u);
  m.pop_back();
  // A candidate whose fit failed (infinite error) is never kept, even as the strongest.
  m[4].error = std::numeric_limits<double>::infinity();
  m[4].strength = {1e9};
  EXPECT_EQ(select_candidate(m, CvRule::one_se_unpaired), 5u);
}

TEST(CrossValidation, RuleNames) {
  for (CvRule r : {CvRule::minimum, CvRule::one_se, CvRule::one_se_unpaired})
    EXPECT_EQ(parse_cv_rule(cv_rule_name(r)), r);
  EXPECT_THROW(parse_cv_rule("1se"), InputError);
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
