// The survey measurements (NHANES definitions, core/measure.h) on a MakeHuman body whose girths
// and lengths are made known: torso rings moved onto circles, the upper-arm ring onto an even
// polygon, the landmarks of the two lengths placed at given distances.
#include <random>
#include <gtest/gtest.h>

#include <cmath>

#include "core/geometry.h"
#include "core/landmarks.h"
#include "core/makehuman.h"
#include "core/measure.h"
#include "core/plausibility.h"

using namespace bodymodel;

namespace {

const MakeHuman& makehuman() {
  static const MakeHuman mh = MakeHuman::load();
  return mh;
}

Eigen::Vector3d point(const Eigen::MatrixX3d& V, const std::vector<int>& ids) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int v : ids) p += V.row(v).transpose();
  return p / static_cast<double>(ids.size());
}

// The default female body with known survey measurements:
//   torso between 15 mm above the crotch and 60 mm above the iliac crest on circles round the
//   vertical axis (x = 0, z = z_c) of radius r(y): 160 mm at and above the crest's band, a bump
//   peaking at 175 mm at `hip_y` below it;
//   upper-arm ring: a regular 20-gon of radius 50 mm square to acromion → olecranon;
//   olecranon 300 mm from the acromion, patella top 400 mm below the inguinal landmark.
struct KnownBody {
  Eigen::MatrixX3d V;
  double crest = 0, hip_y = 0;
  static constexpr double waist_radius = 160, hip_radius = 175, arm_radius = 50;
};

KnownBody known_body() {
  const MakeHuman& mh = makehuman();
  MacroSettings s;
  s.gender = 0;
  KnownBody k;
  k.V = mh.build_vertices(s).topRows(MakeHuman::kBodyVertexCount);
  Eigen::MatrixX3d& V = k.V;
  const SurveyLandmarks& L = survey_landmarks();
  k.crest = point(V, L.iliac_crest).y();
  const double crotch = point(V, L.crotch).y();
  k.hip_y = crotch + 0.3 * (k.crest - crotch);  // inside the searched lower half
  const double lo = crotch + 15, hi = k.crest + 60;
  std::vector<int> torso;
  double zc = 0;
  for (int v = 0; v < V.rows(); ++v)
    if (V(v, 1) >= lo && V(v, 1) <= hi && std::abs(V(v, 0)) < 220) torso.push_back(v), zc += V(v, 2);
  zc /= static_cast<double>(torso.size());
  for (int v : torso) {
    const double y = V(v, 1), d = y - k.hip_y;
    double r = KnownBody::waist_radius;
    if (y < k.crest - 20) r = KnownBody::hip_radius - 0.004 * d * d;
    r = std::max(r, y < k.crest - 20 ? 120.0 : KnownBody::waist_radius);
    const double a = std::atan2(V(v, 2) - zc, V(v, 0));
    V(v, 0) = r * std::cos(a);
    V(v, 2) = zc + r * std::sin(a);
  }
  // Lengths.
  const Eigen::Vector3d A = V.row(L.acromion[0]).transpose();
  const Eigen::Vector3d dir = (V.row(L.olecranon[0]).transpose() - A).normalized();
  V.row(L.olecranon[0]) = (A + 300 * dir).transpose();
  V.row(L.patella_top[0]) = V.row(L.inguinal[0]) - Eigen::RowVector3d(0, 400, 0);
  // Arm ring: a regular polygon round the midpoint, square to the (new) acromion → olecranon line.
  const Eigen::Vector3d M = A + 150 * dir;
  Eigen::Vector3d a = dir.cross(Eigen::Vector3d::UnitY()).normalized(), b = dir.cross(a);
  const int n = static_cast<int>(L.upper_arm_ring.size());
  for (int i = 0; i < n; ++i) {
    const double t = 2 * M_PI * i / n;
    V.row(L.upper_arm_ring[i]) = (M + KnownBody::arm_radius * (std::cos(t) * a + std::sin(t) * b)).transpose();
  }
  return k;
}

}  // namespace

TEST(SurveyMeasure, KnownGirthsAndLengths) {
  const KnownBody k = known_body();
  const BodyMeasurements m = measure_body(k.V, makehuman().body_faces(), Sex::female);
  ASSERT_TRUE(m.survey);
  // Waist at the iliac crest: a section of points on one circle (on chords between its vertices).
  const double waist = 2 * M_PI * KnownBody::waist_radius / 10;
  EXPECT_LE(m.waist_iliac_cm, waist * 1.0001);
  EXPECT_GE(m.waist_iliac_cm, waist * 0.99);
  EXPECT_NEAR(m.waist_iliac_at_cm, (k.crest - k.V.col(1).minCoeff()) / 10, 1e-9);
  // Hip: the level of the largest posterior extension is the bump's peak (cuts 3 mm apart).
  const double hip = 2 * M_PI * KnownBody::hip_radius / 10;
  EXPECT_LE(m.hips_cm, hip * 1.0001);
  EXPECT_GE(m.hips_cm, hip * 0.99);
  EXPECT_NEAR(m.hips_at_cm, (k.hip_y - k.V.col(1).minCoeff()) / 10, 0.4);
  // Arm: the ring is a regular 20-gon square to the measuring direction: exact.
  const int n = static_cast<int>(survey_landmarks().upper_arm_ring.size());
  EXPECT_NEAR(m.arm_circumference_cm, 2 * n * KnownBody::arm_radius * std::sin(M_PI / n) / 10, 1e-9);
  EXPECT_NEAR(m.upper_arm_length_cm, 30.0, 1e-9);
  EXPECT_NEAR(m.upper_leg_length_cm, 40.0, 1e-9);
}

TEST(SurveyMeasure, UnitsAndTopology) {
  const KnownBody k = known_body();
  MeasureOptions cm;
  cm.mm_per_unit = 10;  // the same body given in centimetres measures the same
  const BodyMeasurements a = measure_body(k.V, makehuman().body_faces(), Sex::female);
  const BodyMeasurements b = measure_body(k.V / 10, makehuman().body_faces(), Sex::female, cm);
  EXPECT_NEAR(a.waist_iliac_cm, b.waist_iliac_cm, 1e-6);
  EXPECT_NEAR(a.hips_cm, b.hips_cm, 1e-6);
  EXPECT_NEAR(a.arm_circumference_cm, b.arm_circumference_cm, 1e-6);
  // Not the template's topology: no survey measurements (NaN), the band hip instead.
  Eigen::MatrixX3d V = k.V;
  V.conservativeResize(V.rows() + 1, 3);
  V.row(V.rows() - 1) = V.row(0);
  const BodyMeasurements c = measure_body(V, makehuman().body_faces(), Sex::female);
  EXPECT_FALSE(c.survey);
  EXPECT_TRUE(std::isnan(c.waist_iliac_cm));
  EXPECT_TRUE(std::isnan(measurement_value(c, "arm_circumference_cm")));
  EXPECT_GT(c.hips_cm, 0);
}

TEST(SurveyMeasure, DefaultBodiesAreInTheSurveysRange) {
  // MakeHuman's default woman and man against NHANES adults: girths inside the survey's 1st–99th
  // percentile range, the hip below the waist's level, the waist at the crest above the natural one.
  for (double g : {0.0, 1.0}) {
    MacroSettings s;
    s.gender = g;
    const MakeHuman::Body b = makehuman().body(s);
    const BodyMeasurements m = measure_body(b.mesh.V, b.mesh.F, g > 0.5 ? Sex::male : Sex::female);
    EXPECT_GT(m.waist_iliac_cm, 65);
    EXPECT_LT(m.waist_iliac_cm, 140);
    EXPECT_GT(m.hips_cm, 80);
    EXPECT_LT(m.hips_cm, 140);
    EXPECT_GT(m.arm_circumference_cm, 20);
    EXPECT_LT(m.arm_circumference_cm, 45);
    EXPECT_LT(m.hips_at_cm, m.waist_iliac_at_cm);
    EXPECT_LT(m.waist_iliac_at_cm, m.waist_at_cm);
  }
}

TEST(Plausibility, RoughnessSeesACrease) {
  // The default body is smooth on its trunk and limbs; a 15 mm ridge pushed out along the belly
  // raises the region's 95th percentile and maximum.
  const MakeHuman& mh = makehuman();
  const MakeHuman::Body b = mh.body(MacroSettings{});
  const auto region = mh.trunk_and_limbs_region();
  const Roughness smooth = roughness(b.mesh.V, b.mesh.F, region);
  EXPECT_LT(smooth.p95_deg, 12);
  Eigen::MatrixX3d V = b.mesh.V;
  const Eigen::MatrixX3d N = [&] {
    Eigen::MatrixX3d n = V;
    n.setZero();
    for (int f = 0; f < b.mesh.F.rows(); ++f) {
      const Eigen::RowVector3d a = V.row(b.mesh.F(f, 1)) - V.row(b.mesh.F(f, 0)),
                               c = V.row(b.mesh.F(f, 2)) - V.row(b.mesh.F(f, 0));
      for (int k = 0; k < 3; ++k) n.row(b.mesh.F(f, k)) += a.cross(c);
    }
    n.rowwise().normalize();
    return n;
  }();
  const double y0 = point(V, survey_landmarks().iliac_crest).y();
  int moved = 0;
  for (int v = 0; v < V.rows(); ++v)
    if (region[v] && std::abs(V(v, 1) - y0) < 40 && V(v, 2) > 0 && std::abs(V(v, 0)) < 150 && (v % 2 == 0))
      V.row(v) += 15 * N.row(v), ++moved;
  ASSERT_GT(moved, 20);
  const Roughness rough = roughness(V, b.mesh.F, region);
  EXPECT_GT(rough.max_deg, smooth.max_deg);
  EXPECT_GT(rough.p95_deg, 1.25 * smooth.p95_deg);
  // With the edges given once (a crowd's bodies): the same figures, bit for bit.
  const Eigen::MatrixX2i edges = unique_edges(b.mesh.F);
  for (const Eigen::MatrixX3d* mesh : {&b.mesh.V, static_cast<const Eigen::MatrixX3d*>(&V)}) {
    const Roughness a = roughness(*mesh, b.mesh.F, region), e = roughness(*mesh, b.mesh.F, region, edges);
    EXPECT_EQ(a.p95_deg, e.p95_deg);
    EXPECT_EQ(a.max_deg, e.max_deg);
    EXPECT_EQ(a.vertices, e.vertices);
  }
}

TEST(Plausibility, SelfIntersectionsOfTwoCrossingBodies) {
  const MakeHuman::Body b = makehuman().body(MacroSettings{});
  const int own = self_intersecting_triangle_pairs(b.mesh.V, b.mesh.F);
  // Two copies, the second shifted by half a body width: their surfaces cross along curves.
  Eigen::MatrixX3d V(2 * b.mesh.V.rows(), 3);
  V << b.mesh.V, b.mesh.V.rowwise() + Eigen::RowVector3d(150, 0, 0);
  Eigen::MatrixX3i F(2 * b.mesh.F.rows(), 3);
  F << b.mesh.F, b.mesh.F.array() + static_cast<int>(b.mesh.V.rows());
  const int both = self_intersecting_triangle_pairs(V, F);
  EXPECT_GT(both, 2 * own + 100);
  // The grid broad phase finds the pairs CGAL's box intersection finds.
  EXPECT_EQ(self_intersecting_triangle_pairs_box_d(b.mesh.V, b.mesh.F), own);
  EXPECT_EQ(self_intersecting_triangle_pairs_box_d(V, F), both);
  // Far apart: exactly twice the body's own count.
  V.bottomRows(b.mesh.V.rows()).col(0).array() += 5000;
  EXPECT_EQ(self_intersecting_triangle_pairs(V, F), 2 * own);
}

TEST(Plausibility, SelfIntersectionGridCountsWhatCgalBoxIntersectionCounts) {
  // A soup of random triangles of mixed sizes (some sharing vertices, one degenerate, some
  // 12× larger): the grid broad phase and CGAL's box_self_intersection_d give the same count.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0, 100), small(-4, 4);
  const int nv = 3000, nf = 2000;
  Eigen::MatrixX3d V(nv, 3);
  for (int v = 0; v < nv; v += 3) {
    const Eigen::RowVector3d c(u(rng), u(rng), u(rng));
    const double scale = v % 300 == 0 ? 12.0 : 1.0;
    for (int k = 0; k < 3; ++k) V.row(v + k) = c + scale * Eigen::RowVector3d(small(rng), small(rng), small(rng));
  }
  V.row(7) = V.row(6);  // a degenerate triangle
  // The vertices' triangles, then triangles sharing vertices with them and their neighbours
  // in index order (spanning a few units: the grid's cells, not the whole cube).
  Eigen::MatrixX3i F(nf, 3);
  std::uniform_int_distribution<int> any(0, nv - 7);
  for (int f = 0; f < nf; ++f)
    if (f < nv / 3) F.row(f) << 3 * f, 3 * f + 1, 3 * f + 2;
    else {
      const int a = any(rng);
      F.row(f) << a, a + 1, a + 5;
    }
  const int grid = self_intersecting_triangle_pairs(V, F);
  EXPECT_GT(grid, 10);
  EXPECT_EQ(grid, self_intersecting_triangle_pairs_box_d(V, F));
}
