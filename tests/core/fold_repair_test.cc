// Fold repair (core/fold_repair.h): folds pushed into a sphere that is a scaled and rotated copy
// of the reference are put back at the copy's exact positions; the repair never increases the
// number of flipped triangles; bad input is an InputError.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "core/error.h"
#include "core/fold_repair.h"
#include "core/geometry.h"
#include "support/fixtures.h"

using namespace bodymodel;

namespace {

// s·R·ref + t (a body larger than and turned against its reference).
Eigen::MatrixX3d similar(const Eigen::MatrixX3d& ref, double s, const Eigen::Matrix3d& R, const Eigen::RowVector3d& t) {
  return ((s * ref * R.transpose()).rowwise() + t).eval();
}

// Two folds: vertices slid along the surface past their neighbours (one along the latitude,
// one along the meridian).
void fold(Eigen::MatrixX3d& V, int a, int b, double radius, const Eigen::RowVector3d& centre) {
  for (int k : {a, b}) {
    const Eigen::Vector3d p = V.row(k).transpose(), n = (V.row(k) - centre).transpose().normalized();
    const Eigen::Vector3d east = n.cross(Eigen::Vector3d::UnitY()).normalized(), north = east.cross(n);
    V.row(k) = (p + 0.3 * radius * (k == a ? east : north)).transpose();
  }
}

}  // namespace

TEST(FoldRepair, PutsFoldsBackOnAScaledAndRotatedCopyOfTheReference) {
  const Mesh ref = fixtures::uv_sphere(50.0, 24, 48);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.45, Eigen::Vector3d(1, 2, 0.5).normalized()).toRotationMatrix();
  const double s = 1.6;
  const Eigen::MatrixX3d target = similar(ref.V, s, R, Eigen::RowVector3d(10, -20, 5));
  // The reference rigidly placed on the body (same centre, the body's rotation, NOT its size).
  const Eigen::MatrixX3d V_ref = similar(ref.V, 1.0, R, Eigen::RowVector3d(10, -20, 5));
  Eigen::MatrixX3d V = target;
  const int a = 12 * 48 + 7, b = 8 * 48 + 30;  // mid-latitude vertices, far apart
  fold(V, a, b, s * 50.0, Eigen::RowVector3d(10, -20, 5));
  const int before = count_flipped_triangles(V, V_ref, ref.F);
  ASSERT_GE(before, 4);  // at least 2 per fold

  Eigen::MatrixX3d fixed = V;
  const FoldRepairSummary sum = repair_folds(fixed, V_ref, ref.F);
  EXPECT_EQ(sum.flipped_before, before);
  EXPECT_EQ(sum.flipped_after, 0);
  EXPECT_EQ(count_flipped_triangles(fixed, V_ref, ref.F), 0);
  EXPECT_GE(sum.regions_kept, 2);
  // The reference's local shape, rotated and scaled by the border's similarity fit, is the
  // copy's shape exactly: the folded vertices go back to where they were before folding.
  const double err = (fixed - target).rowwise().norm().maxCoeff();
  EXPECT_LT(err, 1e-6) << "max distance to the unfolded copy, mm";

  // Pasting the reference's unscaled Laplacian coordinates (no similarity fit) leaves the
  // region the reference's size: far from the copy.
  Eigen::MatrixX3d pasted = V;
  FoldRepairOptions o;
  o.local_similarity = false;
  repair_folds(pasted, V_ref, ref.F, o);
  EXPECT_GT((pasted - target).rowwise().norm().maxCoeff(), 1000 * std::max(err, 1e-6));
}

TEST(FoldRepair, NeverIncreasesTheFlipCountAndLeavesFoldFreeMeshesAlone) {
  const Mesh ref = fixtures::uv_sphere(50.0, 20, 40);
  // No flips: nothing moves, bit for bit.
  Eigen::MatrixX3d V = 1.3 * ref.V;
  const Eigen::MatrixX3d copy = V;
  FoldRepairSummary s = repair_folds(V, ref.V, ref.F);
  EXPECT_EQ(s.flipped_before, 0);
  EXPECT_EQ(s.vertices_moved, 0);
  EXPECT_TRUE(V == copy);

  // Heavy noise: many flips everywhere; whatever the repair manages, it never adds flips.
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01(0, 1);
  for (double sigma : {2.0, 5.0, 12.0}) {
    Eigen::MatrixX3d noisy = ref.V;
    for (Eigen::Index i = 0; i < noisy.rows(); ++i)
      for (int c = 0; c < 3; ++c) noisy(i, c) += sigma * n01(rng);
    for (bool gate_only : {false, true}) {
      Eigen::MatrixX3d W = noisy;
      FoldRepairOptions o;
      o.local_similarity = !gate_only;
      o.max_region_vertices = gate_only ? 50 : 4000;
      const FoldRepairSummary r = repair_folds(W, ref.V, ref.F, o);
      EXPECT_GT(r.flipped_before, 0) << sigma;
      EXPECT_LE(r.flipped_after, r.flipped_before) << sigma;
      EXPECT_EQ(count_flipped_triangles(W, ref.V, ref.F), r.flipped_after) << sigma;
      EXPECT_TRUE(W.allFinite());
    }
  }
}

// The smoothing fallback alone (every Laplacian region refused by max_region_vertices = 0): a
// vertex slid along the sphere past its neighbours is pulled back toward them until no triangle
// is flipped, only the vertices of flipped triangles move, and by less than the slide; without
// smoothing steps the fold stays.
TEST(FoldRepair, SmoothingStepsUnfoldACreaseTheSolveLeaves) {
  const Mesh ref = fixtures::uv_sphere(50.0, 24, 48);
  Eigen::MatrixX3d V = ref.V;
  const int a = 12 * 48 + 7, b = 6 * 48 + 30;
  fold(V, a, b, 50.0, Eigen::RowVector3d::Zero());
  const int before = count_flipped_triangles(V, ref.V, ref.F);
  ASSERT_GE(before, 4);
  FoldRepairOptions o;
  o.max_region_vertices = 0;
  Eigen::MatrixX3d kept = V;
  EXPECT_EQ(repair_folds(kept, ref.V, ref.F, o).flipped_after, before);
  EXPECT_TRUE(kept == V);
  o.smoothing_steps = 10;
  Eigen::MatrixX3d W = V;
  const FoldRepairSummary s = repair_folds(W, ref.V, ref.F, o);
  EXPECT_EQ(s.flipped_before, before);
  EXPECT_EQ(s.flipped_after, 0);
  EXPECT_EQ(count_flipped_triangles(W, ref.V, ref.F), 0);
  EXPECT_GE(s.smoothing_steps, 1);
  EXPECT_LE(s.smoothing_steps, 10);
  // Only vertices of flipped triangles (the slid ones and their one-ring) move, each by less
  // than the 15 mm slide.
  const Eigen::VectorXd moved = (W - V).rowwise().norm();
  EXPECT_LT(moved.maxCoeff(), 15.0);
  int moved_count = 0;
  for (Eigen::Index i = 0; i < moved.size(); ++i) moved_count += moved(i) > 0;
  EXPECT_EQ(moved_count, s.vertices_moved);
  EXPECT_LE(moved_count, 2 * 7);  // two slid vertices and their one-rings (6 neighbours each)
  // max_displacement bounds the smoothing too: 0.01 mm per step cannot unfold it.
  o.max_displacement = 0.01;
  Eigen::MatrixX3d bounded = V;
  EXPECT_EQ(repair_folds(bounded, ref.V, ref.F, o).flipped_after, before);
}

TEST(FoldRepair, BadInputIsAnInputError) {
  const Mesh ref = fixtures::uv_sphere(1.0, 6, 12);
  Eigen::MatrixX3d V = ref.V.topRows(ref.V.rows() - 1);
  EXPECT_THROW(repair_folds(V, ref.V, ref.F), InputError);
  Eigen::MatrixX3i F = ref.F;
  F(0, 1) = int(ref.V.rows());
  Eigen::MatrixX3d W = ref.V;
  try {
    repair_folds(W, ref.V, F);
    FAIL() << "no error for a face index out of range";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("face index"), std::string::npos) << e.what();
  }
}
