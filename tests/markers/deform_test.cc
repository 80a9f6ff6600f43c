// Park & Hodgins' marker-driven skin (markers/deform.h): known answers (a rigid-plus-quadratic
// motion per part is reproduced; the RBF residual interpolates the markers exactly) and the
// refusals of compare_marker_skins.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "core/error.h"
#include "markers/deform.h"
#include "markers/deform_evaluation.h"

namespace bodymodel {
namespace {

Eigen::MatrixX3d random_points(int n, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  Eigen::MatrixX3d P(n, 3);
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) P(i, c) = lo(c) + u(rng) * (hi(c) - lo(c));
  return P;
}

// x → R (x + B m(x) / L) + t, m = [x² y² z² xy yz zx]: a rigid motion after a quadratic one.
Eigen::MatrixX3d rigid_quadratic(const Eigen::MatrixX3d& X, const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                                 const Eigen::Matrix<double, 3, 6>& B, double L) {
  Eigen::MatrixX3d Y(X.rows(), 3);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    const Eigen::Vector3d x = X.row(i).transpose();
    Eigen::Matrix<double, 6, 1> m;
    m << x.x() * x.x(), x.y() * x.y(), x.z() * x.z(), x.x() * x.y(), x.y() * x.z(), x.z() * x.x();
    Y.row(i) = (R * (x + B * m / L) + t).transpose();
  }
  return Y;
}

// Two parts split at x = 0 (hard weights), each moved by its own rigid-plus-quadratic motion.
struct TwoParts {
  Eigen::MatrixX3d rest, markers, rest_moved, markers_moved;
  Eigen::MatrixXd vertex_weights, marker_weights;
};

TwoParts two_parts() {
  TwoParts s;
  s.rest = random_points(400, {-200, -60, -40}, {200, 60, 40}, 1);
  s.markers = random_points(60, {-200, -60, -40}, {200, 60, 40}, 2);
  const Eigen::Matrix3d R[2] = {Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix(),
                                Eigen::AngleAxisd(-0.9, Eigen::Vector3d(0, 1, 1).normalized()).toRotationMatrix()};
  const Eigen::Vector3d t[2] = {{10, -20, 30}, {-40, 5, 12}};
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.15, 0.15);
  Eigen::Matrix<double, 3, 6> B[2];
  for (auto& b : B) b = b.NullaryExpr([&] { return u(rng); });
  auto move = [&](const Eigen::MatrixX3d& X, Eigen::MatrixXd& W) {
    Eigen::MatrixX3d Y(X.rows(), 3);
    W = Eigen::MatrixXd::Zero(X.rows(), 2);
    for (Eigen::Index i = 0; i < X.rows(); ++i) {
      const int p = X(i, 0) < 0 ? 0 : 1;
      W(i, p) = 1;
      Y.row(i) = rigid_quadratic(X.row(i), R[p], t[p], B[p], 100).row(0);
    }
    return Y;
  };
  s.rest_moved = move(s.rest, s.vertex_weights);
  s.markers_moved = move(s.markers, s.marker_weights);
  return s;
}

double max_error(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B) { return (A - B).rowwise().norm().maxCoeff(); }

// The paper's model without regularisation: exact least squares and exact interpolation.
MarkerSkinOptions exact() {
  MarkerSkinOptions o;
  o.quadratic_ridge = 1e-12;
  o.rbf_ridge = 0;
  return o;
}

TEST(MarkerSkin, ReproducesARigidPlusQuadraticMotionPerPart) {
  const TwoParts s = two_parts();
  const MarkerSkin skin = build_marker_skin(s.rest, s.markers, s.vertex_weights, s.marker_weights, exact());
  ASSERT_EQ(skin.parts.size(), 2u);
  const double moved = max_error(s.rest, s.rest_moved);
  EXPECT_GT(moved, 50.0) << "the motion is not small";
  EXPECT_LT(max_error(deform_by_markers(skin, s.markers_moved, MarkerSkinStage::quadratic), s.rest_moved), 1e-6);
  EXPECT_LT(max_error(deform_by_markers(skin, s.markers_moved, MarkerSkinStage::full), s.rest_moved), 1e-6);
  // Rigid parts alone cannot follow the quadratic part of the motion.
  EXPECT_GT(max_error(deform_by_markers(skin, s.markers_moved, MarkerSkinStage::rigid), s.rest_moved), 5.0);
  // The defaults damp A towards the identity (the residual RBF takes up the rest near the markers):
  // better than rigid parts, not exact.
  const MarkerSkin damped = build_marker_skin(s.rest, s.markers, s.vertex_weights, s.marker_weights);
  const double rigid = max_error(deform_by_markers(damped, s.markers_moved, MarkerSkinStage::rigid), s.rest_moved);
  EXPECT_LT(max_error(deform_by_markers(damped, s.markers_moved, MarkerSkinStage::full), s.rest_moved), 0.5 * rigid);
}

TEST(MarkerSkin, LeavesAMisplacedMarkerOutOfItsPartsFit) {
  TwoParts s = two_parts();
  s.markers_moved.row(7) += Eigen::RowVector3d(150, -80, 60);  // a wrong merge in the cleaning
  const MarkerSkin skin = build_marker_skin(s.rest, s.markers, s.vertex_weights, s.marker_weights, exact());
  EXPECT_LT(max_error(deform_by_markers(skin, s.markers_moved, MarkerSkinStage::full), s.rest_moved), 1e-6);
  MarkerSkinOptions trusting = exact();
  trusting.outlier_factor = 0;
  const MarkerSkin all = build_marker_skin(s.rest, s.markers, s.vertex_weights, s.marker_weights, trusting);
  EXPECT_GT(max_error(deform_by_markers(all, s.markers_moved, MarkerSkinStage::full), s.rest_moved), 10.0);
}

// Samples the cleaning filled, each off by a known 25 mm, with the outlier test off (most bad fills
// are within its reach on the captures): trusted, the fits and the RBF carry their error into the
// skin; with a low confidence the fits lean on the seen markers and the RBF leaves them out.
TEST(MarkerSkin, LowConfidenceInFilledMarkersKeepsTheirErrorOutOfTheSkin) {
  TwoParts s = two_parts();
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0, 1);
  Eigen::VectorXd confidence = Eigen::VectorXd::Ones(s.markers.rows());
  for (int i = 3; i < s.markers.rows(); i += 7) {  // 9 of the 60 markers
    const Eigen::RowVector3d dir = Eigen::RowVector3d(n(rng), n(rng), n(rng)).normalized();
    s.markers_moved.row(i) += 25 * dir;
    confidence(i) = 0.01;  // below rbf_min_confidence: left out of the RBF
  }
  MarkerSkinOptions o = exact();
  o.outlier_factor = 0;
  const MarkerSkin skin = build_marker_skin(s.rest, s.markers, s.vertex_weights, s.marker_weights, o);
  auto mean_error = [&](const Eigen::MatrixX3d& V) { return (V - s.rest_moved).rowwise().norm().mean(); };
  const double trusted = mean_error(deform_by_markers(skin, s.markers_moved));
  const double weighed = mean_error(deform_by_markers(skin, s.markers_moved, MarkerSkinStage::full, confidence));
  EXPECT_GT(trusted, 2.0) << "the filled samples' error reaches the skin when trusted";
  EXPECT_LT(weighed, 0.25 * trusted);
  EXPECT_LT(weighed, 1.0);
  // Every confidence 1 is the paper's method, exactly.
  EXPECT_EQ(deform_by_markers(skin, s.markers_moved, MarkerSkinStage::full, Eigen::VectorXd::Ones(s.markers.rows())),
            deform_by_markers(skin, s.markers_moved));
  Eigen::VectorXd bad = confidence;
  bad(4) = 0;
  EXPECT_THROW(deform_by_markers(skin, s.markers_moved, MarkerSkinStage::full, bad), InputError);
  EXPECT_THROW(deform_by_markers(skin, s.markers_moved, MarkerSkinStage::full, confidence.head(10)), InputError);
}

TEST(MarkerSkin, FilledSampleConfidenceHalvesWithTheFramesFromASeenSample) {
  MarkerData d;
  d.rate = 120;
  d.labels = {"A", "B"};
  d.xyz = Eigen::MatrixXd::Zero(20, 6);
  // A: frames 5-9 filled (seen at 4 and 10); B: frames 15-19 (to the end: only frame 14 bounds it).
  const Eigen::MatrixXd c = filled_sample_confidence(d, {{"A", 5, 9}, {"B", 15, 19}}, 0.2, 2);
  const double expected_a[] = {0.2, 0.2 / std::sqrt(2.0), 0.1, 0.2 / std::sqrt(2.0), 0.2};
  for (int f = 0; f < 20; ++f) {
    EXPECT_NEAR(c(f, 0), f >= 5 && f <= 9 ? expected_a[f - 5] : 1.0, 1e-12) << f;
    EXPECT_NEAR(c(f, 1), f >= 15 ? 0.2 * std::exp2(-(f - 15) / 2.0) : 1.0, 1e-12) << f;
  }
  auto refusal = [&](const std::vector<GapRecord>& gaps, double w = 0.1, double h = 10) {
    try {
      filled_sample_confidence(d, gaps, w, h);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(refusal({{"C", 3, 4}}).find("gap of marker 'C'"), std::string::npos);
  EXPECT_NE(refusal({{"A", 18, 20}}).find("not within the capture's 20 frames"), std::string::npos);
  EXPECT_NE(refusal({{"A", 6, 5}}).find("over frames 6-5"), std::string::npos);
  EXPECT_NE(refusal({}, 0).find("weight"), std::string::npos);
  EXPECT_NE(refusal({}, 0.1, 0).find("half-life"), std::string::npos);
}

TEST(MarkerSkin, RadialBasisResidualInterpolatesTheMarkersExactly) {
  const Eigen::MatrixX3d ref = random_points(50, {-150, -150, -150}, {150, 150, 150}, 4);
  Eigen::MatrixX3d now = ref;
  for (Eigen::Index i = 0; i < ref.rows(); ++i)  // a motion no quadratic follows
    now.row(i) += 15 * Eigen::RowVector3d(std::sin(ref(i, 1) / 40), std::cos(ref(i, 2) / 30), std::sin(ref(i, 0) / 25));
  const Eigen::MatrixXd ones = Eigen::MatrixXd::Ones(ref.rows(), 1);
  MarkerSkinOptions o = exact();
  o.outlier_factor = 0;  // every member is interpolated
  const MarkerSkin skin = build_marker_skin(ref, ref, ones, ones, o);  // the mesh's vertices are the markers
  EXPECT_LT(max_error(deform_by_markers(skin, now, MarkerSkinStage::full), now), 1e-8);
  EXPECT_GT(max_error(deform_by_markers(skin, now, MarkerSkinStage::quadratic), now), 1.0);
  EXPECT_DOUBLE_EQ(cubic_bspline(0), 2.0 / 3);
  EXPECT_DOUBLE_EQ(cubic_bspline(2.5), 0.0);
}

TEST(MarkerSkin, RefusesBadWeightsAndMarkerCounts) {
  const TwoParts s = two_parts();
  Eigen::MatrixXd bad = s.vertex_weights;
  bad(3, 0) = -1;
  EXPECT_THROW(build_marker_skin(s.rest, s.markers, bad, s.marker_weights), InputError);
  bad = s.vertex_weights;
  bad.row(5).setZero();
  EXPECT_THROW(build_marker_skin(s.rest, s.markers, bad, s.marker_weights), InputError);
  const MarkerSkin skin = build_marker_skin(s.rest, s.markers, s.vertex_weights, s.marker_weights);
  EXPECT_THROW(deform_by_markers(skin, s.markers.topRows(10)), InputError);
}

// A small mesh sequence (a box of 8 vertices, 12 triangles, scaled) and its corners as markers.
struct Sequence {
  std::vector<Eigen::MatrixX3d> meshes;
  Eigen::MatrixX3i F;
  MarkerData markers;
};

Sequence box_sequence(int meshes, int frames) {
  Sequence s;
  Eigen::MatrixX3d V(8, 3);
  for (int i = 0; i < 8; ++i) V.row(i) << 100.0 * (i & 1), 100.0 * ((i >> 1) & 1), 100.0 * ((i >> 2) & 1);
  s.F.resize(12, 3);
  s.F << 0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5;
  for (int k = 0; k < meshes; ++k) s.meshes.push_back(V * (1 + 0.01 * k));
  s.markers.rate = 120;
  for (int i = 0; i < 8; ++i) s.markers.labels.push_back("M" + std::to_string(i));
  s.markers.xyz.resize(frames, 24);
  for (int f = 0; f < frames; ++f)
    for (int i = 0; i < 8; ++i) s.markers.set(f, i, V.row(i).transpose());
  return s;
}

std::string refusal(const Sequence& s, MarkerDeformOptions o = {}) {
  o.mesh_rate = 10;
  o.parts = 2;
  try {
    compare_marker_skins(s.meshes, s.F, s.markers, o);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(MarkerDeform, RefusesBadInputWithOneLine) {
  Sequence s = box_sequence(4, 37);  // 4 meshes at 10 fps make 37 frames at 120 Hz
  s.markers.xyz.conservativeResize(30, 24);
  EXPECT_NE(refusal(s).find("the capture has 30 frames but 4 meshes"), std::string::npos) << refusal(s);
  s = box_sequence(4, 37);
  s.markers.labels[2] = "*7";
  EXPECT_NE(refusal(s).find("unlabelled piece '*7'"), std::string::npos) << refusal(s);
  s = box_sequence(4, 37);
  s.markers.clear(5, 3);
  EXPECT_NE(refusal(s).find("'M3' is missing at frame 6"), std::string::npos) << refusal(s);
  s = box_sequence(4, 37);
  for (int f = 0; f < 37; ++f) s.markers.set(f, 6, s.markers.at(f, 6) * 1000);  // in another unit
  EXPECT_NE(refusal(s).find("marker 'M6' is"), std::string::npos) << refusal(s);
  s = box_sequence(4, 37);
  s.markers.rate = 125;
  EXPECT_NE(refusal(s).find("whole multiple"), std::string::npos) << refusal(s);
  for (const std::string& m : {refusal(s)}) EXPECT_EQ(m.find('\n'), std::string::npos);
  s = box_sequence(4, 37);
  MarkerDeformOptions zero;
  zero.mesh_rate = 0;
  EXPECT_THROW(compare_marker_skins(s.meshes, s.F, s.markers, zero), InputError);
}

}  // namespace
}  // namespace bodymodel
