// FAUST's correspondence protocol (registration/correspondence.h) against a case computed by
// hand: three "registrations" of two far-apart triangles and three truth vertices each.
#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"
#include "registration/correspondence.h"

namespace bodymodel {
namespace {

Eigen::MatrixX3d rows(std::initializer_list<std::array<double, 3>> r) {
  Eigen::MatrixX3d M(Eigen::Index(r.size()), 3);
  Eigen::Index i = 0;
  for (const auto& x : r) M.row(i++) << x[0], x[1], x[2];
  return M;
}

struct HandCase {
  Eigen::MatrixX3i F = (Eigen::MatrixX3i(2, 3) << 0, 1, 2, 3, 4, 5).finished();
  // A: a unit right triangle at z = 0 and its copy at z = 100.
  CorrespondenceMesh A{"A", "s1",
                       rows({{0.25, 0.25, 0.5}, {2, -1, 0}, {0, 0, 99}}),
                       rows({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 100}, {1, 0, 100}, {0, 1, 100}})};
  // B (same subject): the first triangle doubled and lifted by 1, the second moved by 10 in x.
  // Truths chosen 3, 4 and 12 mm from where A's truths land on B.
  CorrespondenceMesh B{"B", "s1",
                       rows({{0.5, 0.5, 4}, {2, 0, 5}, {10, 0, 112}}),
                       rows({{0, 0, 1}, {2, 0, 1}, {0, 2, 1}, {10, 0, 100}, {11, 0, 100}, {10, 1, 100}})};
  // C (another subject): A's registration, truths moved by 1 in x.
  CorrespondenceMesh C{"C", "s2",
                       rows({{1.25, 0.25, 0.5}, {3, -1, 0}, {1, 0, 99}}), A.registered};
};

TEST(Correspondence, LocatesTruthVerticesByClosestPointAndBarycentrics) {
  HandCase h;
  const auto loc = locate_on_surface(h.A.truth, h.A.registered, h.F);
  ASSERT_EQ(loc.size(), 3u);
  // (0.25, 0.25, 0.5) projects inside triangle 0 at (0.25, 0.25, 0): weights (0.5, 0.25, 0.25).
  EXPECT_EQ(loc[0].face, 0);
  EXPECT_NEAR((loc[0].bary - Eigen::Vector3d(0.5, 0.25, 0.25)).norm(), 0, 1e-12);
  EXPECT_NEAR(loc[0].distance, 0.5, 1e-12);
  // (2, −1, 0) is outside, beyond corner 1 = (1, 0, 0).
  EXPECT_EQ(loc[1].face, 0);
  EXPECT_NEAR((loc[1].bary - Eigen::Vector3d(0, 1, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR(loc[1].distance, std::sqrt(2.0), 1e-12);
  // (0, 0, 99) is 1 from triangle 1's corner 0, 99 from triangle 0.
  EXPECT_EQ(loc[2].face, 1);
  EXPECT_NEAR((loc[2].bary - Eigen::Vector3d(1, 0, 0)).norm(), 0, 1e-12);
  const Eigen::MatrixX3d carried = carry_locations(loc, h.B.registered, h.F);
  EXPECT_NEAR((carried.row(0) - Eigen::RowVector3d(0.5, 0.5, 1)).norm(), 0, 1e-12);
  EXPECT_NEAR((carried.row(1) - Eigen::RowVector3d(2, 0, 1)).norm(), 0, 1e-12);
  EXPECT_NEAR((carried.row(2) - Eigen::RowVector3d(10, 0, 100)).norm(), 0, 1e-12);
}

TEST(Correspondence, PairErrorsAndPoolsMatchTheHandComputedCase) {
  HandCase h;
  const CorrespondenceReport all = evaluate_correspondence({h.A, h.B, h.C}, h.F);
  ASSERT_EQ(all.pairs.size(), 6u);  // ordered pairs, a ≠ b
  EXPECT_EQ(all.intra.pairs, 2);
  EXPECT_EQ(all.inter.pairs, 4);
  auto pair = [&](int a, int b) -> const PairError& {
    for (const auto& p : all.pairs)
      if (p.a == a && p.b == b) return p;
    throw std::runtime_error("pair missing");
  };
  // A → B: errors 3, 4, 12.
  const ErrorStats ab = pair(0, 1).stats;
  EXPECT_FALSE(pair(0, 1).inter);
  EXPECT_NEAR(ab.mean, 19.0 / 3, 1e-12);
  EXPECT_NEAR(ab.median, 4, 1e-12);
  EXPECT_NEAR(ab.p95, 4 + 0.9 * 8, 1e-12);  // numpy: position 0.95 · 2 = 1.9
  EXPECT_NEAR(ab.max, 12, 1e-12);
  // B → A: B's truths land at (0.5,0.5,1)→(0.25,0.25,0), (2,0,1)→(1,0,0), (10,0,100)→(0,0,100);
  // errors 0.5, √2, 1.
  const ErrorStats ba = pair(1, 0).stats;
  EXPECT_NEAR(ba.mean, (0.5 + std::sqrt(2.0) + 1) / 3, 1e-12);
  EXPECT_NEAR(ba.median, 1, 1e-12);
  EXPECT_NEAR(ba.p95, 1 + 0.9 * (std::sqrt(2.0) - 1), 1e-12);
  EXPECT_NEAR(ba.max, std::sqrt(2.0), 1e-12);
  // A → C (inter): A's truths land on A's own closest points; C's truths are A's moved by 1 in x:
  // errors √1.25, √5, √2.
  EXPECT_TRUE(pair(0, 2).inter);
  EXPECT_NEAR(pair(0, 2).stats.mean, (std::sqrt(1.25) + std::sqrt(5.0) + std::sqrt(2.0)) / 3, 1e-12);
  EXPECT_NEAR(pair(0, 2).stats.max, std::sqrt(5.0), 1e-12);
  // The intra pool: {3, 4, 12, 0.5, √2, 1}; median and p95 from 0.01-mm bins (±0.005 mm).
  const double intra_mean = (3 + 4 + 12 + 0.5 + std::sqrt(2.0) + 1) / 6;
  EXPECT_NEAR(all.intra.mean, intra_mean, 1e-12);
  EXPECT_NEAR(all.intra.median, (std::sqrt(2.0) + 3) / 2, 0.01);
  EXPECT_NEAR(all.intra.p95, 4 + 0.75 * 8, 0.01);  // position 0.95 · 5 = 4.75
  EXPECT_DOUBLE_EQ(all.intra.max, 12);
  EXPECT_EQ(all.intra.count, 6);
  // Selecting pairs: only the two intra pairs, same pooled values.
  CorrespondenceOptions o;
  o.pairs = PairSelection::intra;
  const CorrespondenceReport intra = evaluate_correspondence({h.A, h.B, h.C}, h.F, o);
  EXPECT_EQ(intra.pairs.size(), 2u);
  EXPECT_EQ(intra.inter.pairs, 0);
  EXPECT_NEAR(intra.intra.mean, intra_mean, 1e-12);
  // Per truth vertex and mesh, the mean over the pairs that include the mesh: A and B are in both
  // intra pairs (A → B errors 3, 4, 12; B → A 0.5, √2, 1), C in none.
  ASSERT_EQ(intra.vertex_error_mean.rows(), 3);
  ASSERT_EQ(intra.vertex_error_mean.cols(), 3);
  for (int m : {0, 1}) {
    EXPECT_NEAR(intra.vertex_error_mean(0, m), (3 + 0.5) / 2, 1e-12);
    EXPECT_NEAR(intra.vertex_error_mean(1, m), (4 + std::sqrt(2.0)) / 2, 1e-12);
    EXPECT_NEAR(intra.vertex_error_mean(2, m), (12 + 1) / 2.0, 1e-12);
  }
  EXPECT_EQ(intra.vertex_error_mean.col(2).norm(), 0.0);
  // Truth vertices' mean distance to their own registration: A 0.5, √2, 1.
  EXPECT_NEAR(all.location_distance_mean[0], (0.5 + std::sqrt(2.0) + 1) / 3, 1e-12);
}

// Where two limbs touch: a palm 2 mm above a hip, facing it. A truth point of the hip 1.5 mm above
// the registration's hip (0.5 mm below its palm) is closest to the palm; located by orientation it
// lands on the hip, which faces its way.
TEST(Correspondence, OrientedLocationKeepsAPointOnTheSurfaceFacingItsWay) {
  const Eigen::MatrixX3d V = rows({{-10, -10, 0}, {10, -10, 0}, {0, 10, 0}, {-10, -10, 2}, {0, 10, 2}, {10, -10, 2}});
  const Eigen::MatrixX3i F = (Eigen::MatrixX3i(2, 3) << 0, 1, 2, 3, 4, 5).finished();  // hip +z, palm −z
  const Eigen::MatrixX3d P = rows({{0, 0, 1.5}, {0, 0, 1.8}});
  const Eigen::MatrixX3d N = rows({{0, 0, 1}, {0, 0, -1}});  // a hip point, a palm point
  const auto closest = locate_on_surface(P, V, F);
  EXPECT_EQ(closest[0].face, 1);  // the palm: the wrong limb
  const auto oriented = locate_on_surface_oriented(P, N, V, F);
  EXPECT_EQ(oriented[0].face, 0);
  EXPECT_NEAR(oriented[0].distance, 1.5, 1e-12);
  EXPECT_NEAR((carry_locations(oriented, V, F).row(0) - Eigen::RowVector3d(0, 0, 0)).norm(), 0.0, 1e-12);
  EXPECT_EQ(oriented[1].face, 1);  // already facing its way: unchanged
  EXPECT_NEAR(oriented[1].distance, 0.2, 1e-12);
  EXPECT_THROW(locate_on_surface_oriented(P, N.topRows(1), V, F), InputError);
}

TEST(Correspondence, RejectsMismatchedTopologiesAndNaN) {
  HandCase h;
  CorrespondenceMesh bad = h.B;
  bad.truth.conservativeResize(2, 3);
  EXPECT_THROW(evaluate_correspondence({h.A, bad}, h.F), InputError);
  bad = h.B;
  bad.registered(0, 0) = std::nan("");
  EXPECT_THROW(evaluate_correspondence({h.A, bad}, h.F), InputError);
  EXPECT_THROW(evaluate_correspondence({h.A}, h.F), InputError);
}

}  // namespace
}  // namespace bodymodel
