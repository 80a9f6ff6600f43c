// Fitting assets by their binding on small hand-made bodies: the formula, its invariance to a
// per-axis scaling of the body, weights carried through the binding, hidden faces, and the
// penetration measure and fix on a sphere.
#include <gtest/gtest.h>

#include <cmath>

#include "assets/binding.h"
#include "assets/fit.h"
#include "assets/penetration.h"
#include "core/error.h"

namespace bodymodel {
namespace {

Eigen::MatrixX3d small_body() {
  Eigen::MatrixX3d B(6, 3);
  B << 0, 0, 0,  //
      10, 0, 0,  //
      0, 20, 0,  //
      0, 0, 30,  //
      5, 5, 5,   //
      -4, 7, 2;
  return B;
}

AssetBinding small_binding() {
  return parse_asset_binding(R"(name t
x_scale 0 1 0.5
y_scale 0 2 1.0
z_scale 0 3 2.0
verts 0
0 1 2 0.2 0.3 0.5 0.1 0.2 0.3
4
3 4 5 0.5 0.5 0.0 -0.1 0 0
delete_verts
4 - 5
)",
                             "t.mhclo", 6);
}

TEST(AssetFit, FormulaWithScaleLines) {
  const Eigen::MatrixX3d B = small_body();
  const AssetBinding b = small_binding();
  // Scales: |10 − 0| / 0.5 = 20, |20 − 0| / 1 = 20, |30 − 0| / 2 = 15.
  EXPECT_TRUE(asset_offset_scale(b, B).isApprox(Eigen::Vector3d(20, 20, 15)));
  const Eigen::MatrixX3d X = fit_asset(b, B);
  const Eigen::RowVector3d x0 = 0.2 * B.row(0) + 0.3 * B.row(1) + 0.5 * B.row(2) + Eigen::RowVector3d(2, 4, 4.5);
  EXPECT_LT((X.row(0) - x0).norm(), 1e-12);
  EXPECT_LT((X.row(1) - B.row(4)).norm(), 1e-12);  // exact row
  EXPECT_LT((X.row(2) - (0.5 * B.row(3) + 0.5 * B.row(4) + Eigen::RowVector3d(-2, 0, 0))).norm(), 1e-12);
}

TEST(AssetFit, FollowsAPerAxisScalingAndTranslationOfTheBody) {
  // The binding is built so that an asset on a body stretched per axis (and moved) is the
  // asset stretched and moved the same way: the offsets scale with the body.
  const AssetBinding b = small_binding();
  const Eigen::MatrixX3d B = small_body();
  const Eigen::Vector3d s(1.3, 0.7, 2.1), t(5, -3, 11);
  Eigen::MatrixX3d B2 = (B * s.asDiagonal()).rowwise() + t.transpose();
  const Eigen::MatrixX3d X = fit_asset(b, B), X2 = fit_asset(b, B2);
  const Eigen::MatrixX3d expected = (X * s.asDiagonal()).rowwise() + t.transpose();
  EXPECT_LT((X2 - expected).cwiseAbs().maxCoeff(), 1e-10);
}

TEST(AssetFit, BodyTooSmallForTheBinding) {
  const AssetBinding b = small_binding();
  EXPECT_THROW(fit_asset(b, small_body().topRows(5)), InputError);
  SkinWeights W(5, 2);
  EXPECT_THROW(asset_skin_weights(b, W), InputError);
}

TEST(AssetFit, SkinWeightsAreTheBindingsMixNormalised) {
  const AssetBinding b = small_binding();
  SkinWeights W(6, 3);
  std::vector<Eigen::Triplet<double>> t = {{0, 0, 1.0}, {1, 1, 1.0}, {2, 1, 0.5}, {2, 2, 0.5},
                                           {3, 0, 1.0}, {4, 2, 1.0}, {5, 1, 1.0}};
  W.setFromTriplets(t.begin(), t.end());
  const SkinWeights A = asset_skin_weights(b, W);
  ASSERT_EQ(A.rows(), 3);
  // Row 0: 0.2·[1 0 0] + 0.3·[0 1 0] + 0.5·[0 .5 .5] = [.2 .55 .25].
  EXPECT_NEAR(A.coeff(0, 0), 0.2, 1e-12);
  EXPECT_NEAR(A.coeff(0, 1), 0.55, 1e-12);
  EXPECT_NEAR(A.coeff(0, 2), 0.25, 1e-12);
  // Exact row: vertex 4's weights; the padding indices (0, 1) carry nothing.
  EXPECT_NEAR(A.coeff(1, 2), 1.0, 1e-12);
  EXPECT_EQ(A.coeff(1, 0), 0.0);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(Eigen::RowVectorXd(A.row(i)).sum(), 1.0, 1e-12);
  // Dense attributes are carried without renormalising.
  Eigen::MatrixXd colour = Eigen::MatrixXd::Zero(6, 1);
  colour(4, 0) = 2.0;
  EXPECT_NEAR(carry_through_binding(b, colour)(2, 0), 1.0, 1e-12);
}

TEST(AssetFit, NegativeBarycentricWeightsAreDropped) {
  const AssetBinding b = parse_asset_binding("verts 0\n0 1 2 1.2 -0.1 -0.1\n", "neg.mhclo", 3);
  SkinWeights W(3, 2);
  std::vector<Eigen::Triplet<double>> t = {{0, 0, 1.0}, {1, 1, 1.0}, {2, 1, 1.0}};
  W.setFromTriplets(t.begin(), t.end());
  const SkinWeights A = asset_skin_weights(b, W);
  EXPECT_NEAR(A.coeff(0, 0), 1.0, 1e-12);
  EXPECT_EQ(A.coeff(0, 1), 0.0);
}

TEST(AssetFit, AMixThatCancelsToZeroIsCountedOnce) {
  // Bone 0 gets +0.5 and −0.5 from the first two vertices (back to exactly 0), then 0.7 from
  // the third: it must appear once, in the ratio 0.7 : 0.3 with bone 1.
  const AssetBinding b = parse_asset_binding("verts 0\n0 1 2 0.5 -0.5 1.0\n", "cancel.mhclo", 3);
  SkinWeights W(3, 2);
  std::vector<Eigen::Triplet<double>> t = {{0, 0, 1.0}, {1, 0, 1.0}, {2, 0, 0.7}, {2, 1, 0.3}};
  W.setFromTriplets(t.begin(), t.end());
  const SkinWeights A = asset_skin_weights(b, W);
  EXPECT_NEAR(A.coeff(0, 0), 0.7, 1e-12);
  EXPECT_NEAR(A.coeff(0, 1), 0.3, 1e-12);
}

TEST(AssetFit, HiddenVerticesHideEveryFaceTheyTouch) {
  const AssetBinding b = small_binding();
  const auto hidden = hidden_body_vertices({&b}, 6);
  EXPECT_EQ(hidden, (std::vector<char>{0, 0, 0, 0, 1, 1}));
  Eigen::MatrixX3i F(3, 3);
  F << 0, 1, 2, 1, 2, 4, 3, 5, 0;
  const Eigen::MatrixX3i vis = visible_faces(F, hidden);
  ASSERT_EQ(vis.rows(), 1);
  EXPECT_EQ(vis.row(0), Eigen::RowVector3i(0, 1, 2));
}

// An icosphere-like UV sphere of radius r (outward faces).
Mesh sphere(double r, int rings, int segs) {
  Mesh m;
  m.V.resize(2 + (rings - 1) * segs, 3);
  m.V.row(0) << 0, 0, r;
  m.V.row(1) << 0, 0, -r;
  for (int i = 1; i < rings; ++i)
    for (int j = 0; j < segs; ++j) {
      const double th = M_PI * i / rings, ph = 2 * M_PI * j / segs;
      m.V.row(2 + (i - 1) * segs + j) << r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph),
          r * std::cos(th);
    }
  std::vector<Eigen::Vector3i> f;
  auto idx = [&](int i, int j) { return 2 + (i - 1) * segs + (j % segs); };
  for (int j = 0; j < segs; ++j) {
    f.emplace_back(0, idx(1, j), idx(1, j + 1));
    f.emplace_back(1, idx(rings - 1, j + 1), idx(rings - 1, j));
    for (int i = 1; i + 1 < rings; ++i) {
      f.emplace_back(idx(i, j), idx(i + 1, j), idx(i + 1, j + 1));
      f.emplace_back(idx(i, j), idx(i + 1, j + 1), idx(i, j + 1));
    }
  }
  m.F.resize(f.size(), 3);
  for (size_t k = 0; k < f.size(); ++k) m.F.row(k) = f[k].transpose();
  return m;
}

TEST(AssetPenetration, SignedDistanceOnASphere) {
  const Mesh body = sphere(100, 60, 120);
  Eigen::MatrixX3d P(3, 3);
  P << 0, 0, 110,  // 10 outside
      0, 95, 0,    // 5 inside
      -80, 0, 0;   // 20 inside
  const BodyDistance d = body_distance(P, body.V, body.F);
  EXPECT_NEAR(d.signed_distance[0], 10, 0.2);
  EXPECT_NEAR(d.signed_distance[1], -5, 0.2);
  EXPECT_NEAR(d.signed_distance[2], -20, 0.2);
  EXPECT_NEAR(d.normal(1, 1), 1.0, 1e-3);
  const Penetration p = penetration_of(d, 2.0);
  EXPECT_EQ(p.penetrating, 2);
  EXPECT_NEAR(p.max_depth, 20, 0.2);
  // Skin hidden under the third point: it no longer counts.
  std::vector<char> hidden(body.V.rows(), 0);
  for (Eigen::Index v = 0; v < body.V.rows(); ++v) hidden[v] = body.V(v, 0) < -50;
  const BodyDistance h = body_distance(P, body.V, body.F, hidden);
  EXPECT_EQ(h.visible, (std::vector<char>{1, 1, 0}));
  EXPECT_EQ(penetration_of(h, 2.0).penetrating, 1);
}

TEST(AssetPenetration, PushOutClearsADentedShell) {
  // A "garment": a sphere of radius 104 around a body of radius 100, dented 10 mm into the body
  // over a cap; pushing it out must leave no vertex more than 2 mm inside and move only the cap.
  const Mesh body = sphere(100, 40, 80);
  Mesh cloth = sphere(104, 30, 60);
  for (Eigen::Index i = 0; i < cloth.V.rows(); ++i)
    if (cloth.V(i, 0) > 80) cloth.V.row(i) *= 90.0 / 104.0;
  const PushOutResult r = push_garment_out(cloth.V, cloth.F, body.V, body.F, {});
  EXPECT_GT(r.before.fraction, 0.03);
  EXPECT_EQ(r.after.penetrating, 0);
  const Eigen::VectorXd sd = body_distance(r.V, body.V, body.F).signed_distance;
  EXPECT_GT(sd.minCoeff(), 0.0);
  for (Eigen::Index i = 0; i < cloth.V.rows(); ++i) {
    if (cloth.V(i, 0) < 0) EXPECT_EQ((r.V.row(i) - cloth.V.row(i)).norm(), 0.0);
  }
  EXPECT_LT(r.max_move, 15.0);
}

// A coarse garment: one triangle whose corners sit 3 mm outside a sphere of radius 100 but 43°
// apart, so its middle lies some 7 mm inside. The vertices alone are all out (nothing moves);
// with the faces sampled the triangle is pushed out until its centroid clears the body, each
// corner along its own normal (radial here, 25° from the centroid's), so that neighbouring frames'
// pushes point the same way and their blend stays out.
TEST(AssetPenetration, PushOutClearsATriangleWhoseCornersAreOutside) {
  const Mesh body = sphere(100, 60, 120);
  Eigen::MatrixX3d G(3, 3);
  for (int k = 0; k < 3; ++k) {
    const double a = 2 * M_PI * k / 3, tilt = 25.0 * M_PI / 180;   // corners about 43° apart
    G.row(k) = 103 * Eigen::RowVector3d(std::sin(tilt) * std::cos(a), std::sin(tilt) * std::sin(a), std::cos(tilt));
  }
  Eigen::MatrixX3i GF(1, 3);
  GF << 0, 1, 2;
  const Eigen::MatrixX3d centroid = G.colwise().mean();
  ASSERT_LT(body_distance(centroid, body.V, body.F).signed_distance[0], -5.0);
  PushOutOptions o;
  o.faces = false;
  const PushOutResult vertices_only = push_garment_out(G, GF, body.V, body.F, {}, o);
  EXPECT_EQ(vertices_only.moved, 0);
  o.faces = true;
  const PushOutResult r = push_garment_out(G, GF, body.V, body.F, {}, o);
  EXPECT_EQ(r.moved, 3);
  for (int k = 0; k < 3; ++k) {
    const Eigen::RowVector3d move = r.V.row(k) - G.row(k);
    EXPECT_GT(move.normalized().dot(G.row(k).normalized()), std::cos(1.0 * M_PI / 180)) << "corner " << k;
  }
  EXPECT_GT(body_distance(r.V.colwise().mean(), body.V, body.F).signed_distance[0], 0.0);
  EXPECT_EQ(r.after.penetrating, 0);
}

}  // namespace
}  // namespace bodymodel
