// The registration's shape fit in a built model's shape space (`register --model`,
// model/model_shape_space.h): a small model of MakeHuman bodies, linearised at its mean; a body
// decoded EXACTLY from known coefficients (so the linearisation's own error is part of the test),
// posed and sampled, is found again by the shape fit from the model's mean body.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/geometry.h"
#include "core/landmarks.h"
#include "core/makehuman.h"
#include "encoding/relative_rotation_decoder.h"
#include "model/body_model.h"
#include "model/model_shape_space.h"
#include "registration/fixtures.h"
#include "registration/pose_fit.h"
#include "registration/shape_fit.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {

// Eight rest-pose MakeHuman bodies of different height, weight and sex: the shape model.
BodyModel small_shape_model(const MakeHuman& mh) {
  ModelBuildInput in;
  in.F = mh.body_faces();
  const double sliders[8][3] = {{0.1, 0.3, 0.2}, {0.9, 0.7, 0.8}, {0.2, 0.8, 0.6}, {0.8, 0.2, 0.3},
                                {0.5, 0.5, 0.9}, {0.4, 0.9, 0.1}, {0.7, 0.4, 0.5}, {0.3, 0.1, 0.7}};
  for (int s = 0; s < 8; ++s) {
    MacroSettings m;
    // Within 0.2 of the middle: a population, not MakeHuman's extremes (the approximation is local).
    m.gender = 0.3 + 0.4 * sliders[s][0], m.height = 0.3 + 0.4 * sliders[s][1], m.weight = 0.3 + 0.4 * sliders[s][2];
    in.meshes.push_back(mh.body(m).mesh.V);
    in.scan_ids.push_back(fmt::format("s{}", s));
    in.subject_ids.push_back(fmt::format("s{}", s));
    in.is_standard_pose.push_back(1);
  }
  in.subject_label_values.resize(8, 0);
  in.pose_label_values.resize(8, 0);
  return build_body_model(in);
}

TEST(ModelShapeSpace, ShapeFitRecoversCoefficientsOfADecodedBody) {
  const MakeHuman mh = MakeHuman::load();
  const BodyModel model = small_shape_model(mh);
  ASSERT_GE(model.shape.component_count(), 3);
  ModelShapeSpaceOptions mo;
  mo.components = 3;
  mo.frame = mh.body(MacroSettings{}).mesh.V;
  mo.measure_error = true;
  ModelShapeSpaceSummary ms;
  const VertexShapeSpace space = model_shape_space(model, mo, &ms);
  std::printf("approximated: %d components, %d decodes, %.1f s; at ±2 sd (largest move %.1f mm) second order mean "
              "%.3f mm, max %.3f mm (component %d); linear mean %.3f, max %.3f mm\n",
              ms.components, ms.decodes, ms.seconds, ms.max_displacement_mm, ms.mean_error_mm, ms.max_error_mm,
              ms.worst_component, ms.mean_error_linear_mm, ms.max_error_linear_mm);
  ASSERT_EQ(space.components(), 3);
  EXPECT_GT(ms.max_error_mm, 0.0);  // measured, not assumed
  EXPECT_LT(ms.mean_error_mm, ms.mean_error_linear_mm);
  EXPECT_LT(ms.max_error_mm, 0.1 * ms.max_displacement_mm);
  // The mean body sits in MakeHuman's frame: near the default body.
  EXPECT_LT((space.mean - mo.frame).rowwise().norm().mean(), 40.0);

  // The truth: decoded exactly at known coefficients, placed on the linear body of them.
  const Eigen::Vector3d c_true(1.5, -1.0, 0.8);
  Eigen::VectorXd x = model.shape.pca.mean;
  for (int k = 0; k < 3; ++k) x += c_true[k] * std::sqrt(model.shape.pca.eigenvalues[k]) * model.shape.pca.basis.col(k);
  Eigen::MatrixX3d exact = RelativeRotationDecoder(model.tmpl).decode(model.encoding_of(x));
  const MakeHuman::Body linear = vertex_space_body(mh, space, c_true);
  exact = apply(fit_rigid_motion(exact, linear.mesh.V), exact);
  const Skeleton sk = mh.skeleton_from_body(exact);
  Pose pose = Pose::rest(sk.bone_count());
  pose.rotations[0] = test::rot(20, {0, 1, 0});
  pose.rotations[sk.index("upperarm01.L")] = test::rot(-30, {0, 0, 1});
  pose.rotations[sk.index("lowerleg01.R")] = test::rot(25, {1, 0, 0});
  Mesh posed{pose_template(exact, sk, mh.body_weights(), 1.0, pose), mh.body_faces()};
  const PointCloud scan = test::scan_of(posed, 40000, 5, 1.0);
  std::vector<Landmark> landmarks;
  for (const auto& [name, v] : body_landmarks()) landmarks.push_back({v, posed.V.row(v).transpose(), name});

  const MakeHuman::Body mean = vertex_space_body(mh, space, Eigen::VectorXd());
  Pose start_pose = pose;
  start_pose.root_translation = pose.root_translation + (sk.heads.row(0) - mean.skeleton.heads.row(0)).transpose();
  const Eigen::MatrixX3d V0 = pose_template(mean.mesh.V, mean.skeleton, mean.weights, 1.0, start_pose);
  ShapeFitOptions o;
  o.vertex_space = &space;
  o.space_prior_weight = 0.1;
  ShapeFitSummary sum;
  const ShapeFitResult r = fit_shape_in_space(mh, Eigen::VectorXd(), 1.0, start_pose, scan, landmarks, o, &sum);
  const double e0 = (V0 - posed.V).rowwise().norm().mean(), e1 = (r.V - posed.V).rowwise().norm().mean();
  std::printf("model-space fit: %d ICP iterations, %d builds; vertex error %.2f -> %.2f mm; c = %.2f %.2f %.2f\n",
              sum.icp_iterations, sum.builds, e0, e1, r.coefficients[0], r.coefficients[1], r.coefficients[2]);
  ASSERT_EQ(r.coefficients.size(), 3);
  EXPECT_GT(e0, 10.0);
  EXPECT_LT(e1, 0.1 * e0);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(r.coefficients[k], c_true[k], 0.15) << "component " << k;
  // Both spaces, a wrong start size: clear errors.
  ShapeFitOptions both = o;
  ShapeSpace learned;
  both.space = &learned;
  EXPECT_THROW(fit_shape_in_space(mh, Eigen::VectorXd(), 1.0, start_pose, scan, landmarks, both), InputError);
  EXPECT_THROW(fit_shape_in_space(mh, Eigen::VectorXd::Zero(2), 1.0, start_pose, scan, landmarks, o), InputError);
}

// A file that is not a model: one line naming the option and the file, exit 2, nothing written.
TEST(ModelShapeSpace, RegisterRefusesABadModelFile) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / fmt::format("bm_bad_model_{}", ::getpid());
  fs::create_directories(dir);
  std::ofstream(dir / "bad.npz") << "not a model\n";
  std::ofstream(dir / "lm.json") << "{}\n";
  std::ofstream(dir / "m.off") << "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  const fs::path out = dir / "out";
  const fixtures::CliResult r = fixtures::run_cli(fmt::format("register-mesh '{}' --landmarks '{}' --model '{}' --out '{}'",
                                                              (dir / "m.off").string(), (dir / "lm.json").string(),
                                                              (dir / "bad.npz").string(), out.string()));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--model"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("bad.npz"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_FALSE(fs::exists(out));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bodymodel
