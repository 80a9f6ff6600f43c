#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "core/error.h"
#include "core/geometry.h"
#include "core/point_index.h"
#include "support/fixtures.h"

using namespace bodymodel;

TEST(CotangentLaplacian, SymmetricRowsSumToZeroNegativeSemidefinite) {
  Mesh m = fixtures::uv_sphere(1.0, 12, 24);
  SparseMatrixd L = cotangent_laplacian(m.V, m.F);
  EXPECT_LT((Eigen::MatrixXd(L) - Eigen::MatrixXd(L.transpose())).cwiseAbs().maxCoeff(), 1e-12);
  Eigen::VectorXd rows = L * Eigen::VectorXd::Ones(m.V.rows());
  EXPECT_LT(rows.cwiseAbs().maxCoeff(), 1e-12);
  // x^T L x <= 0 for random x
  Eigen::VectorXd x = Eigen::VectorXd::Random(m.V.rows());
  EXPECT_LE(x.dot(L * x), 1e-12);
}

TEST(CotangentLaplacian, ReproducesMeanCurvatureNormalOfSphere) {
  // On a sphere of radius r, M⁻¹ L V = -2 H n with H = 1/r: a vector of length 2/r pointing inward.
  const double r = 2.0;
  Mesh m = fixtures::uv_sphere(r, 40, 80);
  SparseMatrixd L = cotangent_laplacian(m.V, m.F);
  SparseMatrixd M = mass_matrix_barycentric(m.V, m.F);
  Eigen::MatrixX3d LV = L * m.V;
  double worst = 0, mean = 0;
  int count = 0;
  for (Eigen::Index i = 1; i + 1 < m.V.rows(); ++i) {  // skip the two poles (fan valence 80)
    Eigen::Vector3d hn = LV.row(i).transpose() / M.coeff(i, i);
    Eigen::Vector3d n = m.V.row(i).transpose().normalized();
    double err = (hn + (2.0 / r) * n).norm() / (2.0 / r);
    worst = std::max(worst, err);
    mean += err;
    ++count;
  }
  mean /= count;
  EXPECT_LT(mean, 0.02);   // relative error of the mean-curvature normal
  EXPECT_LT(worst, 0.10);
}

TEST(GradientOperator, ExactForLinearFunctions) {
  Mesh m = fixtures::uv_sphere(1.0, 8, 16);
  SparseMatrixd G = gradient_operator(m.V, m.F);
  Eigen::Vector3d a(0.3, -1.2, 2.0);
  Eigen::VectorXd f = m.V * a;  // linear function: gradient = a projected onto each triangle
  Eigen::VectorXd g = G * f;
  Eigen::MatrixX3d N = face_normals(m.V, m.F);
  const Eigen::Index nf = m.F.rows();
  for (Eigen::Index t = 0; t < nf; ++t) {
    Eigen::Vector3d n = N.row(t).transpose();
    Eigen::Vector3d expected = a - n * n.dot(a);
    Eigen::Vector3d got(g(t), g(nf + t), g(2 * nf + t));
    ASSERT_LT((got - expected).norm(), 1e-9);
  }
}

TEST(Geometry, AreasVolumeNormalsOfBox) {
  Mesh b = fixtures::box(2, 3, 4);
  EXPECT_NEAR(face_areas(b.V, b.F).sum(), 2 * (6 + 8 + 12), 1e-12);
  EXPECT_NEAR(signed_volume(b.V, b.F), 24, 1e-12);
  EXPECT_NEAR(bounding_box_diagonal(b.V), std::sqrt(29.0), 1e-12);
  Eigen::MatrixX3d N = vertex_normals(b.V, b.F);
  // Corner 7 = (2,3,4): its normal points into the positive octant.
  EXPECT_GT(N.row(7).minCoeff(), 0.3);
}

TEST(Adjacency, ClosedMeshHasNoBoundaryAndEulerCharacteristicTwo) {
  Mesh m = fixtures::uv_sphere(1.0, 10, 20);
  Eigen::MatrixX3i TT = triangle_adjacency(m.F);
  EXPECT_GE(TT.minCoeff(), 0);
  for (Eigen::Index f = 0; f < m.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      int g = TT(f, k);
      int shares = 0;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) shares += m.F(f, a) == m.F(g, b);
      ASSERT_EQ(shares, 2);
    }
  Eigen::MatrixX2i E = unique_edges(m.F);
  EXPECT_EQ(m.V.rows() - E.rows() + m.F.rows(), 2);
}

TEST(Adjacency, NonManifoldEdgeIsAnError) {
  Eigen::MatrixX3d V(5, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1;
  Eigen::MatrixX3i F(3, 3);
  F << 0, 1, 2, 1, 0, 3, 0, 1, 4;  // edge (0,1) in three triangles
  EXPECT_THROW(triangle_adjacency(F), InputError);
  EXPECT_THROW(check_triangle_mesh(V, F), InputError);
  F.row(2) << 0, 1, 7;  // out of range
  EXPECT_THROW(check_triangle_mesh(V, F), InputError);
}

TEST(RigidMotion, RecoversRotationAndTranslation) {
  Eigen::MatrixX3d A = Eigen::MatrixX3d::Random(50, 3);
  Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  RigidMotion truth{R, Eigen::Vector3d(1, -2, 0.5)};
  RigidMotion fit = fit_rigid_motion(A, apply(truth, A));
  EXPECT_LT((fit.R - R).norm(), 1e-10);
  EXPECT_LT((fit.t - truth.t).norm(), 1e-10);
}

TEST(PointIndex, MatchesBruteForce) {
  Eigen::MatrixX3d P = Eigen::MatrixX3d::Random(2000, 3);
  PointIndex index(P);
  for (int q = 0; q < 50; ++q) {
    Eigen::Vector3d x = Eigen::Vector3d::Random();
    Eigen::Index best;
    double d2 = (P.rowwise() - x.transpose()).rowwise().squaredNorm().minCoeff(&best);
    double got;
    EXPECT_EQ(index.nearest(x, &got), best);
    EXPECT_NEAR(got, d2, 1e-12);
    auto k = index.knn(x, 5);
    ASSERT_EQ(k.size(), 5u);
    EXPECT_EQ(k[0], best);
    auto w = index.within(x, 0.3);
    int brute = ((P.rowwise() - x.transpose()).rowwise().norm().array() <= 0.3).count();
    EXPECT_EQ(static_cast<int>(w.size()), brute);
  }
}

TEST(SampleSurface, UniformByArea) {
  Mesh b = fixtures::box(1, 1, 10);  // the four long sides hold 40/42 of the area
  SurfaceSamples s = sample_surface(b.V, b.F, 20000, 3);
  int on_caps = (s.P.col(2).array() < 1e-9 || s.P.col(2).array() > 10 - 1e-9).count();
  EXPECT_NEAR(on_caps / 20000.0, 2.0 / 42.0, 0.01);
}
