#include <gtest/gtest.h>

#include "core/error.h"
#include "core/measure.h"
#include "support/fixtures.h"

using namespace bodymodel;

TEST(Measure, BoxHeightVolumeGirth) {
  // 300 × 1700 × 200 mm box standing on y: girth at any height = 2(300 + 200).
  Mesh b = fixtures::box(300, 1700, 200);
  BodyMeasurements m = measure_body(b.V, b.F);
  EXPECT_NEAR(m.height_cm, 170.0, 1e-9);
  EXPECT_NEAR(m.volume_l, 3.0 * 17 * 2, 1e-9);  // dm³ = L
  EXPECT_NEAR(m.weight_kg, m.volume_l * 1.01, 1e-9);
  EXPECT_NEAR(m.waist_cm, 100.0, 1e-6);
  EXPECT_NEAR(girth_at_height(b.V, b.F, 500), 1000.0, 1e-6);
  EXPECT_EQ(girth_at_height(b.V, b.F, 5000), 0.0);
}

TEST(Measure, CylinderGirthIsPolygonPerimeter) {
  const int n = 64;
  const double r = 150;
  Mesh c = fixtures::cylinder(r, 1000, n, 10);
  double exact_polygon = 2 * n * r * std::sin(M_PI / n);
  EXPECT_NEAR(girth_at_height(c.V, c.F, 333), exact_polygon, 1e-6);
  BodyMeasurements m = measure_body(c.V, c.F);
  double polygon_area = 0.5 * n * r * r * std::sin(2 * M_PI / n);
  EXPECT_NEAR(m.volume_l, polygon_area * 1000 * 1e-6, 1e-9);
  EXPECT_NEAR(m.height_cm, 100, 1e-9);
}

TEST(Measure, SphereVolumeAndSectionGirth) {
  const double r = 100;
  Mesh s = fixtures::uv_sphere(r, 90, 180);
  BodyMeasurements m = measure_body(s.V, s.F);
  EXPECT_NEAR(m.volume_l, 4.0 / 3 * M_PI * r * r * r * 1e-6, 0.005 * m.volume_l);
  EXPECT_NEAR(m.height_cm, 20, 1e-9);
  // Section at height 40 above the centre: circle of radius sqrt(r² − 40²).
  EXPECT_NEAR(girth_at_height(s.V, s.F, 40), 2 * M_PI * std::sqrt(r * r - 1600), 0.005 * 2 * M_PI * r);
}

TEST(Measure, InwardFacingMeshIsRejected) {
  Mesh b = fixtures::box(1, 1, 1);
  b.F.col(1).swap(b.F.col(2));
  EXPECT_THROW(measure_body(b.V, b.F), InputError);
}

TEST(Measure, NavyFormulaMatchesPublishedExample) {
  // Hodgdon & Beckett: a man 70 in tall, neck 15 in, waist 34 in → about 17.5 % (hand-computed).
  double bf = navy_body_fat_pct(Sex::male, 70 * 2.54, 15 * 2.54, 34 * 2.54, 0);
  EXPECT_NEAR(bf, 86.010 * std::log10(19.0) - 70.041 * std::log10(70.0) + 36.76, 1e-9);
  EXPECT_NEAR(bf, 17.5, 0.3);
  EXPECT_TRUE(std::isnan(navy_body_fat_pct(Sex::unknown, 170, 35, 80, 90)));
}
