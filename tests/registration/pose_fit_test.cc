#include "registration/pose_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "core/error.h"
#include "core/geometry.h"
#include "core/makehuman.h"
#include "core/rotation.h"
#include "registration/metrics.h"
#include "registration/fixtures.h"

namespace bodymodel {
namespace {

using test::rot;

// Three-bone limb posed with a known global motion, scale and joint rotations: the fit must
// recover them from a dense scan.
TEST(PoseFit, RecoversKnownLimbPose) {
  test::Limb limb = test::limb();
  Pose truth = Pose::rest(3);
  truth.rotations[0] = rot(20, {0, 0, 1});
  truth.rotations[1] = rot(35, {1, 0, 0.3});
  truth.rotations[2] = rot(-25, {0, 0, 1});
  truth.root_translation = {15, -10, 5};
  const double true_scale = 1.08;
  Mesh posed = limb.mesh;
  posed.V = pose_template(limb.mesh.V, limb.skeleton, limb.weights, true_scale, truth);
  PointCloud scan = test::scan_of(posed, 20000, 5, 0.5);

  PoseFitOptions o;
  o.free_bones = {"lower", "hand"};
  PoseFitSummary summary;
  PoseFitResult r = fit_pose(limb.mesh, limb.skeleton, limb.weights, scan, {}, o, &summary);
  std::printf("limb: %d ICP iterations, %.2f s, rms %.3f mm, scale %.4f\n",
              summary.icp_iterations, summary.seconds, summary.rms, r.scale);
  // Bone directions are what a tube determines (a twist about its own axis is invisible).
  auto Qt = world_rotations(limb.skeleton, truth), Qe = world_rotations(limb.skeleton, r.pose);
  const Eigen::Vector3d axis(0, 1, 0);
  for (int b = 0; b < 3; ++b) {
    const double c = (Qe[b] * axis).dot(Qt[b] * axis);
    EXPECT_LT(std::acos(std::clamp(c, -1.0, 1.0)) * 180 / M_PI, 1.0) << limb.skeleton.names[b];
  }
  EXPECT_NEAR(r.scale, true_scale, 0.01);
  // Surface fit (distance to the true surface along its normal; twist slides along it).
  Eigen::MatrixX3d N = vertex_normals(posed.V, posed.F);
  double normal_error = 0;
  for (Eigen::Index i = 0; i < posed.V.rows(); ++i)
    normal_error += std::abs((r.V.row(i) - posed.V.row(i)).dot(N.row(i)));
  EXPECT_LT(normal_error / posed.V.rows(), 1.0);
  EXPECT_LT(summary.rms, 3.0);  // closest-sample distance of a ~3 mm spaced scan
}

// The MakeHuman template posed with a known pose of the major joints (and a global motion):
// the major joints' rotations must come back within a few degrees.
TEST(PoseFit, RecoversKnownBodyPose) {
  MakeHuman mh = MakeHuman::load();
  MakeHuman::Body body = mh.body(MacroSettings{});
  const Skeleton& sk = body.skeleton;
  Pose truth = Pose::rest(sk.bone_count());
  truth.rotations[0] = rot(15, {0, 1, 0});
  truth.root_translation = {40, 10, -30};
  const std::vector<std::pair<std::string, Eigen::Matrix3d>> joints = {
      {"upperarm01.L", rot(-40, {0, 0, 1})}, {"upperarm01.R", rot(30, {1, 0, 0.5})},
      {"lowerarm01.L", rot(45, {0, 1, 0.4})}, {"upperleg01.R", rot(-25, {1, 0, 0})},
      {"lowerleg01.R", rot(30, {1, 0, 0})},   {"spine03", rot(10, {1, 0, 0})},
      {"neck01", rot(15, {0, 1, 0})},         {"upperleg01.L", rot(12, {0, 0, 1})}};
  for (const auto& [name, R] : joints) truth.rotations[sk.index(name)] = R;
  const double true_scale = 0.95;
  Mesh posed = body.mesh;
  posed.V = pose_template(body.mesh.V, sk, body.weights, true_scale, truth);
  PointCloud scan = test::scan_of(posed, 50000, 11, 1.0);

  // Landmarks as a scan database supplies them: the vertex most bound to each of a dozen bones.
  std::vector<Landmark> landmarks;
  for (const char* name : {"head", "wrist.L", "wrist.R", "foot.L", "foot.R", "lowerarm01.L",
                           "lowerarm01.R", "lowerleg01.L", "lowerleg01.R", "spine03",
                           "upperleg02.L", "upperleg02.R"}) {
    const int b = sk.index(name);
    int best = -1;
    double best_w = 0;
    for (int k = 0; k < body.weights.outerSize(); ++k)
      for (SkinWeights::InnerIterator it(body.weights, k); it; ++it)
        if (it.col() == b && it.value() > best_w) best_w = it.value(), best = int(it.row());
    ASSERT_GE(best, 0) << name;
    landmarks.push_back({best, posed.V.row(best).transpose(), name});
  }
  PoseFitSummary summary;
  PoseFitResult r =
      fit_pose(body.mesh, sk, body.weights, scan, landmarks, PoseFitOptions{}, &summary);
  auto Qt = world_rotations(sk, truth), Qe = world_rotations(sk, r.pose);
  std::vector<double> errors;
  // World orientation of each segment's distal bone (the split of a rotation between the two
  // bones of a segment is not observable).
  for (const std::string& name : major_joints()) {
    const int b = sk.index(name);
    errors.push_back(rotation_angle_deg(Qe[b], Qt[b]));
    std::printf("  %-14s %.2f°\n", name.c_str(), errors.back());
  }
  std::sort(errors.begin(), errors.end());
  const double vertex_error = (r.V - posed.V).rowwise().norm().mean();
  std::printf("body: %d ICP iterations, %.2f s, rms %.3f mm, scale %.4f, vertex error %.2f mm\n",
              summary.icp_iterations, summary.seconds, summary.rms, r.scale, vertex_error);
  EXPECT_LT(errors[errors.size() / 2], 3.0);   // median of the major joints
  // The worst is a twist of an upper arm about its own axis, which a near-cylindrical arm
  // hardly shows (the vertices are within ~1 mm either way).
  EXPECT_LT(errors.back(), 25.0);
  EXPECT_NEAR(r.scale, true_scale, 0.01);
  EXPECT_LT(vertex_error, 5.0);
}

TEST(PoseFit, BadInput) {
  test::Limb limb = test::limb();
  PointCloud empty;
  EXPECT_THROW(fit_pose(limb.mesh, limb.skeleton, limb.weights, empty, {}), InputError);
  PointCloud scan = test::scan_of(limb.mesh, 2000, 1);
  PoseFitOptions o;
  o.free_bones = {"elbow_that_does_not_exist"};
  EXPECT_THROW(fit_pose(limb.mesh, limb.skeleton, limb.weights, scan, {}, o), InputError);
  // A scan 100 times too large and far away: no overlap → clear error, not a collapsed mesh.
  PointCloud far = scan;
  far.P = (far.P.array() * 100.0).matrix();
  far.P.rowwise() += Eigen::RowVector3d(1e6, 0, 0);
  PoseFitOptions fixed;
  fixed.fit_scale = false;
  fixed.free_bones = {"lower"};
  EXPECT_THROW(fit_pose(limb.mesh, limb.skeleton, limb.weights, far, {}, fixed), InputError);
}

// Options out of range are refused before any work, with the option named; the defaults and the
// hand-stage parameterisation are valid.
TEST(PoseFit, OptionsValidate) {
  PoseFitOptions o;
  EXPECT_NO_THROW(o.validate());
  o.parameters = hand_stage_pose_parameters();
  EXPECT_NO_THROW(o.validate());
  auto message = [](const PoseFitOptions& bad) {
    try {
      bad.validate();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  PoseFitOptions bad;
  bad.max_distance = -5;
  EXPECT_NE(message(bad).find("max_distance"), std::string::npos) << message(bad);
  bad = {};
  bad.trim_fraction = 1.0;
  EXPECT_NE(message(bad).find("trim_fraction"), std::string::npos) << message(bad);
  bad = {};
  bad.hand_start_margin = std::nan("");
  EXPECT_NE(message(bad).find("hand_start_margin"), std::string::npos) << message(bad);
  bad = {};
  bad.parameters = {{{"finger1-2.L"}, false, 1.0, false, false, true, true}};  // a tuck, not late
  EXPECT_NE(message(bad).find("finger1-2.L"), std::string::npos) << message(bad);
  test::Limb limb = test::limb();
  const PointCloud scan = test::scan_of(limb.mesh, 2000, 1);
  PoseFitOptions threads;
  threads.threads = 0;
  EXPECT_THROW(fit_pose(limb.mesh, limb.skeleton, limb.weights, scan, {}, threads), InputError);
}

}  // namespace
}  // namespace bodymodel
