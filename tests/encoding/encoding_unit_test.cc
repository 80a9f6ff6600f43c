// Unit tests on fixtures made in code: polar decomposition, rotation vectors, round trips on
// closed and open meshes, linear operations, positional constraints and bad input.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/Cholesky>
#include <Eigen/SVD>
#include <cmath>
#include <limits>
#include <random>
#include <thread>

#include "core/error.h"
#include "encoding/block_cholesky.h"
#include "encoding/deformation_gradient.h"
#include "encoding/relative_rotation_decoder.h"
#include "encoding/relative_rotation_encoding.h"
#include "encoding_test_util.h"

namespace bodymodel {
namespace {

using testing::grid_mesh;
using testing::max_error_after_alignment;
using testing::torus_mesh;

// A smooth non-rigid deformation of the torus: twist about z, bend, and a bulge.
Eigen::MatrixX3d deform(const Eigen::MatrixX3d& V, double amount) {
  Eigen::MatrixX3d out(V.rows(), 3);
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    const Eigen::Vector3d p = V.row(i);
    const double angle = amount * p.x() / 100.0;
    Eigen::Vector3d q = Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitX()) * p;
    q *= 1 + 0.2 * amount * std::sin(p.y() / 40.0);
    q.z() += 0.3 * amount * p.x() * p.x() / 100.0;
    out.row(i) = q;
  }
  return out;
}

TEST(PolarDecomposition, ReproducesRandomMatricesIncludingReflectionsAndRankDeficiency) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0, 1);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::Matrix3d U;
    for (int i = 0; i < 9; ++i) U(i) = n(rng);
    if (trial % 4 == 1) U.col(2) = U.col(0) + 2 * U.col(1);  // rank 2
    if (trial % 4 == 2) U.col(0) = -U.col(0);                // reflection if det was > 0
    if (trial % 4 == 3) U.setZero();                         // rank 0
    const PolarDecomposition p = polar_decomposition(U);
    EXPECT_LT((p.R * p.S - U).norm(), 1e-12 * std::max(1.0, U.norm()));
    EXPECT_LT((p.R.transpose() * p.R - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    EXPECT_NEAR(p.R.determinant(), 1.0, 1e-12);
    EXPECT_LT((p.S - p.S.transpose()).norm(), 1e-12 * std::max(1.0, U.norm()));
    EXPECT_TRUE(p.R.allFinite() && p.S.allFinite());
  }
}

// The closed-form fast path (det U > 0, well conditioned) agrees with the SVD definition.
TEST(PolarDecomposition, FastPathAgreesWithTheSvd) {
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0, 1);
  int fast_cases = 0;
  for (int trial = 0; trial < 500; ++trial) {
    Eigen::Matrix3d U = Eigen::Matrix3d::Identity();
    for (int i = 0; i < 9; ++i) U(i) += 0.4 * n(rng);
    if (U.determinant() <= 0) continue;
    ++fast_cases;
    const PolarDecomposition p = polar_decomposition(U);
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(U, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Eigen::Matrix3d R_svd = svd.matrixU() * svd.matrixV().transpose();  // det U > 0
    EXPECT_LT((p.R - R_svd).norm(), 1e-10) << "trial " << trial;
    EXPECT_LT((closest_rotation(U) - R_svd).norm(), 1e-10) << "trial " << trial;
    EXPECT_LT((p.R * p.S - U).norm(), 1e-13 * U.norm());
    EXPECT_LT((p.R.transpose() * p.R - Eigen::Matrix3d::Identity()).norm(), 1e-14);
  }
  EXPECT_GT(fast_cases, 400);
}

TEST(RotationVector, ExpAndLogAreInverseNearZeroAndNearPi) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0, 1);
  const double pi = 3.14159265358979323846;
  for (double angle : {0.0, 1e-14, 1e-9, 1e-5, 0.3, 1.5, 3.0, pi - 1e-7, pi - 1e-12}) {
    for (int trial = 0; trial < 10; ++trial) {
      Eigen::Vector3d axis(n(rng), n(rng), n(rng));
      axis.normalize();
      const Eigen::Vector3d r = angle * axis;
      const Eigen::Matrix3d R = rotation_exp(r);
      const Eigen::Matrix3d R_ref = Eigen::AngleAxisd(angle, axis).toRotationMatrix();
      EXPECT_LT((R - R_ref).norm(), 1e-14) << "angle " << angle;
      const Eigen::Matrix3d R2 = rotation_exp(rotation_log(R));
      EXPECT_LT((R2 - R).norm(), 1e-12) << "angle " << angle;
      if (angle < 3.0) EXPECT_LT((rotation_log(R) - r).norm(), 1e-12) << "angle " << angle;
    }
  }
}

TEST(Encoding, TemplateEncodesToIdentityAndMeanToZero) {
  const Mesh m = torus_mesh(40, 16);
  EncodingTemplate tmpl(m.V, m.F);
  const Eigen::VectorXd x = encode_absolute(tmpl, m.V);
  for (int f = 0; f < tmpl.triangle_count(); ++f) {
    EXPECT_LT(x.segment<9>(15 * f).norm(), 1e-12);
    Eigen::Matrix<double, 6, 1> s;
    s << 1, 0, 0, 1, 0, 1;
    EXPECT_LT((x.segment<6>(15 * f + 9) - s).norm(), 1e-12);
  }
  // A set's mean encodes to exactly zero relative to itself.
  const EncodedSet set = encode_set(tmpl, {deform(m.V, 0.2), deform(m.V, 0.6), deform(m.V, 1.0)});
  const Encoding mean_of_mean = relative_to(set.mean, set.mean->values);
  EXPECT_LT(mean_of_mean.values.cwiseAbs().maxCoeff(), 1e-12);
  // Relative ↔ absolute is lossless.
  EXPECT_LT((absolute_values(set.encodings[1]) - encode_absolute(tmpl, deform(m.V, 0.6)))
                .cwiseAbs().maxCoeff(), 1e-10);
}

TEST(Encoding, RoundTripOnClosedTorusIsExactUpToRigidMotion) {
  const Mesh m = torus_mesh(60, 24);
  auto tmpl = std::make_shared<const EncodingTemplate>(m.V, m.F);
  RelativeRotationDecoder decoder(tmpl);
  const EncodedSet set = encode_set(*tmpl, {deform(m.V, 0.5), deform(m.V, 1.5), m.V});
  const std::vector<Eigen::MatrixX3d> originals = {deform(m.V, 0.5), deform(m.V, 1.5), m.V};
  for (size_t i = 0; i < originals.size(); ++i) {
    const Eigen::MatrixX3d X = decoder.decode(set.encodings[i]);
    const double diag = bounding_box_diagonal(originals[i]);
    EXPECT_LT(max_error_after_alignment(X, originals[i]) / diag, 1e-9) << "mesh " << i;
  }
}

TEST(Encoding, RoundTripOnOpenGridWithBoundaryTriangles) {
  Mesh m = grid_mesh(30, 20);
  auto tmpl = std::make_shared<const EncodingTemplate>(m.V, m.F);
  EXPECT_GT(tmpl->boundary_slot_count(), 0);
  Eigen::MatrixX3d V = m.V;
  for (Eigen::Index i = 0; i < V.rows(); ++i) {  // roll the sheet into a partial cylinder
    const double a = V(i, 0) / 100.0;
    V.row(i) << 60 * std::sin(a), V(i, 1) * (1 + 0.1 * std::sin(a)), 60 * (1 - std::cos(a));
  }
  RelativeRotationDecoder decoder(tmpl);
  const Eigen::MatrixX3d X = decoder.decode(encode(*tmpl, V));
  EXPECT_LT(max_error_after_alignment(X, V) / bounding_box_diagonal(V), 1e-9);
}

TEST(Encoding, SeveralComponentsDecodeEachRigidly) {
  const Mesh a = torus_mesh(30, 12), b = grid_mesh(10, 8);
  Mesh m;
  m.V.resize(a.V.rows() + b.V.rows(), 3);
  m.V << a.V, (b.V.rowwise() + Eigen::RowVector3d(500, 0, 0));
  m.F.resize(a.F.rows() + b.F.rows(), 3);
  m.F << a.F, (b.F.array() + static_cast<int>(a.V.rows())).matrix();
  auto tmpl = std::make_shared<const EncodingTemplate>(m.V, m.F);
  RelativeRotationDecoder decoder(tmpl);
  EXPECT_EQ(decoder.component_count(), 2);
  const Eigen::MatrixX3d D = deform(m.V, 0.4);
  const Eigen::MatrixX3d X = decoder.decode(encode(*tmpl, D));
  // Each component is exact up to its own rigid motion.
  std::vector<char> first(m.V.rows(), 0), second(m.V.rows(), 0);
  for (Eigen::Index i = 0; i < m.V.rows(); ++i) (i < a.V.rows() ? first : second)[i] = 1;
  EXPECT_LT(max_error_after_alignment(X, D, first), 1e-8 * bounding_box_diagonal(D));
  EXPECT_LT(max_error_after_alignment(X, D, second), 1e-8 * bounding_box_diagonal(D));
}

TEST(Encoding, LinearOperationsAndMeansMustMatch) {
  const Mesh m = torus_mesh(30, 12);
  EncodingTemplate tmpl(m.V, m.F);
  const EncodedSet set = encode_set(tmpl, {deform(m.V, 0.2), deform(m.V, 0.8)});
  const Encoding& a = set.encodings[0];
  const Encoding& b = set.encodings[1];
  EXPECT_LT((interpolate(a, b, 0).values - a.values).norm(), 1e-15);
  EXPECT_LT((interpolate(a, b, 1).values - b.values).norm(), 1e-12);
  EXPECT_LT((interpolate(a, b, 0.5).values - 0.5 * (a + b).values).norm(), 1e-12);
  EXPECT_LT(((a - b) + b).values.cwiseAbs().maxCoeff() - a.values.cwiseAbs().maxCoeff(), 1e-12);
  // The two encodings of a two-mesh set are opposite in their stretch entries.
  for (int f = 0; f < 10; ++f)
    EXPECT_NEAR(a.values(15 * f + 9) + b.values(15 * f + 9), 0, 1e-12);
  const Encoding other = encode(tmpl, deform(m.V, 0.2));  // relative to the template
  EXPECT_THROW(a + other, InputError);
  EXPECT_THROW(interpolate(a, other, 0.5), InputError);
  // rebase: the same mesh relative to another mean.
  EXPECT_LT((rebase(other, set.mean).values - a.values).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_THROW(masked_change(a, b, Eigen::VectorXd::Ones(3)), InputError);
}

TEST(Decoder, PositionalConstraintsPullHandlesWithin1mm) {
  const Mesh m = torus_mesh(80, 24, 300, 80);  // ~0.76 m across, in mm
  auto tmpl = std::make_shared<const EncodingTemplate>(m.V, m.F);
  RelativeRotationDecoder decoder(tmpl);
  const Encoding e = encode(*tmpl, m.V);
  PositionConstraints c;
  c.vertices.resize(10);
  c.targets.resize(10, 3);
  const Eigen::MatrixX3d N = vertex_normals(m.V, m.F);
  for (int i = 0; i < 10; ++i) {
    c.vertices(i) = (i * 173 + 11) % static_cast<int>(m.V.rows());
    const double sign = i % 2 ? 1.0 : -1.0;  // push some out, pull some in: not a rigid motion
    c.targets.row(i) = m.V.row(c.vertices(i)) + sign * 50.0 * N.row(c.vertices(i));
  }
  const Eigen::MatrixX3d X = decoder.decode(e, c);
  double worst = 0;
  for (int i = 0; i < 10; ++i)
    worst = std::max(worst, (X.row(c.vertices(i)) - c.targets.row(i)).norm());
  EXPECT_LT(worst, 1.0);
  // The handles really moved the surface (not a rigid motion of the template).
  EXPECT_GT(max_error_after_alignment(X, m.V), 20.0);
  EXPECT_TRUE(X.allFinite());
}

TEST(BadInput, WrongCountsNaNNonManifoldAndDegenerateTriangles) {
  const Mesh m = torus_mesh(20, 10);
  auto tmpl = std::make_shared<const EncodingTemplate>(m.V, m.F);
  // Wrong vertex count.
  EXPECT_THROW(encode(*tmpl, m.V.topRows(m.V.rows() - 1)), InputError);
  // NaN coordinates.
  Eigen::MatrixX3d bad = m.V;
  bad(5, 1) = std::numeric_limits<double>::quiet_NaN();
  try {
    encode(*tmpl, bad);
    FAIL() << "NaN input accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("vertex 5"), std::string::npos) << e.what();
  }
  // Wrong face list (same count, different triangles).
  Eigen::MatrixX3i F2 = m.F;
  std::swap(F2(3, 0), F2(3, 1));
  EXPECT_THROW(tmpl->check_faces(F2, "mesh"), InputError);
  EXPECT_THROW(tmpl->check_faces(m.F.topRows(10), "mesh"), InputError);
  // Non-manifold template: a third triangle on an existing edge.
  Eigen::MatrixX3i F3(m.F.rows() + 1, 3);
  F3 << m.F, Eigen::RowVector3i(m.F(0, 0), m.F(0, 1), m.F(7, 2));
  EXPECT_THROW(EncodingTemplate(m.V, F3), InputError);
  // Zero-area template triangle.
  Eigen::MatrixX3d flat = m.V;
  flat.row(m.F(0, 2)) = 0.5 * (flat.row(m.F(0, 0)) + flat.row(m.F(0, 1)));
  EXPECT_THROW(EncodingTemplate(flat, m.F), InputError);
  // Zero-area triangles in a mesh to encode: robust (documented), finite output, and the
  // round trip still reproduces the mesh.
  RelativeRotationDecoder decoder(tmpl);
  const Encoding e = encode(*tmpl, flat);
  EXPECT_TRUE(e.values.allFinite());
  const Eigen::MatrixX3d X = decoder.decode(e);
  EXPECT_TRUE(X.allFinite());
  EXPECT_LT(max_error_after_alignment(X, flat) / bounding_box_diagonal(flat), 1e-8);
  // A collapsed mesh (every vertex at one point) still decodes to finite positions.
  const Eigen::MatrixX3d point = Eigen::MatrixX3d::Zero(m.V.rows(), 3);
  EXPECT_TRUE(decoder.decode(encode(*tmpl, point)).allFinite());
  // Encodings of the wrong size or with NaN values.
  Encoding wrong{Eigen::VectorXd::Zero(15), nullptr};
  EXPECT_THROW(decoder.decode(wrong), InputError);
  Encoding nan_enc = encode(*tmpl, m.V);
  nan_enc.values(3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(decoder.decode(nan_enc), InputError);
  // Constraints on a vertex that does not exist.
  PositionConstraints c;
  c.vertices = Eigen::VectorXi::Constant(1, 100000);
  c.targets = Eigen::MatrixX3d::Zero(1, 3);
  EXPECT_THROW(decoder.decode(encode(*tmpl, m.V), c), InputError);
}

TEST(Decoder, BaselineWithoutReuseGivesTheSameResult) {
  const Mesh m = torus_mesh(40, 16);
  auto tmpl = std::make_shared<const EncodingTemplate>(m.V, m.F);
  DecoderOptions baseline;
  baseline.reuse_factorisations = false;
  RelativeRotationDecoder fast(tmpl), slow(tmpl, baseline);
  const Encoding e = encode(*tmpl, deform(m.V, 0.7));
  EXPECT_LT((fast.decode(e) - slow.decode(e)).cwiseAbs().maxCoeff(), 1e-9);
  // Decoding twice with the reused factorisation gives the same again.
  EXPECT_LT((fast.decode(e) - slow.decode(e)).cwiseAbs().maxCoeff(), 1e-9);
}

// The three rotation paths (exact tree integration, conjugate gradients, Cholesky) give the
// least-squares solution: each agrees with the forced Cholesky decode.
TEST(Decoder, RotationPathsAgreeWithTheCholeskySolve) {
  const Mesh m = torus_mesh(40, 16);
  auto tmpl = std::make_shared<const EncodingTemplate>(m.V, m.F);
  DecoderOptions chol;
  chol.rotation_solver = RotationSolver::kCholeskyRefactor;
  RelativeRotationDecoder fast(tmpl), reference(tmpl, chol);
  const double diag = bounding_box_diagonal(m.V);
  const EncodedSet set = encode_set(*tmpl, {deform(m.V, 0.5), deform(m.V, -1.2)});
  // Realisable: no linear solve.
  DecodeTiming t;
  const Eigen::MatrixX3d exact = fast.decode(set.encodings[0], {}, &t);
  EXPECT_EQ(t.rotation_path, 0);
  EXPECT_LT((exact - reference.decode(set.encodings[0])).cwiseAbs().maxCoeff(), 1e-9 * diag);
  // Nearly consistent (rotation vectors perturbed by ~1e-7 rad): conjugate gradients.
  Encoding noisy = set.encodings[0];
  std::mt19937 rng(11);
  std::normal_distribution<double> n(0, 1e-7);
  for (int f = 0; f < tmpl->triangle_count(); ++f)
    for (int i = 0; i < 9; ++i) noisy.values(15 * f + i) += n(rng);
  const Eigen::MatrixX3d cg = fast.decode(noisy, {}, &t);
  EXPECT_EQ(t.rotation_path, 1);
  EXPECT_GT(t.cg_iterations, 0);
  EXPECT_LT((cg - reference.decode(noisy)).cwiseAbs().maxCoeff(), 1e-7 * diag);
  // A blend (holonomy): the Cholesky path, and a result that differs from both ends.
  const Encoding blend = interpolate(set.encodings[0], set.encodings[1], 0.5);
  const Eigen::MatrixX3d b = fast.decode(blend, {}, &t);
  EXPECT_EQ(t.rotation_path, 2);
  EXPECT_LT((b - reference.decode(blend)).cwiseAbs().maxCoeff(), 1e-9 * diag);
  EXPECT_GT((b - exact).cwiseAbs().maxCoeff(), 1e-3 * diag);
}

// One decoder, several threads: every concurrent decode (realisable, blend, constrained with
// two different constraint sets) is bit-identical to the sequential one.
TEST(Decoder, ConcurrentDecodesOnOneDecoderMatchSequentialOnes) {
  const Mesh m = torus_mesh(40, 16);
  auto tmpl = std::make_shared<const EncodingTemplate>(m.V, m.F);
  for (const RotationSolver solver : {RotationSolver::kPreconditionedCG, RotationSolver::kCholeskyRefactor}) {
  SCOPED_TRACE(solver == RotationSolver::kCholeskyRefactor ? "CHOLMOD pool" : "default");
  DecoderOptions options;
  options.rotation_solver = solver;
  const RelativeRotationDecoder decoder(tmpl, options);
  const EncodedSet set = encode_set(*tmpl, {deform(m.V, 0.5), deform(m.V, -1.2)});
  const Encoding blend = interpolate(set.encodings[0], set.encodings[1], 0.3);
  PositionConstraints c1, c2;
  c1.vertices = Eigen::Vector3i(0, 200, 400);
  c1.targets = m.V(c1.vertices, Eigen::all).rowwise() + Eigen::RowVector3d(0, 0, 20);
  c2.vertices = Eigen::Vector4i(10, 150, 300, 500);
  c2.targets = m.V(c2.vertices, Eigen::all).rowwise() + Eigen::RowVector3d(15, 0, 0);
  struct Job {
    const Encoding* e;
    const PositionConstraints* c;
  };
  const PositionConstraints none;
  const std::vector<Job> jobs = {{&set.encodings[0], &none}, {&blend, &none},
                                 {&set.encodings[1], &c1}, {&blend, &c2}};
  std::vector<Eigen::MatrixX3d> sequential;
  for (const Job& j : jobs) sequential.push_back(decoder.decode(*j.e, *j.c));
  constexpr int kThreads = 4, kRounds = 3;
  std::vector<std::vector<Eigen::MatrixX3d>> got(kThreads);
  std::vector<std::thread> threads;
  for (int i = 0; i < kThreads; ++i)
    threads.emplace_back([&, i] {
      for (int r = 0; r < kRounds; ++r)
        for (size_t k = 0; k < jobs.size(); ++k) {
          const Job& j = jobs[(k + i) % jobs.size()];  // threads in different orders
          got[i].push_back(decoder.decode(*j.e, *j.c));
        }
    });
  for (auto& t : threads) t.join();
  for (int i = 0; i < kThreads; ++i)
    for (size_t n = 0; n < got[i].size(); ++n) {
      const Eigen::MatrixX3d& expected = sequential[(n % jobs.size() + i) % jobs.size()];
      ASSERT_EQ(got[i][n].rows(), expected.rows());
      EXPECT_EQ((got[i][n] - expected).cwiseAbs().maxCoeff(), 0.0)
          << "thread " << i << ", decode " << n;
    }
  }
}

// The 3×3-block Cholesky (parallel over elimination subtrees) solves a random SPD block system
// on a torus dual graph like a dense LLᵀ, and rejects an indefinite one.
TEST(BlockCholesky, SolvesLikeADenseFactorisationAndRejectsIndefiniteMatrices) {
  const Mesh m = torus_mesh(20, 10);
  const EncodingTemplate tmpl(m.V, m.F);
  const int n = tmpl.triangle_count();
  std::vector<std::pair<int, int>> lower;
  for (int f = 0; f < n; ++f)
    for (int k = 0; k < 3; ++k)
      if (tmpl.adjacency()(f, k) < f) lower.emplace_back(f, tmpl.adjacency()(f, k));
  const BlockCholesky3 chol(n, lower);
  std::mt19937 rng(2);
  std::normal_distribution<double> g(0, 1);
  std::vector<Eigen::Matrix3d> diag(n), off(lower.size());
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (size_t e = 0; e < lower.size(); ++e) {
    for (int i = 0; i < 9; ++i) off[e](i) = g(rng);
    A.block<3, 3>(3 * lower[e].first, 3 * lower[e].second) = off[e];
    A.block<3, 3>(3 * lower[e].second, 3 * lower[e].first) = off[e].transpose();
  }
  for (int i = 0; i < n; ++i) {
    Eigen::Matrix3d B;
    for (int j = 0; j < 9; ++j) B(j) = g(rng);
    diag[i] = B * B.transpose() + 12 * Eigen::Matrix3d::Identity();  // diagonally dominant
    A.block<3, 3>(3 * i, 3 * i) = diag[i];
  }
  BlockCholesky3::Factor factor;
  ASSERT_TRUE(chol.factorize(diag, off, factor));
  // 3 columns (the decoder's kernel), 1, and 5 / 14 (12-column panels, the last zero-padded).
  for (int k : {3, 1, 5, 14}) {
    Eigen::MatrixXd b = Eigen::MatrixXd::Random(3 * n, k), x = b;
    chol.solve(factor, x);
    const Eigen::MatrixXd reference = A.llt().solve(b);
    EXPECT_LT((x - reference).cwiseAbs().maxCoeff(), 1e-12 * reference.cwiseAbs().maxCoeff()) << k << " columns";
  }
  diag[n / 2] = -diag[n / 2];
  EXPECT_FALSE(chol.factorize(diag, off, factor));
}

}  // namespace
}  // namespace bodymodel
