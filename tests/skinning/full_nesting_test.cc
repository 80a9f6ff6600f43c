// Full nesting of the cross-validation (--cv-nesting full): each fold recovers its own bones from
// its training part, and the held-out examples are posed with bone maps fitted afterwards (weights
// held fixed), never with maps fitted together with them. Also the moment forms of the fixed-weight
// transform fit and of the SSD normal equations against the per-vertex implementations they replace.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "core/error.h"
#include "skinning/bone_recovery.h"
#include "skinning/cross_validation.h"
#include "skinning/fit_lbs.h"
#include "skinning/sequence_evaluation.h"
#include "synthetic_tube.h"

namespace bodymodel {
namespace {

struct TubeSequence {
  testing::SyntheticTube t = testing::make_tube(15, 10);
  SequenceEvaluationOptions o;
  PreparedSequence prep;
  LbsFitOptions lo;
  TubeSequence() {
    const SkinningExamples ex = testing::bulging_examples(t, 10, 23);
    std::vector<Eigen::MatrixX3d> frames{t.V};   // frame 0: the rest pose
    frames.insert(frames.end(), ex.poses.begin(), ex.poses.end());
    o.recovery.bones = 3;
    o.max_influences = 3;
    o.alternations = 3;
    o.cv.folds = 3;
    o.cv.as_ridges = {1e-6, 1e-3, 1e-1, 10};
    std::vector<int> train(frames.size());
    for (size_t f = 0; f < train.size(); ++f) train[f] = static_cast<int>(f);
    prep = prepare_skinning_sequence(frames, t.F, train, o);
    lo = o.lbs;
    lo.max_influences = o.max_influences;
    lo.require_rigid = false;
  }
  FoldBoneFitter fitter() const {
    return [this](const std::vector<int>& tr, const std::vector<int>& h) {
      return fit_fold_bones(prep.examples, t.F, tr, h, o);
    };
  }
};

TEST(FullNesting, HeldOutPosesNeverShapeTheFoldsBones) {
  const TubeSequence s;
  const std::vector<int> train = {0, 1, 2, 4, 5, 7, 8, 10}, held = {3, 6, 9};
  const FoldBones a = fit_fold_bones(s.prep.examples, s.t.F, train, held, s.o);
  ASSERT_EQ(a.train.pose_count(), 8);
  ASSERT_EQ(a.held_out.size(), 3u);
  // Move a held-out pose far away: the fold's bones and weights must not move at all.
  SkinningExamples moved = s.prep.examples;
  moved.poses[6] = moved.poses[6] * 1.3 + Eigen::MatrixX3d::Constant(moved.poses[6].rows(), 3, 0.2);
  const FoldBones b = fit_fold_bones(moved, s.t.F, train, held, s.o);
  for (int p = 0; p < 8; ++p)
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(a.train.transforms[static_cast<size_t>(p)][static_cast<size_t>(k)].matrix(),
                b.train.transforms[static_cast<size_t>(p)][static_cast<size_t>(k)].matrix());
  EXPECT_EQ(a.lbs.coefficients, b.lbs.coefficients);
  EXPECT_EQ(a.lbs.influences, b.lbs.influences);
  // Its own bone maps do follow it (they are fitted to it, after the weights).
  EXPECT_GT((a.held_out[1][0].translation() - b.held_out[1][0].translation()).norm(), 0.05);
  // The held-out maps explain their poses about as well as the training frames' maps do theirs.
  double held_rms = 0;
  for (size_t k = 0; k < held.size(); ++k)
    held_rms += (evaluate_rig(a.lbs, a.held_out[k]) - s.prep.examples.poses[static_cast<size_t>(held[k])]).squaredNorm();
  held_rms = std::sqrt(held_rms / (3.0 * s.t.V.rows()));
  EXPECT_LT(held_rms, 0.05) << "held-out bone maps do not fit their poses";
  EXPECT_THROW(fit_fold_bones(s.prep.examples, s.t.F, {0, 1, 3}, {3}, s.o), InputError);
  EXPECT_THROW(fit_fold_bones(s.prep.examples, s.t.F, {0, 1}, {11}, s.o), InputError);
}

TEST(FullNesting, HeldOutErrorsUseEachFoldsOwnBonesAndTheArgminIsChosen) {
  const TubeSequence s;
  SkinCrossValidationOptions weights = s.o.cv, full = s.o.cv;
  full.nesting = CvNesting::full;
  EXPECT_THROW(CrossValidator(s.prep.examples, s.lo, full), InputError);   // no bone fit to refit with
  const CrossValidator leaky(s.prep.examples, s.lo, weights), nested(s.prep.examples, s.lo, full, {}, s.fitter());
  ASSERT_EQ(nested.folds(), 3);
  // Weights nesting poses held-out examples with the maps fitted with all training frames; full
  // nesting with maps fitted after the fold's own bones: they differ.
  double moved = 0;
  for (int f = 0; f < nested.folds(); ++f)
    for (size_t k = 0; k < nested.held_out(f).size(); ++k) {
      const int p = nested.held_out(f)[k];
      EXPECT_EQ(leaky.held_out_transforms(f, static_cast<int>(k))[1].matrix(),
                s.prep.examples.transforms[static_cast<size_t>(p)][1].matrix());
      for (int b = 0; b < 3; ++b)
        moved = std::max(moved, (nested.held_out_transforms(f, static_cast<int>(k))[static_cast<size_t>(b)].matrix() -
                                 s.prep.examples.transforms[static_cast<size_t>(p)][static_cast<size_t>(b)].matrix())
                                    .cwiseAbs()
                                    .maxCoeff());
    }
  EXPECT_GT(moved, 1e-6);
  const CrossValidationResult rl = leaky.select(SkinningModel::as, s.o.fit);
  const CrossValidationResult rn = nested.select(SkinningModel::as, s.o.fit);
  ASSERT_EQ(rn.candidates.size(), 4u);
  double differs = 0;
  for (size_t c = 0; c < rn.candidates.size(); ++c)
    differs = std::max(differs, std::abs(rn.candidates[c].error - rl.candidates[c].error) / rl.candidates[c].error);
  EXPECT_GT(differs, 1e-4) << "full nesting gave the leaky held-out errors";
  // The chosen candidate is the argmin of the nested table.
  size_t argmin = 0;
  for (size_t c = 0; c < rn.candidates.size(); ++c)
    if (rn.candidates[c].error < rn.candidates[argmin].error) argmin = c;
  EXPECT_EQ(rn.chosen_setting, rn.candidates[argmin].setting);
  // Recomputed by hand from the fold's own bones (vertex distance, every 4th vertex): the table's
  // per-example errors of one candidate.
  const CvCandidate& c = rn.candidates[1];
  std::vector<double> by_hand;
  for (int f = 0; f < nested.folds(); ++f) {
    const FittedModel m = fit_model(SkinningModel::as, nested.fold_train(f), nested.fold_lbs(f), c.options);
    for (size_t k = 0; k < nested.held_out(f).size(); ++k) {
      const Eigen::MatrixX3d X = m.pose(nested.held_out_transforms(f, static_cast<int>(k)));
      const Eigen::MatrixX3d& Y = s.prep.examples.poses[static_cast<size_t>(nested.held_out(f)[k])];
      double sum = 0;
      int count = 0;
      for (Eigen::Index i = 0; i < X.rows(); i += 4, ++count) sum += (X.row(i) - Y.row(i)).norm();
      by_hand.push_back(sum / count);
    }
  }
  ASSERT_EQ(by_hand.size(), c.example_errors.size());
  for (size_t k = 0; k < by_hand.size(); ++k) EXPECT_NEAR(by_hand[k], c.example_errors[k], 1e-12 + 1e-9 * by_hand[k]);
  for (CvNesting n : {CvNesting::weights, CvNesting::full}) EXPECT_EQ(parse_cv_nesting(cv_nesting_name(n)), n);
  EXPECT_THROW(parse_cv_nesting("leaky"), InputError);
}

TEST(FullNesting, EvaluationRunsWithEitherNesting) {
  const TubeSequence s;
  std::vector<Eigen::MatrixX3d> frames{s.t.V};
  frames.insert(frames.end(), s.prep.examples.poses.begin() + 1, s.prep.examples.poses.end());
  SequenceEvaluationOptions o = s.o;
  o.methods = {SkinningModel::ssd, SkinningModel::as};
  const std::vector<int> train = {0, 1, 2, 4, 5, 7, 8, 10};
  const SequenceEvaluation w = evaluate_skinning_sequence(frames, s.t.F, train, o);
  o.cv.nesting = CvNesting::full;
  const SequenceEvaluation f = evaluate_skinning_sequence(frames, s.t.F, train, o);
  // SSD has nothing to cross-validate: identical under both nestings; AS's held-out table is not.
  EXPECT_EQ(w.rows[0].stats.mean_geometric(), f.rows[0].stats.mean_geometric());
  EXPECT_NE(w.fits[1].cv.candidates[0].error, f.fits[1].cv.candidates[0].error);
}

TEST(MomentForms, TransformFitAndSsdNormalEquationsMatchThePerVertexSums) {
  const TubeSequence s;
  const SkinningRig& lbs = s.prep.lbs;
  std::mt19937 rng(3);
  for (int p = 1; p < 5; ++p) {
    const Eigen::MatrixX3d& Q = s.prep.examples.poses[static_cast<size_t>(p)];
    const BoneTransforms start = fit_section_transforms(s.t.V, s.prep.recovered.vertex_bone, 3, Q);
    const BoneTransforms a = fit_transforms_with_fixed_weights(lbs, Q, start, 10);
    const BoneTransforms b = fit_transforms_with_fixed_weights_per_vertex(lbs, Q, start, 10);
    for (int k = 0; k < 3; ++k)
      EXPECT_LT((a[static_cast<size_t>(k)].matrix() - b[static_cast<size_t>(k)].matrix()).cwiseAbs().maxCoeff(), 1e-10);
    // And the fit does something: it moves away from the section maps toward a better fit.
    EXPECT_LT((evaluate_rig(lbs, a) - Q).norm(), (evaluate_rig(lbs, start) - Q).norm());
  }
  LbsFitOptions lo = s.lo, per_pose = s.lo;
  per_pose.pairwise_moments = false;
  const SkinningRig m = fit_lbs(s.prep.examples, {}, lo), r = fit_lbs(s.prep.examples, {}, per_pose);
  EXPECT_EQ(m.influences, r.influences);
  EXPECT_LT((m.coefficients - r.coefficients).cwiseAbs().maxCoeff(), 1e-9);
}

}  // namespace
}  // namespace bodymodel
