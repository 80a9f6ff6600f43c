#include <gtest/gtest.h>

#include "support/fixtures.h"
#include "tools/render/render.h"

using namespace bodymodel;

TEST(Render, BoxFillsTheFrameAndLeavesTheBackgroundWhite) {
  Mesh b = fixtures::box(1, 2, 1);
  Image img = render_mesh(b.V, b.F, {}, 100, 200);
  auto px = [&](int x, int y, int c) { return int(img.rgb[(size_t(y) * img.width + x) * 3 + c]); };
  EXPECT_EQ(px(1, 1, 0), 255);                 // corner: background (4 % margin)
  EXPECT_LT(px(50, 100, 0), 250);              // centre: the box, shaded
  // The front face spans the frame minus the margin: 4..96 horizontally.
  EXPECT_LT(px(6, 100, 0), 250);
  EXPECT_EQ(px(2, 100, 0), 255);
}

TEST(Render, NearerSurfaceWins) {
  // Two parallel quads: the red one nearer the camera (+z) must cover the blue one.
  Eigen::MatrixX3d V(8, 3);
  V << 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1,  // near (z = 1)
      0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0;   // far (z = 0)
  Eigen::MatrixX3i F(4, 3);
  F << 0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7;
  Eigen::MatrixX3d C(8, 3);
  C.topRows(4).rowwise() = Eigen::RowVector3d(1, 0, 0);
  C.bottomRows(4).rowwise() = Eigen::RowVector3d(0, 0, 1);
  Image img = render_mesh(V, F, C, 64, 64);
  size_t centre = (size_t(32) * 64 + 32) * 3;
  EXPECT_GT(img.rgb[centre], 150);      // red channel
  EXPECT_LT(img.rgb[centre + 2], 30);   // blue channel
}

TEST(Render, HeatColorsRunBlueToRed) {
  Eigen::VectorXd v(3);
  v << -1, 0.5, 9;
  Eigen::MatrixX3d C = heat_colors(v, 0, 1);
  EXPECT_GT(C(0, 2), C(0, 0));  // below range: blue
  EXPECT_GT(C(2, 0), C(2, 2));  // above range: red
  EXPECT_GT(C(1, 1), 0.7);      // middle: green
}
