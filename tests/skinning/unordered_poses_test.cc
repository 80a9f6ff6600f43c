// Sets of poses without an order (SCAPE): the protocol depends only on which frames train, not on
// the order in which they come.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "skinning/sequence_evaluation.h"
#include "synthetic_tube.h"

namespace bodymodel {
namespace {

TEST(UnorderedPoses, ShufflingTheFramesChangesNothing) {
  const auto t = testing::make_tube(21, 12);
  SkinningExamples ex = testing::bulging_examples(t, 12, 17);
  std::vector<Eigen::MatrixX3d> frames{t.V};   // frame 0: the rest pose
  frames.insert(frames.end(), ex.poses.begin(), ex.poses.end());
  const std::vector<int> train = {0, 1, 2, 4, 5, 7, 8, 10, 11};   // unseen: 3, 6, 9, 12
  SequenceEvaluationOptions o;
  o.methods = {SkinningModel::ssd, SkinningModel::as, SkinningModel::psd};
  o.recovery.bones = 3;
  o.max_influences = 3;
  o.cv.folds = 3;
  // One candidate per grid: folds are taken in the order the training frames come in, so with a
  // choice to make a shuffle may pick another setting; with none every method must agree.
  o.cv.as_ridges = {1e-3};
  o.cv.kernel_widths = {1};
  o.cv.rbf_ridges = {0.1};
  const SequenceEvaluation a = evaluate_skinning_sequence(frames, t.F, train, o);
  // The same frames in another order (rest frame and split carried along).
  std::vector<int> perm(frames.size());
  for (size_t i = 0; i < perm.size(); ++i) perm[i] = static_cast<int>(i);
  std::mt19937 rng(5);
  std::shuffle(perm.begin(), perm.end(), rng);
  std::vector<Eigen::MatrixX3d> shuffled(frames.size());
  std::vector<int> where(frames.size());
  for (size_t i = 0; i < perm.size(); ++i) shuffled[i] = frames[static_cast<size_t>(perm[i])], where[static_cast<size_t>(perm[i])] = static_cast<int>(i);
  std::vector<int> train_s;
  for (int f : train) train_s.push_back(where[static_cast<size_t>(f)]);
  o.rest_frame = where[0];
  const SequenceEvaluation b = evaluate_skinning_sequence(shuffled, t.F, train_s, o);
  ASSERT_EQ(a.rows.size(), b.rows.size());
  for (size_t r = 0; r < a.rows.size(); ++r) {
    EXPECT_EQ(a.rows[r].split, b.rows[r].split);
    EXPECT_EQ(a.rows[r].stats.frames, b.rows[r].stats.frames);
    EXPECT_NEAR(a.rows[r].stats.mean_geometric(), b.rows[r].stats.mean_geometric(),
                1e-6 * a.rows[r].stats.mean_geometric() + 1e-12)
        << skinning_model_name(a.rows[r].method) << " " << a.rows[r].split;
  }
}

}  // namespace
}  // namespace bodymodel
