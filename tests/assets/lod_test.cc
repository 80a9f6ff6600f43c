// Levels of detail on small hand-made meshes (assets/lod.h): edge collapse keeps a sphere's shape
// within the distance bound near the triangle target, weights carried to the new vertices follow
// the field they came from and sum to one, and a level fits its budget with the body first.
#include <gtest/gtest.h>

#include <cmath>

#include "assets/lod.h"
#include "core/error.h"
#include "support/fixtures.h"

namespace bodymodel {
namespace {

// Two bones whose weights vary linearly with height on a sphere of radius r: w0 = (y + r) / 2r.
SkinWeights height_weights(const Eigen::MatrixX3d& V, double r) {
  std::vector<Eigen::Triplet<double>> t;
  for (Eigen::Index v = 0; v < V.rows(); ++v) {
    const double w = (V(v, 1) + r) / (2 * r);
    if (w > 0) t.emplace_back(v, 0, w);
    if (w < 1) t.emplace_back(v, 1, 1 - w);
  }
  SkinWeights W(V.rows(), 2);
  W.setFromTriplets(t.begin(), t.end());
  return W;
}

TEST(Lod, SimplifiedSphereNearItsTargetAndWithinTheBound) {
  const Mesh s = fixtures::uv_sphere(100, 30, 60);   // 3480 triangles, radius 100 mm
  for (const double bound : {0.0, 2.0}) {
    const SimplifiedMesh m = simplify_mesh(s.V, s.F, 400, bound);
    EXPECT_LE(m.F.rows(), 420) << bound;
    EXPECT_GE(m.F.rows(), 320) << bound;
    ASSERT_EQ(m.F.maxCoeff(), m.V.rows() - 1);   // every vertex used, faces renumbered
    double worst = 0;
    for (Eigen::Index v = 0; v < m.V.rows(); ++v) worst = std::max(worst, std::abs(m.V.row(v).norm() - 100));
    // A point within `bound` of the input facets is within bound + their sagitta (< 0.1 mm) of the sphere.
    EXPECT_LT(worst, bound > 0 ? bound + 0.1 : 5.0) << bound;
  }
  // Fewer triangles than the target: kept as they are.
  EXPECT_EQ(simplify_mesh(s.V, s.F, 10000).F.rows(), s.F.rows());
  EXPECT_THROW(simplify_mesh(s.V, s.F, 0), InputError);
  EXPECT_THROW(simplify_mesh(Eigen::MatrixX3d(), Eigen::MatrixX3i(), 10), InputError);
}

TEST(Lod, WeightsCarriedToSimplifiedVerticesFollowTheirField) {
  const Mesh s = fixtures::uv_sphere(100, 20, 40);
  DressedPart p;
  p.name = p.kind = "body";
  p.V = s.V;
  p.F = s.F;
  p.weights = height_weights(s.V, 100);
  const DressedPart q = simplified_part(p, 200, 3);
  ASSERT_EQ(q.weights.rows(), q.V.rows());
  double worst = 0;
  for (Eigen::Index v = 0; v < q.V.rows(); ++v) {
    EXPECT_NEAR(q.weights.coeff(v, 0) + q.weights.coeff(v, 1), 1.0, 1e-12);
    worst = std::max(worst, std::abs(q.weights.coeff(v, 0) - (q.V(v, 1) + 100) / 200));
  }
  EXPECT_LT(worst, 0.02);   // the field at the closest surface point: off by the vertex's distance to it
}

TEST(Lod, LevelFitsItsBudgetBodyFirstAndDropsKinds) {
  std::vector<DressedPart> parts(3);
  const Mesh body = fixtures::uv_sphere(100, 20, 40), coat = fixtures::uv_sphere(110, 20, 40),
             lash = fixtures::uv_sphere(5, 6, 8);
  parts[0].name = parts[0].kind = "body";
  parts[1].name = "coat", parts[1].kind = "clothes", parts[1].garment = true;
  parts[2].name = "lash", parts[2].kind = "eyelashes";
  const Mesh* meshes[] = {&body, &coat, &lash};
  for (int k = 0; k < 3; ++k) {
    parts[k].V = meshes[k]->V;
    parts[k].F = meshes[k]->F;
    parts[k].weights = height_weights(meshes[k]->V, meshes[k]->V.col(1).maxCoeff());
  }
  const DressedSkinBody none;   // no proxy: nothing of it is read
  LodSpec spec;
  spec.max_triangles = 600;
  spec.drop_kinds = {"eyelashes"};
  spec.max_error_mm = 4;
  const std::vector<DressedPart> level = level_of_detail(parts, none, spec);
  ASSERT_EQ(level.size(), 2u);
  EXPECT_EQ(level[0].name, "body");
  EXPECT_EQ(level[1].name, "coat");
  EXPECT_TRUE(level[1].garment);
  EXPECT_LE(triangle_count(level), 600);
  EXPECT_GT(triangle_count(level), 450);   // the budget is used, not wasted
  // Shares by area: the coat (radius 110) gets more than the body (100).
  EXPECT_GT(level[1].F.rows(), level[0].F.rows() * 0.95);
  spec.max_triangles = 30;   // fewer than 24 a part
  EXPECT_THROW(level_of_detail(parts, none, spec), InputError);
  std::vector<DressedPart> headless(parts.begin() + 1, parts.end());
  EXPECT_THROW(level_of_detail(headless, none, LodSpec{}), InputError);
}

}  // namespace
}  // namespace bodymodel
