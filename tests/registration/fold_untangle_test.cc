// The untangling of local folds (registration/fold_untangle.h) on a tube with known rest shape:
// folds planted by dragging vertices past their neighbours are removed, the displacement stays
// within the drag that made them, the surface away from them is untouched, and a fold the rest
// shape has itself (a sharp feature) is kept.
#include "registration/fold_untangle.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "registration/fixtures.h"
#include "registration/metrics.h"

namespace bodymodel {
namespace {

int count(const std::vector<char>& x) { return int(std::count(x.begin(), x.end(), 1)); }

// The limb tube (radius 50 mm, rings 10 mm apart, 24 segments): vertex of ring i, segment j.
constexpr int kSegments = 24;
int vertex(int ring, int segment) { return ring * kSegments + segment; }

// Drags a vertex `mm` along the tube (+y), past the next ring: its two triangles towards that
// ring turn over (registration/metrics_test.cc).
void drag(Eigen::MatrixX3d& V, int v, double mm) { V(v, 1) += mm; }

// Folds at four places of a tube placed in another frame and size than its rest shape (turned,
// 1.1× larger, moved), as a registration is against the template at rest: all are untangled; no
// vertex moves farther than 4 mm (a dragged vertex is 2 mm, 2.2 at this size, past the ring it
// crossed: the least move that unfolds, plus the margin the solve keeps), the moved vertices
// stay on the tube's surface, and vertices farther than 60 mm (six rings) from every fold do
// not move.
TEST(UntangleLocalFolds, RemovesPlantedFoldsWithinTheirDragAndTouchesNothingElse) {
  const test::Limb limb = test::limb();
  const Eigen::MatrixX3i& F = limb.mesh.F;
  const Eigen::MatrixX3d& rest = limb.mesh.V;
  const std::vector<int> dragged = {vertex(10, 3), vertex(20, 15), vertex(30, 5), vertex(45, 20)};
  Eigen::MatrixX3d V = rest;
  for (int v : dragged) drag(V, v, 12.0);
  // Two neighbours dragged together: a wider fold (four triangles).
  drag(V, vertex(45, 21), 12.0);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::RowVector3d shift(30, -40, 500);
  const double scale = 1.1;
  V = ((scale * V) * R.transpose()).rowwise() + shift;
  const Eigen::MatrixX3d V0 = V;
  const int planted = count(locally_folded_triangles(V, rest, F));
  ASSERT_EQ(planted, 2 * 3 + 4);

  const UntangleSummary s = untangle_local_folds(V, rest, F);
  EXPECT_EQ(s.folded_before, planted);
  EXPECT_EQ(s.folded_after, 0);
  EXPECT_EQ(count(locally_folded_triangles(V, rest, F)), 0);
  const Eigen::VectorXd moved = (V - V0).rowwise().norm();
  EXPECT_NEAR(s.max_displacement, moved.maxCoeff(), 1e-9);
  EXPECT_LE(s.max_displacement, 4.0);
  EXPECT_GT(s.vertices_moved, 0);
  // Back in the tube's own frame: every vertex on the tube's side stays within 3 mm of its
  // radius (55 mm at this size) — unfolded along the surface, not pulled off it.
  const Eigen::MatrixX3d back = ((V.rowwise() - shift) * R) / scale;
  for (Eigen::Index i = 0; i < kSegments * 61; ++i) {
    const double r = std::hypot(back(i, 0), back(i, 2));
    EXPECT_NEAR(scale * r, scale * 50.0, 3.0) << "vertex " << i;
  }
  int untouched = 0;
  for (Eigen::Index i = 0; i < rest.rows(); ++i) {
    double nearest = 1e9;
    for (int v : dragged) nearest = std::min(nearest, (rest.row(i) - rest.row(v)).norm());
    if (nearest > 60.0) {
      ++untouched;
      EXPECT_EQ(moved(i), 0.0) << "vertex " << i << ", " << nearest << " mm from the nearest fold";
    }
  }
  EXPECT_GT(untouched, rest.rows() / 2);
}

// A fold the rest shape has itself (the same dragged vertex in the rest mesh: a sharp feature
// like an ear rim) is not a local fold and is kept, while a planted fold next to it (its region
// takes in the feature's triangles) is untangled: the solve does not turn the feature over.
TEST(UntangleLocalFolds, KeepsAFoldTheRestShapeHas) {
  const test::Limb limb = test::limb();
  const Eigen::MatrixX3i& F = limb.mesh.F;
  Eigen::MatrixX3d rest = limb.mesh.V;
  const int feature = vertex(15, 7);
  drag(rest, feature, 12.0);
  Eigen::MatrixX3d V = rest;
  EXPECT_EQ(count(locally_folded_triangles(V, rest, F)), 0);
  drag(V, vertex(17, 9), 12.0);
  const UntangleSummary s = untangle_local_folds(V, rest, F);
  EXPECT_EQ(s.folded_before, 2);
  EXPECT_EQ(s.folded_after, 0);
  // The feature's triangles still face against their ring, as at rest.
  const Eigen::MatrixX3d S = ring_normals(V, F);
  int against = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::RowVector3d n = (V.row(F(f, 1)) - V.row(F(f, 0))).cross(V.row(F(f, 2)) - V.row(F(f, 0)));
    if (n.dot(S.row(f)) < 0) {
      ++against;
      EXPECT_TRUE(F(f, 0) == feature || F(f, 1) == feature || F(f, 2) == feature) << "triangle " << f;
    }
  }
  EXPECT_EQ(against, 2);
}

// Against two rest shapes a feature is kept only where both have it: folded in one rest shape
// and not in the other (a shaped body's blend), it is untangled like any fold.
TEST(UntangleLocalFolds, KeepsOnlyFeaturesEveryRestShapeHas) {
  const test::Limb limb = test::limb();
  const Eigen::MatrixX3i& F = limb.mesh.F;
  Eigen::MatrixX3d folded_rest = limb.mesh.V;
  const int feature = vertex(15, 7);
  drag(folded_rest, feature, 12.0);
  for (const bool both : {true, false}) {
    Eigen::MatrixX3d V = folded_rest;
    const Eigen::MatrixX3d other = both ? folded_rest : limb.mesh.V;
    const UntangleSummary s = untangle_local_folds(V, std::vector<Eigen::MatrixX3d>{folded_rest, other}, F);
    EXPECT_EQ(s.folded_before, 0);  // counted against the first rest shape
    EXPECT_EQ(count(locally_folded_triangles(V, other, F)), 0) << (both ? "both" : "one");
    if (both) EXPECT_EQ((V - folded_rest).norm(), 0.0);
    else EXPECT_GT(s.max_displacement, 1.0);
  }
  Eigen::MatrixX3d V = folded_rest;
  EXPECT_THROW(untangle_local_folds(V, std::vector<Eigen::MatrixX3d>{}, F), InputError);
}

// The displacement bound is a bound: a fold that needs a 2 mm move is left as it is when no
// vertex may move 1 mm, and untangled when 3 mm are allowed.
TEST(UntangleLocalFolds, RefusesASolveThatMovesAVertexFartherThanTheBound) {
  const test::Limb limb = test::limb();
  const Eigen::MatrixX3i& F = limb.mesh.F;
  Eigen::MatrixX3d V = limb.mesh.V;
  drag(V, vertex(30, 5), 12.0);
  const Eigen::MatrixX3d V0 = V;
  UntangleOptions o;
  o.rounds = 3;  // every round is refused: three suffice to show it
  o.max_displacement = 1.0;
  const UntangleSummary refused = untangle_local_folds(V, limb.mesh.V, F, o);
  EXPECT_EQ(refused.folded_before, 2);
  EXPECT_EQ(refused.folded_after, 2);
  EXPECT_EQ(refused.vertices_moved, 0);
  EXPECT_EQ((V - V0).norm(), 0.0);
  o.max_displacement = 3.0;
  const UntangleSummary kept = untangle_local_folds(V, limb.mesh.V, F, o);
  EXPECT_EQ(kept.folded_after, 0);
  EXPECT_LE(kept.max_displacement, 3.0);
  EXPECT_GT(kept.max_displacement, 1.0);
}

TEST(UntangleLocalFolds, RefusesMeshesOfAnotherSize) {
  const test::Limb limb = test::limb();
  Eigen::MatrixX3d V = limb.mesh.V.topRows(10);
  EXPECT_THROW(untangle_local_folds(V, limb.mesh.V, limb.mesh.F), InputError);
}

}  // namespace
}  // namespace bodymodel
