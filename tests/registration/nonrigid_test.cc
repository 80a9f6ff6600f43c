#include "registration/nonrigid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/fold_repair.h"
#include "core/geometry.h"
#include "registration/fixtures.h"
#include "registration/register_scan.h"

namespace bodymodel {
namespace {

// A flat grid of template vertices at z = 0 (normals +z) and a dense noiseless scan of the
// plane z = 5: every vertex with ≥ 4 matched points must be projected exactly onto z = 5
// right above itself (x, y unchanged), which the closest-point target would not do.
TEST(InverseCorrespondences, PlaneProjectionLandsOnThePlane) {
  const int g = 21;
  Eigen::MatrixX3d V(g * g, 3), VN(g * g, 3);
  for (int i = 0; i < g; ++i)
    for (int j = 0; j < g; ++j) {
      V.row(i * g + j) << 10.0 * i, 10.0 * j, 0.0;
      VN.row(i * g + j) << 0, 0, 1;
    }
  PointCloud scan;
  const int s = 160;
  scan.P.resize(s * s, 3);
  scan.N.resize(s * s, 3);
  for (int i = 0; i < s; ++i)
    for (int j = 0; j < s; ++j) {
      // Irregular sampling so the closest scan point is never right above a vertex.
      scan.P.row(i * s + j) << -3.0 + 206.0 * (i + 0.37) / s, -3.0 + 206.0 * (j + 0.61) / s,
          5.0;
      scan.N.row(i * s + j) << 0, 0, 1;
    }
  PointIndex index(scan.P);
  NonrigidOptions o;
  InverseCorrespondences c = inverse_correspondences(V, VN, scan, index, o);
  EXPECT_EQ(c.plane_count, g * g);
  double max_err = 0;
  for (int i = 0; i < g * g; ++i) {
    ASSERT_EQ(c.kind(i), 1);
    Eigen::RowVector3d expected = V.row(i) + Eigen::RowVector3d(0, 0, 5);
    max_err = std::max(max_err, (c.target.row(i) - expected).norm());
  }
  EXPECT_LT(max_err, 1e-9);

  // Normals facing away (> 30°) reject every pair; points beyond 50 mm too.
  PointCloud flipped = scan;
  flipped.N.col(2).setConstant(-1.0);
  InverseCorrespondences none = inverse_correspondences(V, VN, flipped, index, o);
  EXPECT_EQ(none.plane_count + none.closest_count, 0);
  PointCloud far = scan;
  far.P.col(2).setConstant(60.0);
  PointIndex far_index(far.P);
  none = inverse_correspondences(V, VN, far, far_index, o);
  EXPECT_EQ(none.plane_count + none.closest_count, 0);
  // Unsigned comparison accepts the flipped normals.
  o.unsigned_normals = true;
  EXPECT_EQ(inverse_correspondences(V, VN, flipped, index, o).plane_count, g * g);
}

// Sparse scan: fewer than 4 points per vertex → closest scan point is used.
TEST(InverseCorrespondences, FallsBackToClosestPoint) {
  Eigen::MatrixX3d V(2, 3), VN(2, 3);
  V << 0, 0, 0, 100, 0, 0;
  VN << 0, 0, 1, 0, 0, 1;
  PointCloud scan;
  scan.P.resize(2, 3);
  scan.N.resize(2, 3);
  scan.P << 1, 2, 3, 100, 0, 80;  // the second is 80 mm away: rejected
  scan.N << 0, 0, 1, 0, 0, 1;
  PointIndex index(scan.P);
  InverseCorrespondences c = inverse_correspondences(V, VN, scan, index, NonrigidOptions{});
  EXPECT_EQ(c.kind(0), 2);
  EXPECT_EQ(c.kind(1), 0);
  EXPECT_LT((c.target.row(0) - Eigen::RowVector3d(1, 2, 3)).norm(), 1e-12);
}

TEST(NonrigidSchedule, PaperAndFast) {
  NonrigidOptions o;
  o.schedule = NonrigidSchedule::paper;
  std::vector<double> b = nonrigid_schedule(o);
  ASSERT_EQ(b.size(), 1500u);
  EXPECT_DOUBLE_EQ(b.front(), 3000.0);
  // β(tmax) would be k∞; the last step is one step short of it.
  EXPECT_NEAR(b.back(), 3000.0 * std::pow(0.01 / 3000.0, 1499.0 / 1500.0), 1e-9);
  o.schedule = NonrigidSchedule::fast;
  b = nonrigid_schedule(o);
  ASSERT_EQ(int(b.size()), o.fast_steps);
  EXPECT_NEAR(b.back(), o.fast_k_end, 1e-9);
}

// Landmarks on every 300th vertex at their true positions (a scan database supplies ~20).
std::vector<Landmark> landmarks_of(const Eigen::MatrixX3d& truth) {
  std::vector<Landmark> l;
  for (Eigen::Index i = 0; i < truth.rows(); i += 300)
    l.push_back({int(i), truth.row(i).transpose(), "l" + std::to_string(i)});
  return l;
}

// A smooth, known deformation of an asymmetric blob (anisotropic scale, bend and bulge): the
// fitted vertices must land on the deformed vertices of the same index within bounds.
TEST(NonrigidRegistration, RecoversSmoothDeformation) {
  Mesh sphere = test::potato(200.0, 4);  // 2562 vertices
  Mesh deformed = sphere;
  for (Eigen::Index i = 0; i < sphere.V.rows(); ++i) {
    const Eigen::Vector3d p = sphere.V.row(i).transpose();
    Eigen::Vector3d q(1.15 * p.x(), 0.9 * p.y(), p.z());
    q.x() += 25.0 * std::sin(p.y() / 120.0);
    q.z() += 15.0 * std::exp(-((p - Eigen::Vector3d(0, 0, 200)).squaredNorm()) / (2 * 80.0 * 80.0));
    deformed.V.row(i) = q.transpose();
  }
  PointCloud scan = test::scan_of(deformed, 40000, 7, 0.5);
  NonrigidRegistration reg(sphere);
  NonrigidSummary summary;
  Eigen::MatrixX3d V = reg.fit(sphere.V, scan, landmarks_of(deformed.V), &summary);
  ASSERT_TRUE(V.allFinite());
  Eigen::VectorXd err = (V - deformed.V).rowwise().norm();
  const double initial = (sphere.V - deformed.V).rowwise().norm().mean();
  // Surface fit: distance to the deformed surface along its normal.
  Eigen::MatrixX3d N = vertex_normals(deformed.V, deformed.F);
  double normal_err = 0;
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    normal_err += std::abs((V.row(i) - deformed.V.row(i)).dot(N.row(i)));
  normal_err /= V.rows();
  RecordProperty("mean_error_mm", std::to_string(err.mean()));
  std::printf("initial %.2f mm, correspondence mean %.3f max %.3f mm, normal %.3f mm, %d steps %.2f s\n",
              initial, err.mean(), err.maxCoeff(), normal_err, summary.iterations,
              summary.seconds);
  EXPECT_GT(initial, 15.0);
  EXPECT_LT(err.mean(), 3.0);
  EXPECT_LT(err.maxCoeff(), 10.0);
  EXPECT_LT(normal_err, 0.5);
  EXPECT_EQ(summary.iterations, reg.options().fast_steps);
  EXPECT_GT(summary.matched_vertices, int(0.95 * V.rows()));
  EXPECT_LT(summary.data_rms, 1.5);
}

// Landmarks pull a vertex where no data is; a hole in the scan is filled smoothly.
// Reusing the factorisation as a CG preconditioner solves the same systems: the result matches
// factorising every step to far below the scan noise, with fewer factorisations.
TEST(NonrigidRegistration, FactorisationReuseMatchesFullSolves) {
  Mesh sphere = test::potato(200.0, 3);
  Mesh deformed = sphere;
  for (Eigen::Index i = 0; i < sphere.V.rows(); ++i) {
    const Eigen::Vector3d p = sphere.V.row(i).transpose();
    deformed.V.row(i) = Eigen::RowVector3d(1.1 * p.x() + 20.0 * std::sin(p.y() / 100.0),
                                           0.92 * p.y(), p.z());
  }
  const PointCloud scan = test::scan_of(deformed, 15000, 11, 0.5);
  NonrigidOptions full;
  full.reuse_max_iterations = 0;
  NonrigidOptions reuse;  // the default
  ASSERT_GT(reuse.reuse_max_iterations, 0);
  NonrigidSummary s_full, s_reuse;
  NonrigidRegistration r_full(sphere, full), r_reuse(sphere, reuse);
  const Eigen::MatrixX3d V_full = r_full.fit(sphere.V, scan, landmarks_of(deformed.V), &s_full);
  const Eigen::MatrixX3d V_reuse = r_reuse.fit(sphere.V, scan, landmarks_of(deformed.V), &s_reuse);
  const double diff = (V_full - V_reuse).rowwise().norm().maxCoeff();
  std::printf("factorisations %d vs %d (%d CG iterations), max difference %.2e mm\n",
              s_full.factorizations, s_reuse.factorizations, s_reuse.reuse_iterations, diff);
  EXPECT_EQ(s_full.factorizations, full.fast_steps);
  EXPECT_LT(s_reuse.factorizations, full.fast_steps / 2);
  EXPECT_LT(diff, 0.05);
  EXPECT_LT((V_reuse - deformed.V).rowwise().norm().mean(), 3.0);
}

TEST(NonrigidRegistration, LandmarksAndHoles) {
  Mesh sphere = test::potato(200.0, 3);
  Mesh moved = sphere;
  moved.V.rowwise() += Eigen::RowVector3d(10, -5, 8);
  PointCloud scan = test::scan_of(moved, 20000, 3);
  // Cut a hole: drop points with z > 90 (a cap of the blob).
  std::vector<int> keep;
  for (Eigen::Index i = 0; i < scan.P.rows(); ++i)
    if (scan.P(i, 2) < 90.0) keep.push_back(int(i));
  PointCloud holed;
  holed.P = scan.P(keep, Eigen::all);
  holed.N = scan.N(keep, Eigen::all);
  NonrigidRegistration reg(sphere);
  Eigen::MatrixX3d V = reg.fit(sphere.V, holed, landmarks_of(moved.V), nullptr);
  Eigen::VectorXd err = (V - moved.V).rowwise().norm();
  double hole_max = 0;
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    if (moved.V(i, 2) > 100.0) hole_max = std::max(hole_max, err(i));
  EXPECT_LT(hole_max, 5.0);  // no spike inside the hole
  EXPECT_LT(err.mean(), 1.5);
}

// A sphere whose top cap is mirrored left to right (y → −y: its triangles turn inside out,
// a tangle at its rim): the repair removes every fold and brings the cap back close to the
// reference sphere, leaving the rest untouched.
TEST(RepairFlippedTriangles, UnfoldsAFoldedCap) {
  const Mesh sphere = test::icosphere(100.0, 3);
  Eigen::MatrixX3d V = sphere.V;
  std::vector<char> cap(V.rows(), 0);
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    if (V(i, 2) > 80.0) {
      V(i, 1) = -V(i, 1);
      cap[i] = 1;
    }
  const auto flipped = [&](const Eigen::MatrixX3d& X) {
    const Eigen::MatrixX3d N = face_normals(X, sphere.F), R = face_normals(sphere.V, sphere.F);
    int c = 0;
    for (Eigen::Index f = 0; f < sphere.F.rows(); ++f) c += N.row(f).dot(R.row(f)) < 0;
    return c;
  };
  const int before = flipped(V);
  ASSERT_GT(before, 10);
  const Eigen::MatrixX3d folded = V;
  const int reported = repair_flipped_triangles(V, sphere.V, sphere.F, 2);
  EXPECT_EQ(reported, before);
  EXPECT_EQ(flipped(V), 0);
  double cap_err = 0, moved_far = 0;
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    if (cap[i]) cap_err = std::max(cap_err, (V.row(i) - sphere.V.row(i)).norm());
    if (V(i, 2) < 40.0) moved_far = std::max(moved_far, (V.row(i) - folded.row(i)).norm());
  }
  EXPECT_LT(cap_err, 1.0);      // the cap was up to 120 mm off
  EXPECT_LT(moved_far, 1e-12);  // far from the fold nothing moves
}

// A deep dent (the cap above z = 60 pushed through the sphere, twice as deep as it was high):
// its border is tangled over several rings, so the regions of the first passes are too narrow
// to unfold it. The registration's default passes (6, rings up to 7) remove every fold; 3
// passes leave 4 flipped triangles (the real case: a 58-triangle face fold of a registered
// scan, left whole by 3 passes).
TEST(RepairFlippedTriangles, UnfoldsADeepDentWithTheRegistrationsPasses) {
  const Mesh sphere = test::icosphere(100.0, 4);
  Eigen::MatrixX3d V = sphere.V;
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    if (V(i, 2) > 60.0) V(i, 2) = 60.0 - 2.0 * (V(i, 2) - 60.0);
  const int before = count_flipped_triangles(V, sphere.V, sphere.F);
  ASSERT_GT(before, 500);
  const Eigen::MatrixX3d dented = V;
  const RegistrationOptions o;
  Eigen::MatrixX3d three = V;
  repair_flipped_triangles(three, sphere.V, sphere.F, o.repair_flipped_rings, 3);
  EXPECT_GT(count_flipped_triangles(three, sphere.V, sphere.F), 0);
  EXPECT_EQ(repair_flipped_triangles(V, sphere.V, sphere.F, o.repair_flipped_rings,
                                     o.repair_flipped_passes),
            before);
  EXPECT_EQ(count_flipped_triangles(V, sphere.V, sphere.F), 0);
  double moved_far = 0;
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    if (sphere.V(i, 2) < 0.0) moved_far = std::max(moved_far, (V.row(i) - dented.row(i)).norm());
  EXPECT_LT(moved_far, 1e-12);  // the lower half is far from the dent: nothing moves there
}

// A landmark vertex the fit pulled 15 mm out of the reference's surface, beside a fold (a
// neighbour pushed across it): re-solving the region from the reference takes the landmark back
// into the sphere; pinned, it stays where the fit put it and the fold is still removed.
TEST(RepairFlippedTriangles, KeepsPinnedLandmarkVertices) {
  const Mesh sphere = test::icosphere(100.0, 3);
  Eigen::Index p = 0;
  sphere.V.col(2).maxCoeff(&p);
  const Eigen::MatrixX2i E = unique_edges(sphere.F);
  int q = -1;
  for (Eigen::Index e = 0; e < E.rows() && q < 0; ++e)
    if (E(e, 0) == p || E(e, 1) == p) q = E(e, 0) == p ? E(e, 1) : E(e, 0);
  ASSERT_GE(q, 0);
  Eigen::MatrixX3d V = sphere.V;
  V(p, 2) += 15.0;
  V(q, 0) = 2.0 * sphere.V(p, 0) - sphere.V(q, 0);  // across the pole
  V(q, 1) = 2.0 * sphere.V(p, 1) - sphere.V(q, 1);
  const int before = count_flipped_triangles(V, sphere.V, sphere.F);
  ASSERT_GT(before, 0);
  const RegistrationOptions o;
  Eigen::MatrixX3d free = V, pinned = V;
  repair_flipped_triangles(free, sphere.V, sphere.F, o.repair_flipped_rings, o.repair_flipped_passes);
  repair_flipped_triangles(pinned, sphere.V, sphere.F, o.repair_flipped_rings, o.repair_flipped_passes,
                           {int(p)});
  EXPECT_GT((free.row(p) - V.row(p)).norm(), 5.0);  // unpinned, the landmark is lost
  EXPECT_EQ((pinned.row(p) - V.row(p)).norm(), 0.0);
  EXPECT_EQ(count_flipped_triangles(pinned, sphere.V, sphere.F), 0);
}

TEST(NonrigidRegistration, BadInput) {
  Mesh sphere = test::icosphere(100.0, 2);
  NonrigidRegistration reg(sphere);
  PointCloud empty;
  EXPECT_THROW(reg.fit(sphere.V, empty, {}), InputError);
  PointCloud scan = test::scan_of(sphere, 2000, 1);
  EXPECT_THROW(reg.fit(sphere.V.topRows(10), scan, {}), InputError);
  Landmark bad;
  bad.vertex = 100000;
  bad.name = "nowhere";
  EXPECT_THROW(reg.fit(sphere.V, scan, {bad}), InputError);
}

}  // namespace
}  // namespace bodymodel
