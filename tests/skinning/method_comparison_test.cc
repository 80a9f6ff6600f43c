// skinning/method_comparison.h: `skin eval`'s frame splits, cross-validation schemes and pooling.
#include <gtest/gtest.h>

#include <set>

#include "core/error.h"
#include "skinning/method_comparison.h"
#include "synthetic_tube.h"

namespace bodymodel {
namespace {

TEST(MethodComparison, LeaveOneOutHoldsOutEveryFrameButTheRest) {
  FrameSplitRequest r;
  r.leave_one_out = true;
  r.rest = 2;
  const FrameSplit s = split_frames(5, r);
  ASSERT_EQ(s.folds.size(), 4u);
  std::set<int> held;
  for (const auto& fold : s.folds) {
    EXPECT_EQ(fold.size(), 4u);
    EXPECT_TRUE(std::set<int>(fold.begin(), fold.end()).count(2)) << "the rest frame always trains";
    for (int f = 0; f < 5; ++f)
      if (!std::set<int>(fold.begin(), fold.end()).count(f)) held.insert(f);
  }
  EXPECT_EQ(held, (std::set<int>{0, 1, 3, 4}));
  EXPECT_EQ(s.rest, 2);
}

TEST(MethodComparison, SplitsByTheirRules) {
  FrameSplitRequest every;
  every.train_every = 2;
  const FrameSplit a = split_frames(7, every);
  EXPECT_EQ(a.folds.at(0), (std::vector<int>{0, 2, 4, 6}));
  EXPECT_FALSE(a.forecast);  // unseen frames lie between training frames
  EXPECT_EQ(a.rest, 0);

  FrameSplitRequest first;
  first.train_fraction = 0.5;
  const FrameSplit b = split_frames(10, first);
  EXPECT_EQ(b.folds.at(0), (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_TRUE(b.forecast);  // every unseen frame comes after the training ones

  FrameSplitRequest listed;
  listed.train = {3, 1};
  listed.explicit_test = true;
  const FrameSplit c = split_frames(4, listed);
  EXPECT_EQ(c.rest, 1);
  EXPECT_FALSE(c.forecast);  // an explicit split is no forecast

  FrameSplitRequest all;
  all.train = {0, 1, 2};
  EXPECT_THROW(split_frames(3, all), InputError);  // no unseen frame left
  FrameSplitRequest out_of_range;
  out_of_range.train = {0, 7};
  EXPECT_THROW(split_frames(3, out_of_range), InputError);
}

TEST(MethodComparison, CrossValidationSchemesFromText) {
  EXPECT_EQ(parse_cv_scheme("auto", true).scheme, CvScheme::last);
  EXPECT_EQ(parse_cv_scheme("auto", false).scheme, CvScheme::interleaved);
  EXPECT_EQ(parse_cv_scheme("none", false).scheme, CvScheme::none);
  const SkinCrossValidationOptions k = parse_cv_scheme("folds:3", false);
  EXPECT_EQ(k.scheme, CvScheme::interleaved);
  EXPECT_EQ(k.folds, 3);
  EXPECT_EQ(parse_cv_scheme("last:2", false).held_out, 2);
  for (const char* bad : {"folds:", "folds:x", "last:-1", "sometimes"}) EXPECT_THROW(parse_cv_scheme(bad, false), InputError) << bad;
}

TEST(MethodComparison, OneFoldPoolsExactlyTheSequenceEvaluation) {
  const auto t = testing::make_tube(21, 12);
  SkinningExamples ex = testing::bulging_examples(t, 8, 11);
  std::vector<Eigen::MatrixX3d> frames{t.V};
  frames.insert(frames.end(), ex.poses.begin(), ex.poses.end());
  SequenceEvaluationOptions o;
  o.methods = {SkinningModel::ssd, SkinningModel::as};
  o.recovery.bones = 3;
  o.max_influences = 3;
  o.cv.folds = 3;
  o.cv.as_ridges = {1e-3};
  FrameSplitRequest r;
  r.train = {0, 1, 2, 4, 5, 7};
  const FrameSplit split = split_frames(int(frames.size()), r);
  const SkinningComparison c = compare_skinning_methods(frames, t.F, split, o);
  o.rest_frame = split.rest;
  const SequenceEvaluation direct = evaluate_skinning_sequence(frames, t.F, r.train, o);
  for (const auto& row : direct.rows) {
    const size_t m = row.method == SkinningModel::ssd ? 0 : 1;
    const DeviationStats& pooled = row.split == "train" ? c.train[m] : c.unseen[m];
    EXPECT_EQ(pooled.frames, row.stats.frames);
    EXPECT_NEAR(pooled.mean_geometric(), row.stats.mean_geometric(), 1e-12 + 1e-9 * row.stats.mean_geometric());
  }
  EXPECT_EQ(c.frame_split, (std::vector<std::string>{"train", "train", "train", "unseen", "train", "train", "unseen",
                                                     "train", "unseen"}));
  ASSERT_LE(c.cv_rows.size(), 1u);  // at most AS's single ridge candidate, then chosen
  for (const CvCandidateRow& row : c.cv_rows) EXPECT_TRUE(row.chosen);
}

}  // namespace
}  // namespace bodymodel
