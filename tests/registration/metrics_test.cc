// Registration metrics: the local fold test (locally_folded_triangles) that tells a fold from a
// triangle merely turned with its surroundings.
#include "registration/metrics.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/geometry.h"
#include "core/skeleton.h"
#include "registration/fixtures.h"

namespace bodymodel {
namespace {

// The test limb bent at its first joint (y = 200) by `degrees` about z, skinned linearly.
Eigen::MatrixX3d bent_limb(const test::Limb& limb, double degrees) {
  Pose pose = Pose::rest(3);
  pose.rotations[1] = Eigen::AngleAxisd(degrees * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return linear_blend_skinning(limb.mesh.V, limb.weights, forward_kinematics(limb.skeleton, pose));
}

// Linear blend skinning collapses the inside of a sharply bent elbow (the "candy wrapper" of
// an LBS joint): the test finds folded triangles there and only there; a gentle bend, a rigid
// turn of the whole limb and the rest limb have none.
TEST(LocallyFoldedTriangles, FindsTheCollapsedInsideOfABentJointOnly) {
  const test::Limb limb = test::limb();
  const Eigen::MatrixX3i& F = limb.mesh.F;
  const auto count = [](const std::vector<char>& x) { return int(std::count(x.begin(), x.end(), 1)); };

  EXPECT_EQ(count(locally_folded_triangles(limb.mesh.V, limb.mesh.V, F)), 0);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::MatrixX3d turned = limb.mesh.V * R.transpose();
  EXPECT_EQ(count(locally_folded_triangles(turned, limb.mesh.V, F)), 0);
  EXPECT_EQ(count(locally_folded_triangles(bent_limb(limb, 30.0), limb.mesh.V, F)), 0);

  const Eigen::MatrixX3d bent = bent_limb(limb, 150.0);
  const std::vector<char> folded = locally_folded_triangles(bent, limb.mesh.V, F);
  EXPECT_GE(count(folded), 2);  // 0 at 90° (checked at 30° above), 2 at 150°, 4 at 170°
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (folded[f])
      for (int c = 0; c < 3; ++c) {
        const Eigen::RowVector3d p = limb.mesh.V.row(F(f, c));
        EXPECT_NEAR(p.y(), 200.0, 40.0) << "folded triangle " << f << " away from the joint";
        // The lower bone turns towards −x: the inside of the bend is the −x side.
        EXPECT_LT(p.x(), 1e-9) << "folded triangle " << f << " on the outside of the bend";
      }
  EXPECT_THROW(locally_folded_triangles(bent.topRows(10), limb.mesh.V, F), InputError);
}

// A vertex dragged along the tube past the next ring of vertices (rings 10 mm apart) turns the
// two triangles between it and that ring over: exactly those are folded, by 5 mm none is.
TEST(LocallyFoldedTriangles, FindsExactlyTheTrianglesADraggedVertexTurnsOver) {
  const test::Limb limb = test::limb();
  const Eigen::MatrixX3i& F = limb.mesh.F;
  const int v = 30 * 24 + 5;  // ring 30 (y = 300), segment 5
  for (double drag : {5.0, 12.0}) {
    Eigen::MatrixX3d V = limb.mesh.V;
    V(v, 1) += drag;
    const std::vector<char> folded = locally_folded_triangles(V, limb.mesh.V, F);
    const Eigen::MatrixX3d N = face_normals(V, F), N_rest = face_normals(limb.mesh.V, F);
    int turned = 0, found = 0;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
      const bool over = N.row(f).dot(N_rest.row(f)) < 0;
      turned += over;
      found += folded[f];
      EXPECT_EQ(bool(folded[f]), over) << "triangle " << f << ", vertex dragged " << drag << " mm";
    }
    EXPECT_EQ(found, turned);
    EXPECT_EQ(turned, drag > 10.0 ? 2 : 0);
  }
}

// registration_errors splits the flipped triangles by what the scan saw: a scan with a hole
// band around y = 300 (rings 28–32 missing) makes those rings' vertices hole vertices; a vertex
// dragged past the next ring flips two triangles, counted unseen inside the band and seen
// outside it. Each registration's only error is the dragged vertex.
TEST(RegistrationErrors, SplitsFlippedTrianglesIntoSeenAndUnseen) {
  const test::Limb limb = test::limb();
  const Eigen::MatrixX3d& T = limb.mesh.V;
  const Eigen::MatrixX3i& F = limb.mesh.F;
  std::vector<int> seen;
  for (int i = 0; i < T.rows(); ++i)
    if (T(i, 1) < 275.0 || T(i, 1) > 325.0) seen.push_back(i);
  Eigen::MatrixX3d scan(seen.size(), 3);
  for (size_t k = 0; k < seen.size(); ++k) scan.row(k) = T.row(seen[k]);
  for (const int ring : {10, 30}) {
    Eigen::MatrixX3d R = T;
    const int v = ring * 24 + 5;
    R(v, 1) += 12.0;
    const RegistrationErrors e = registration_errors(R, T, F, scan);
    EXPECT_EQ(e.hole_vertices, 5 * 24);
    EXPECT_EQ(int(std::count(e.hole_vertex.begin(), e.hole_vertex.end(), 1)), 5 * 24);
    EXPECT_EQ(e.flipped_triangles, 2) << "vertex dragged in ring " << ring;
    EXPECT_EQ(int(std::count(e.flipped.begin(), e.flipped.end(), 1)), 2);
    EXPECT_EQ(e.flipped_unseen, ring == 30 ? 2 : 0) << "vertex dragged in ring " << ring;
    EXPECT_NEAR(e.vertex_errors(v), 12.0, 1e-9);
    EXPECT_NEAR(e.correspondence_max, 12.0, 1e-9);
    // The hole error is a distance to the true surface: the vertex slid along the tube, so
    // neither registration has one, though the ring-30 vertex is in the hole.
    EXPECT_LT(e.hole_max, 1e-6);
  }
}

}  // namespace
}  // namespace bodymodel
