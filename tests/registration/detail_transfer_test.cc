#include "registration/detail_transfer.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>

#include "core/error.h"
#include "core/geometry.h"
#include "registration/fixtures.h"
#include "registration/metrics.h"

namespace bodymodel {
namespace {

// Known detail: a smooth signed offset (mm, within ±3) at every edge midpoint of `m`.
SurfaceDetail known_detail(const Mesh& m) {
  const MidEdgeSubdivision sub = mid_edge_subdivision(m.F, int(m.V.rows()));
  Eigen::VectorXd edge(sub.edges.rows());
  for (Eigen::Index e = 0; e < sub.edges.rows(); ++e) {
    const Eigen::Vector3d p = 0.5 * (m.V.row(sub.edges(e, 0)) + m.V.row(sub.edges(e, 1))).transpose();
    edge(e) = 2.0 * std::sin(p.x() / 25.0) * std::cos(p.y() / 30.0) + 1.0 * std::sin(p.z() / 20.0);
  }
  SurfaceDetail d;
  d.offsets.resize(m.F.rows(), 3);
  for (Eigen::Index f = 0; f < m.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) d.offsets(f, k) = edge(sub.face_edges(f, k));
  return d;
}

TEST(MidEdgeSubdivision, SplitsEveryTriangleIntoFourWithTheSameOrientation) {
  const Mesh m = test::icosphere(100.0, 2);
  const MidEdgeSubdivision s = mid_edge_subdivision(m.F, int(m.V.rows()));
  EXPECT_EQ(s.F.rows(), 4 * m.F.rows());
  EXPECT_EQ(s.edges.rows(), unique_edges(m.F).rows());
  const Mesh plain = apply_detail(m.V, m.F, SurfaceDetail{Eigen::MatrixX3d::Zero(m.F.rows(), 3)});
  // V + E vertices, each new one the midpoint of its edge; the volume is unchanged (the
  // midpoints lie on the flat triangles) and the result is a valid manifold mesh.
  ASSERT_EQ(plain.V.rows(), m.V.rows() + s.edges.rows());
  for (Eigen::Index e = 0; e < s.edges.rows(); ++e)
    EXPECT_LT((plain.V.row(m.V.rows() + e) -
               0.5 * (m.V.row(s.edges(e, 0)) + m.V.row(s.edges(e, 1))))
                  .norm(),
              1e-12);
  EXPECT_NEAR(signed_volume(plain.V, plain.F), signed_volume(m.V, m.F), 1e-6);
  check_triangle_mesh(plain.V, plain.F, "subdivided");
}

// Synthetic scan = the subdivided template with known normal offsets at the midpoints (densely
// sampled, 0.3 mm noise): the captured offsets must match the known ones, and re-adding them
// must bring the surface much closer to the scan than the plain fit.
TEST(DetailTransfer, RecoversKnownNormalOffsetsAndReducesTheDistance) {
  const Mesh base = test::potato(100.0, 3);  // 642 vertices, mean edge ≈ 12 mm
  const SurfaceDetail truth_detail = known_detail(base);
  const Mesh truth = apply_detail(base.V, base.F, truth_detail);
  const PointCloud scan = test::scan_of(truth, 150000, 3, 0.3);

  const SurfaceDetail got = capture_detail(base.V, base.F, scan);
  EXPECT_EQ(got.edges_missing, 0);
  const Eigen::ArrayXXd err = (got.offsets - truth_detail.offsets).array().abs();
  const double rms = std::sqrt(err.square().mean());
  EXPECT_LT(rms, 0.25) << "RMS offset error (mm); offsets span ±3 mm";
  EXPECT_LT(err.maxCoeff(), 1.0);

  // Distance from the scan to the plain fit vs to the fit with the details re-added.
  const Mesh detailed = apply_detail(base.V, base.F, got);
  const double plain_d = point_to_mesh_distance(scan.P, base.V, base.F).mean();
  const double detail_d = point_to_mesh_distance(scan.P, detailed.V, detailed.F).mean();
  EXPECT_LT(detail_d, 0.5 * plain_d) << "plain " << plain_d << " mm, detailed " << detail_d;
  EXPECT_LT(detail_d, 0.6);  // the noise alone is 0.3 mm RMS along the normal
  std::printf("offset error RMS %.3f mm, max %.3f mm; scan to plain fit %.3f mm, to detailed "
              "fit %.3f mm\n", rms, err.maxCoeff(), plain_d, detail_d);
}

// Details follow the mesh they are applied to: on a rotated, translated and inflated copy of
// the base (same topology) the offsets are added along that mesh's normals.
TEST(DetailTransfer, AppliesToAnotherMeshOfTheSameTopology) {
  const Mesh base = test::potato(100.0, 2);
  const SurfaceDetail d = known_detail(base);
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::RowVector3d t(40, -20, 300);
  Eigen::MatrixX3d moved = (base.V * R.transpose()).rowwise() + t;
  const Mesh a = apply_detail(base.V, base.F, d);
  const Mesh b = apply_detail(moved, base.F, d);
  const Eigen::MatrixX3d a_moved = (a.V * R.transpose()).rowwise() + t;
  EXPECT_LT((b.V - a_moved).cwiseAbs().maxCoeff(), 1e-9);
  // Half the amount moves every midpoint half as far from the plain subdivision.
  const Mesh plain = apply_detail(base.V, base.F, d, 0.0);
  const Mesh half = apply_detail(base.V, base.F, d, 0.5);
  EXPECT_LT(((half.V - plain.V) * 2.0 - (a.V - plain.V)).cwiseAbs().maxCoeff(), 1e-9);
  // A morphed body (non-rigid: inflated by 10 %) keeps the offsets along its own normals.
  const Mesh c = apply_detail(1.1 * base.V, base.F, d);
  const MidEdgeSubdivision sub = mid_edge_subdivision(base.F, int(base.V.rows()));
  const Eigen::MatrixX3d N = edge_midpoint_normals(1.1 * base.V, base.F, sub);
  double worst = 0;
  for (Eigen::Index f = 0; f < base.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int e = sub.face_edges(f, k);
      const Eigen::RowVector3d mid =
          0.55 * (base.V.row(sub.edges(e, 0)) + base.V.row(sub.edges(e, 1)));
      worst = std::max(worst, std::abs((c.V.row(base.V.rows() + e) - mid).dot(N.row(e)) -
                                       d.offsets(f, k)));
    }
  EXPECT_LT(worst, 1e-9);
}

TEST(DetailTransfer, FileRoundTripAndTopologyCheck) {
  const Mesh base = test::potato(100.0, 2);
  SurfaceDetail d = known_detail(base);
  d.edges_found = 7;
  d.line_radius = 1.5;
  const auto path = std::filesystem::temp_directory_path() / "bodymodel_detail_test.detail.npz";
  write_detail(path, d, base.F);
  const SurfaceDetail r = read_detail(path, base.F);
  EXPECT_LT((r.offsets - d.offsets).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(r.edges_found, 7);
  const Mesh other = test::icosphere(50.0, 1);
  EXPECT_THROW(read_detail(path, other.F), InputError);
  EXPECT_THROW(apply_detail(other.V, other.F, d), InputError);
  std::filesystem::remove(path);
}

TEST(DetailTransfer, BadInputIsAnInputError) {
  const Mesh base = test::potato(100.0, 1);
  PointCloud empty;
  EXPECT_THROW(capture_detail(base.V, base.F, empty), InputError);
  PointCloud no_normals = test::scan_of(base, 100, 1);
  no_normals.N.resize(0, 3);
  EXPECT_THROW(capture_detail(base.V, base.F, no_normals), InputError);
  Eigen::MatrixX3d nan_v = base.V;
  nan_v(0, 0) = std::nan("");
  EXPECT_THROW(capture_detail(nan_v, base.F, test::scan_of(base, 100, 1)), InputError);
}

}  // namespace
}  // namespace bodymodel
