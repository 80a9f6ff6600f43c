#include "registration/shape_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "core/error.h"
#include "core/landmarks.h"
#include "core/makehuman.h"
#include "registration/fixtures.h"
#include "registration/pose_fit.h"

namespace bodymodel {
namespace {

using test::rot;

double mean_distance(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B) {
  return (A - B).rowwise().norm().mean();
}

// A MakeHuman body with known non-default sliders, posed with a known pose and sampled as a
// noisy point cloud (with landmarks): the shape fit from the default body with that pose must
// find the sliders that carry the outline (gender, weight, height, proportions) and bring the
// posed template's vertices (correspondence error, same index) far closer than the default
// shape, which keeps the offset the registration's non-rigid stage cannot remove.
TEST(ShapeFit, RecoversMacroSlidersOfAPosedBody) {
  MakeHuman mh = MakeHuman::load();
  MacroSettings truth_s;
  truth_s.gender = 0.85;
  truth_s.age = 0.65;
  truth_s.muscle = 0.7;
  truth_s.weight = 0.75;
  truth_s.height = 0.75;
  truth_s.proportions = 0.3;
  const MakeHuman::Body truth = mh.body(truth_s);
  const Skeleton& sk = truth.skeleton;
  Pose pose = Pose::rest(sk.bone_count());
  pose.rotations[0] = rot(25, {0, 1, 0});
  pose.root_translation = {30, -20, 15};
  for (const auto& [name, R] :
       std::vector<std::pair<std::string, Eigen::Matrix3d>>{{"upperarm01.L", rot(-35, {0, 0, 1})},
                                                            {"upperarm01.R", rot(25, {1, 0, 0.5})},
                                                            {"lowerarm01.L", rot(40, {0, 1, 0.4})},
                                                            {"upperleg01.R", rot(-20, {1, 0, 0})},
                                                            {"lowerleg01.R", rot(30, {1, 0, 0})},
                                                            {"spine03", rot(8, {1, 0, 0})}})
    pose.rotations[sk.index(name)] = R;
  Mesh posed = truth.mesh;
  posed.V = pose_template(truth.mesh.V, sk, truth.weights, 1.0, pose);
  const PointCloud scan = test::scan_of(posed, 40000, 5, 1.0);
  std::vector<Landmark> landmarks;
  for (const auto& [name, v] : body_landmarks())
    landmarks.push_back({v, posed.V.row(v).transpose(), name});

  // The default body with the same joint rotations, its root placed where the truth's is (as a
  // pose fit would): the start.
  const MacroSettings start;
  const MakeHuman::Body def = mh.body(start);
  Pose start_pose = pose;
  start_pose.root_translation =
      pose.root_translation + (sk.heads.row(0) - def.skeleton.heads.row(0)).transpose();
  const Eigen::MatrixX3d V0 = pose_template(def.mesh.V, def.skeleton, def.weights, 1.0, start_pose);
  const double error_default = mean_distance(V0, posed.V);

  ShapeFitSummary sum;
  const ShapeFitResult r = fit_shape(mh, start, 1.0, start_pose, scan, landmarks, {}, &sum);
  const double error_fit = mean_distance(r.V, posed.V);
  std::printf(
      "shape fit: %d ICP iterations, %d steps, %d builds, %.2f s, plane rms %.2f -> %.2f mm; "
      "vertex error default %.2f mm -> fitted %.2f mm; sliders g %.3f a %.3f m %.3f w %.3f h "
      "%.3f p %.3f, scale %.4f\n",
      sum.icp_iterations, sum.solver_steps, sum.builds, sum.seconds, sum.rms_before,
      sum.rms_after, error_default, error_fit, r.settings.gender, r.settings.age,
      r.settings.muscle, r.settings.weight, r.settings.height, r.settings.proportions, r.scale);
  EXPECT_GT(error_default, 15.0);  // the default shape is far off: the test means something
  EXPECT_LT(error_fit, 4.0);
  EXPECT_LT(error_fit, 0.25 * error_default);
  EXPECT_NEAR(r.settings.gender, truth_s.gender, 0.1);
  EXPECT_NEAR(r.settings.weight, truth_s.weight, 0.1);
  EXPECT_NEAR(r.settings.height, truth_s.height, 0.1);
  EXPECT_NEAR(r.settings.proportions, truth_s.proportions, 0.15);
  EXPECT_NEAR(r.scale, 1.0, 0.02);
  EXPECT_LT(sum.rms_after, sum.rms_before);
  // The returned pose and body reproduce the returned vertices.
  const Eigen::MatrixX3d V = pose_template(r.body.mesh.V, r.body.skeleton, r.body.weights,
                                           r.scale, r.pose);
  EXPECT_LT((V - r.V).cwiseAbs().maxCoeff(), 1e-9);
}

// A learned space of three directions (taller, heavier, longer forearms) and the sex slider: a
// body at known coefficients, posed and sampled, is found again from the space's mean (g = 0.5),
// with the vertex error far below the mean body's, the coefficients within a few tenths of an sd
// and the gender within 0.1.
TEST(ShapeFit, RecoversCoefficientsInALearnedSpace) {
  MakeHuman mh = MakeHuman::load();
  ShapeSpace space;
  space.parameters = {"macro/gender", "macro/height", "macro/weight", "shape/armslegs/l-lowerarm-scale-vert-decr|incr",
                      "shape/armslegs/r-lowerarm-scale-vert-decr|incr"};
  ASSERT_GE(mh.shape_modifier_index("armslegs/l-lowerarm-scale-vert-decr|incr"), 0);
  space.mean = (Eigen::VectorXd(5) << 0.0, 0.5, 0.5, 0.0, 0.0).finished();
  space.sex_direction = (Eigen::VectorXd(5) << 1.0, 0.0, 0.0, 0.0, 0.0).finished();
  space.basis = Eigen::MatrixXd::Zero(5, 3);
  space.basis(1, 0) = 1;
  space.basis(2, 1) = 1;
  space.basis(3, 2) = space.basis(4, 2) = std::sqrt(0.5);
  space.sd = (Eigen::VectorXd(3) << 0.15, 0.15, 1.0).finished();
  space.validate(mh, "test space");
  const Eigen::Vector4d c_true(1.5, -1.0, 0.9, 0.2);
  const MakeHuman::Body truth = shape_space_body(mh, space, c_true);
  const Skeleton& sk = truth.skeleton;
  Pose pose = Pose::rest(sk.bone_count());
  pose.rotations[0] = rot(20, {0, 1, 0});
  pose.rotations[sk.index("upperarm01.L")] = rot(-30, {0, 0, 1});
  pose.rotations[sk.index("lowerleg01.R")] = rot(25, {1, 0, 0});
  Mesh posed = truth.mesh;
  posed.V = pose_template(truth.mesh.V, sk, truth.weights, 1.0, pose);
  const PointCloud scan = test::scan_of(posed, 40000, 5, 1.0);
  std::vector<Landmark> landmarks;
  for (const auto& [name, v] : body_landmarks()) landmarks.push_back({v, posed.V.row(v).transpose(), name});

  const MakeHuman::Body mean = shape_space_body(mh, space, Eigen::VectorXd());
  Pose start_pose = pose;
  start_pose.root_translation = pose.root_translation + (sk.heads.row(0) - mean.skeleton.heads.row(0)).transpose();
  const Eigen::MatrixX3d V0 = pose_template(mean.mesh.V, mean.skeleton, mean.weights, 1.0, start_pose);
  ShapeFitOptions o;
  o.space = &space;
  o.space_prior_weight = 0.1;
  ShapeFitSummary sum;
  const ShapeFitResult r = fit_shape_in_space(mh, Eigen::VectorXd(), 1.0, start_pose, scan, landmarks, o, &sum);
  const double e0 = mean_distance(V0, posed.V), e1 = mean_distance(r.V, posed.V);
  std::printf("space fit: %d ICP iterations, %d builds; vertex error %.2f -> %.2f mm; c = %.2f %.2f %.2f, g %.2f\n",
              sum.icp_iterations, sum.builds, e0, e1, r.coefficients[0], r.coefficients[1], r.coefficients[2],
              r.coefficients[3]);
  ASSERT_EQ(r.coefficients.size(), 4);
  EXPECT_NEAR(r.coefficients[3], c_true[3], 0.1);
  EXPECT_NEAR(r.settings.gender, c_true[3], 0.1);
  EXPECT_GT(e0, 10.0);
  EXPECT_LT(e1, 0.2 * e0);
  EXPECT_NEAR(r.coefficients[0], c_true[0], 0.3);
  EXPECT_NEAR(r.coefficients[1], c_true[1], 0.3);
  EXPECT_NEAR(r.coefficients[2], c_true[2], 0.25);
  EXPECT_NEAR(r.settings.height, 0.5 + 0.15 * c_true[0], 0.05);
  // Wrong start size or no space: clear errors.
  EXPECT_THROW(fit_shape_in_space(mh, Eigen::VectorXd::Zero(2), 1.0, start_pose, scan, landmarks, o), InputError);
  EXPECT_THROW(fit_shape_in_space(mh, Eigen::VectorXd(), 1.0, start_pose, scan, landmarks, ShapeFitOptions{}),
               InputError);
}

TEST(ShapeFit, RejectsBadInput) {
  MakeHuman mh = MakeHuman::load();
  const MakeHuman::Body def = mh.body(MacroSettings{});
  const Pose pose = Pose::rest(def.skeleton.bone_count());
  PointCloud empty;
  EXPECT_THROW(fit_shape(mh, MacroSettings{}, 1.0, pose, empty, {}), InputError);
  const PointCloud scan = test::scan_of(def.mesh, 2000, 1);
  EXPECT_THROW(fit_shape(mh, MacroSettings{}, 0.0, pose, scan, {}), InputError);
  ShapeFitOptions o;
  o.sliders = {"gender", "wingspan"};
  EXPECT_THROW(fit_shape(mh, MacroSettings{}, 1.0, pose, scan, {}, o), InputError);
  EXPECT_THROW(fit_shape(mh, MacroSettings{}, 1.0, pose, scan, {{20000, {0, 0, 0}, "x"}}),
               InputError);
}

}  // namespace
}  // namespace bodymodel
