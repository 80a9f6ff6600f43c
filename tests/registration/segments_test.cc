#include "registration/segments.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/geometry.h"
#include "core/makehuman.h"
#include "core/point_index.h"
#include "registration/fixtures.h"
#include "registration/nonrigid.h"

namespace bodymodel {
namespace {

int segment_named(const BodySegments& s, const std::string& name) {
  const auto it = std::find(s.names.begin(), s.names.end(), name);
  return it == s.names.end() ? -1 : int(it - s.names.begin());
}

// The vertex of V closest to p.
int closest_vertex(const Eigen::MatrixX3d& V, const Eigen::Vector3d& p) {
  Eigen::Index i = 0;
  (V.rowwise() - p.transpose()).rowwise().squaredNorm().minCoeff(&i);
  return int(i);
}

// MakeHuman's default body: nine segments, each limb's vertices where its bones are, and the
// adjacency that separates the contacts (hand-hip, forearm-forearm, foot-knee) but keeps the
// seams at the shoulders and hips.
TEST(BodySegments, MakeHumanTemplate) {
  const MakeHuman mh = MakeHuman::load();
  const MakeHuman::Body body = mh.body(MacroSettings{});
  const BodySegments s = body_segments(body.skeleton, body.weights, body.mesh.F);
  ASSERT_EQ(s.count(), 9);
  ASSERT_EQ(s.vertex_segment.size(), body.mesh.V.rows());
  for (int k = 0; k < s.count(); ++k)
    EXPECT_GT((s.vertex_segment.array() == k).count(), 100) << s.names[k];
  const Skeleton& sk = body.skeleton;
  auto at = [&](const char* bone) { return s.vertex_segment(closest_vertex(body.mesh.V, sk.heads.row(sk.index(bone)).transpose())); };
  // Mid-bone points: the tail of a bone that is not itself a segment root.
  auto mid = [&](const char* bone) {
    const int b = sk.index(bone);
    return s.vertex_segment(closest_vertex(body.mesh.V, (0.5 * (sk.heads.row(b) + sk.tails.row(b))).transpose()));
  };
  for (const char* side : {".L", ".R"}) {
    const std::string sd = side;
    EXPECT_EQ(mid(("upperarm01" + sd).c_str()), segment_named(s, "upperarm" + sd));
    EXPECT_EQ(mid(("lowerarm01" + sd).c_str()), segment_named(s, "lowerarm" + sd));
    EXPECT_EQ(at(("wrist" + sd).c_str()), segment_named(s, "lowerarm" + sd));
    EXPECT_EQ(mid(("upperleg01" + sd).c_str()), segment_named(s, "upperleg" + sd));
    EXPECT_EQ(mid(("lowerleg01" + sd).c_str()), segment_named(s, "lowerleg" + sd));
    EXPECT_EQ(at(("foot" + sd).c_str()), segment_named(s, "lowerleg" + sd));
  }
  EXPECT_EQ(at("head"), 0);
  EXPECT_EQ(mid("spine03"), 0);
  auto adj = [&](const std::string& a, const std::string& b) {
    return s.adjacent(segment_named(s, a), segment_named(s, b)) != 0;
  };
  EXPECT_TRUE(adj("torso", "upperarm.L"));
  EXPECT_TRUE(adj("upperarm.R", "lowerarm.R"));
  EXPECT_TRUE(adj("torso", "upperleg.R"));
  EXPECT_TRUE(adj("upperleg.L", "lowerleg.L"));
  EXPECT_FALSE(adj("torso", "lowerarm.L"));      // hands on hips
  EXPECT_FALSE(adj("upperleg.L", "lowerarm.L"));  // hands on thighs
  EXPECT_FALSE(adj("lowerarm.L", "lowerarm.R"));  // crossed arms
  EXPECT_FALSE(adj("lowerarm.R", "upperarm.L"));
  EXPECT_FALSE(adj("lowerleg.R", "upperleg.L"));  // foot on the other knee
  EXPECT_FALSE(adj("torso", "lowerleg.L"));
  EXPECT_THROW(body_segments(body.skeleton, SkinWeights(body.weights.rows(), 3), body.mesh.F), InputError);
}

// Two limbs side by side: a "torso" tube A (radius 40) and a "forearm" tube B (radius 15) that
// touches A along a line in the scan. The scan is fused where they touch (each tube's points
// inside the other are missing, as in a reconstructed scan). The template is the same two tubes
// with B displaced by `offset` (a pose fit that left the limb off its place).
struct ContactCase {
  Mesh tpl;            // A then B, B displaced
  Eigen::MatrixX3d truth;  // the vertices where they belong
  BodySegments segments;
  PointCloud scan;
  Eigen::VectorXi scan_segment;  // the tube each scan point was sampled on
  int a_vertices = 0;
};

ContactCase contact_case(const Eigen::Vector3d& offset) {
  const double ra = 40, rb = 15;
  Mesh a = test::tube(300.0, ra, 31, 48), b = test::tube(240.0, rb, 25, 20);
  const Eigen::RowVector3d b_at(ra + rb, 30.0, 0.0);
  ContactCase c;
  c.a_vertices = int(a.V.rows());
  const Eigen::Index na = a.V.rows(), nb = b.V.rows();
  Mesh truth;
  truth.V.resize(na + nb, 3);
  truth.V.topRows(na) = a.V;
  truth.V.bottomRows(nb) = b.V.rowwise() + b_at;
  truth.F.resize(a.F.rows() + b.F.rows(), 3);
  truth.F.topRows(a.F.rows()) = a.F;
  truth.F.bottomRows(b.F.rows()) = b.F.array() + int(na);
  c.truth = truth.V;
  c.tpl = truth;
  c.tpl.V.bottomRows(nb).rowwise() += offset.transpose();
  c.segments.names = {"A", "B"};
  c.segments.vertex_segment = Eigen::VectorXi::Zero(na + nb);
  c.segments.vertex_segment.tail(nb).setOnes();
  c.segments.adjacent = Eigen::MatrixXi::Identity(2, 2);
  const PointCloud all = test::scan_of(truth, 60000, 3);
  std::vector<int> keep;
  for (Eigen::Index j = 0; j < all.P.rows(); ++j) {
    const Eigen::Vector3d p = all.P.row(j).transpose();
    const double to_a = std::hypot(p.x(), p.z()), to_b = std::hypot(p.x() - b_at.x(), p.z() - b_at.z());
    const bool in_b = to_b < rb - 0.5 && p.y() > b_at.y() && p.y() < b_at.y() + 240.0;
    const bool in_a = to_a < ra - 0.5;
    if (!in_a && !in_b) keep.push_back(int(j));
  }
  c.scan.P.resize(keep.size(), 3);
  c.scan.N.resize(keep.size(), 3);
  c.scan_segment.resize(Eigen::Index(keep.size()));
  for (size_t k = 0; k < keep.size(); ++k) {
    c.scan.P.row(k) = all.P.row(keep[k]);
    c.scan.N.row(k) = all.N.row(keep[k]);
    const Eigen::Vector3d p = c.scan.P.row(k).transpose();
    c.scan_segment(k) = std::abs(std::hypot(p.x(), p.z()) - ra) < std::abs(std::hypot(p.x() - b_at.x(), p.z()) - rb) ? 0 : 1;
  }
  return c;
}

// The scan points of two touching limbs get their own limb's segment from a posed template that
// is a centimetre off: the normal test sends the points next to the contact, which are as close
// to the other limb, to the limb whose surface faces their way.
TEST(ContactSegments, ScanPointsTakeTheirOwnLimbsSegment) {
  const ContactCase c = contact_case({-6, 0, 10});
  const Eigen::MatrixX3d VN = vertex_normals(c.tpl.V, c.tpl.F);
  const Eigen::VectorXi s = point_segments(c.scan.P, c.scan.N, c.tpl.V, VN, c.segments.vertex_segment);
  const double right = double((s.array() == c.scan_segment.array()).count()) / double(s.size());
  PointSegmentOptions nearest;  // no normal test: the closest vertex's segment
  nearest.min_normal_cos = -2.0;
  const Eigen::VectorXi s0 = point_segments(c.scan.P, c.scan.N, c.tpl.V, VN, c.segments.vertex_segment, nearest);
  const double right0 = double((s0.array() == c.scan_segment.array()).count()) / double(s.size());
  std::printf("scan points given their own limb: %.4f with the normal test, %.4f by the closest vertex\n", right,
              right0);
  EXPECT_GT(right, 0.999);
  EXPECT_LT(right0, right);
  EXPECT_THROW(point_segments(c.scan.P, c.scan.N, c.tpl.V, VN, c.segments.vertex_segment.head(5)), InputError);
}

// A limb lying on another (a forearm across the chest, a hand on a hip) where the template's
// limb is not yet in place: the scan points of the limb on top lie 12 mm above the surface below
// and face the same way, so without segments they are matched to the vertices underneath and pull
// them onto the wrong limb; with segments those pairs are refused both ways.
TEST(ContactSegments, RefusedPairsKeepVerticesOffTheOtherLimb) {
  const int g = 21;
  Eigen::MatrixX3d V(g * g, 3), VN(g * g, 3);
  for (int i = 0; i < g; ++i)
    for (int j = 0; j < g; ++j) {
      V.row(i * g + j) << 10.0 * i, 10.0 * j, 0.0;  // the surface below (segment 0)
      VN.row(i * g + j) << 0, 0, 1;
    }
  // Scan: the limb on top (segment 1) at z = 12 over x < 100, the surface below elsewhere.
  const int s = 120;
  PointCloud scan;
  scan.P.resize(s * s, 3);
  scan.N.resize(s * s, 3);
  SegmentLabels labels;
  BodySegments segments;
  segments.names = {"below", "on top"};
  segments.vertex_segment = Eigen::VectorXi::Zero(g * g);
  segments.adjacent = Eigen::MatrixXi::Identity(2, 2);
  labels.segments = &segments;
  labels.point_segment.resize(s * s);
  for (int i = 0; i < s; ++i)
    for (int j = 0; j < s; ++j) {
      const double x = 200.0 * (i + 0.37) / s, y = 200.0 * (j + 0.61) / s;
      const bool on_top = x < 100.0;
      scan.P.row(i * s + j) << x, y, on_top ? 12.0 : 0.0;
      scan.N.row(i * s + j) << 0, 0, 1;
      labels.point_segment(i * s + j) = on_top ? 1 : 0;
    }
  const PointIndex index(scan.P);
  NonrigidOptions o;
  auto on_top_targets = [&](const InverseCorrespondences& c) {
    int n = 0;
    for (int i = 0; i < g * g; ++i)
      if (c.kind(i) != 0 && c.target(i, 2) > 6.0) ++n;
    return n;
  };
  const InverseCorrespondences plain = inverse_correspondences(V, VN, scan, index, o);
  const InverseCorrespondences refused = inverse_correspondences(V, VN, scan, index, o, &labels);
  std::printf("vertices below with a target on the limb on top: %d without segments, %d with\n",
              on_top_targets(plain), on_top_targets(refused));
  EXPECT_GT(on_top_targets(plain), 150);  // the 10 × 21 vertices under the limb
  EXPECT_EQ(on_top_targets(refused), 0);
  EXPECT_GT(refused.refused, s * s / 3);
  // The vertices beyond the limb keep their data.
  int beyond = 0;
  for (int i = 0; i < g * g; ++i)
    if (V(i, 0) > 110.0 && refused.kind(i) != 0) ++beyond;
  EXPECT_EQ(beyond, 9 * g);
  // A point of unknown segment (-1) is compatible with every vertex.
  labels.point_segment.setConstant(-1);
  EXPECT_EQ(on_top_targets(inverse_correspondences(V, VN, scan, index, o, &labels)), on_top_targets(plain));
}

// The whole non-rigid fit on the touching tubes, the template's forearm a centimetre off: with
// segments every vertex lands on its own tube (the landmarks at the tubes' ends and the normal
// test already keep this case right without them; the option must not make it worse).
TEST(ContactSegments, NonrigidFitOfTouchingLimbs) {
  const ContactCase c = contact_case({-6, 0, 10});
  std::vector<Landmark> lm;
  for (Eigen::Index i = 0; i < c.truth.rows(); i += 97)
    if (c.truth(i, 1) > 240 || c.truth(i, 1) < 20) lm.push_back({int(i), c.truth.row(i).transpose(), "end"});
  for (bool on : {false, true}) {
    NonrigidOptions o;
    o.contact_segments = on;
    NonrigidRegistration reg(c.tpl, o);
    reg.set_segments(c.segments);
    NonrigidSummary s;
    const Eigen::MatrixX3d V = reg.fit(c.tpl.V, c.scan, lm, &s);
    const Eigen::VectorXd e = (V - c.truth).rowwise().norm();
    const Eigen::Index na = c.a_vertices, nb = e.size() - na;
    std::printf("contact segments %s: torso tube mean %.2f max %.2f mm, forearm tube mean %.2f max %.2f mm, %d "
                "scan points refused\n", on ? "on " : "off", e.head(na).mean(), e.head(na).maxCoeff(),
                e.tail(nb).mean(), e.tail(nb).maxCoeff(), s.contact_refused);
    EXPECT_LT(e.head(na).maxCoeff(), 1.0);
    EXPECT_LT(e.tail(nb).mean(), 0.5);
    EXPECT_LT(e.tail(nb).maxCoeff(), 1.0);
    if (on) EXPECT_GT(s.contact_refused, 100);
    else EXPECT_EQ(s.contact_refused, 0);
  }
  NonrigidRegistration reg(c.tpl);
  EXPECT_THROW(reg.set_segments(BodySegments{}), InputError);
}

}  // namespace
}  // namespace bodymodel
