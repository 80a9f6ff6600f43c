// Self-intersection repair (core/intersection_repair.h): two spheres pressed 3 mm into each other
// are pushed apart until no triangles cross, by little more than the overlap, and only near the
// contact; faces left unflagged are not touched; bad flags are an InputError.
#include <gtest/gtest.h>

#include "core/error.h"
#include "core/intersection_repair.h"
#include "core/plausibility.h"
#include "support/fixtures.h"

using namespace bodymodel;

namespace {

// Two spheres of radius 50 whose centres are 97 apart (3 mm overlap on the x axis), one mesh.
Mesh pressed_spheres() {
  const Mesh s = fixtures::uv_sphere(50.0, 24, 48);
  Mesh m;
  m.V.resize(2 * s.V.rows(), 3);
  m.F.resize(2 * s.F.rows(), 3);
  m.V << s.V, (s.V.rowwise() + Eigen::RowVector3d(97.0, 0.0, 0.0));
  m.F << s.F, (s.F.array() + static_cast<int>(s.V.rows())).matrix();
  return m;
}

}  // namespace

TEST(IntersectionRepair, PushesPressedSpheresApartNearTheContactOnly) {
  Mesh m = pressed_spheres();
  const Eigen::MatrixX3d start = m.V;
  ASSERT_GT(self_intersecting_triangle_pairs(m.V, m.F), 0);
  EXPECT_EQ(self_intersecting_triangle_pair_list(m.V, m.F).size(),
            static_cast<size_t>(self_intersecting_triangle_pairs(m.V, m.F)));
  const IntersectionRepairSummary s = repair_self_intersections(m.V, m.F);
  EXPECT_GT(s.pairs_before, 0);
  EXPECT_EQ(s.pairs_after, 0);
  EXPECT_EQ(self_intersecting_triangle_pairs(m.V, m.F), 0);
  // Each side needs to give way by half the 3 mm overlap; the fading spreads and averages it.
  EXPECT_LE(s.max_displacement, 3.0);
  EXPECT_GT(s.max_displacement, 1.0);
  // The contact is at x = 48.5; vertices more than 40 mm from it stay where they were.
  const Eigen::RowVector3d contact(48.5, 0.0, 0.0);
  for (Eigen::Index v = 0; v < m.V.rows(); ++v)
    if ((start.row(v) - contact).norm() > 40.0) EXPECT_EQ((m.V.row(v) - start.row(v)).norm(), 0.0) << v;
  // The two parts now lie on either side of the contact: no vertex of the first sphere beyond
  // the second's surface along the axis.
  const Eigen::Index n = m.V.rows() / 2;
  EXPECT_LT(m.V.topRows(n).col(0).maxCoeff(), m.V.bottomRows(n).col(0).minCoeff() + 1e-9);
}

TEST(IntersectionRepair, LeavesPairsWithAnUnflaggedFaceAlone) {
  Mesh m = pressed_spheres();
  const Eigen::MatrixX3d start = m.V;
  std::vector<char> flags(m.F.rows(), 0);
  std::fill(flags.begin(), flags.begin() + m.F.rows() / 2, 1);  // the first sphere only
  const IntersectionRepairSummary s = repair_self_intersections(m.V, m.F, flags);
  EXPECT_EQ(s.pairs_before, 0);
  EXPECT_EQ(s.vertices_moved, 0);
  EXPECT_EQ((m.V - start).norm(), 0.0);
}

TEST(IntersectionRepair, StopsAtTheDisplacementBound) {
  Mesh m = pressed_spheres();
  IntersectionRepairOptions o;
  o.max_displacement = 0.5;  // less than the push the contact needs
  const IntersectionRepairSummary s = repair_self_intersections(m.V, m.F, {}, o);
  EXPECT_GT(s.pairs_after, 0);
  EXPECT_LE(s.max_displacement, 0.5);
}

TEST(IntersectionRepair, BadFlagsAreAnInputError) {
  Mesh m = pressed_spheres();
  EXPECT_THROW(repair_self_intersections(m.V, m.F, std::vector<char>(3, 1)), InputError);
}
