#include "core/shape_space.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/shape_space_file.h"
#include "makehuman_fixture.h"

namespace bodymodel {
namespace {

// Bodies spread along two known directions with known spreads (3 and 1) plus tiny noise: the
// PCA finds both directions, their standard deviations and nearly all the variance.
TEST(ShapeSpace, LearnsKnownDirectionsAndSpreads) {
  const int P = 6, N = 4000;
  Eigen::VectorXd u = Eigen::VectorXd::Zero(P), v = Eigen::VectorXd::Zero(P), mean(P);
  u << 1, 1, 0, 0, 0, 0;
  u.normalize();
  v << 0, 0, 1, -1, 1, 0;
  v.normalize();
  mean << 0.5, 0.4, 0.3, 0.2, 0.1, 0.0;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0, 1);
  Eigen::MatrixXd X(N, P);
  for (int i = 0; i < N; ++i) {
    X.row(i) = (mean + 3 * g(rng) * u + 1 * g(rng) * v).transpose();
    for (int k = 0; k < P; ++k) X(i, k) += 0.01 * g(rng);
  }
  const std::vector<std::string> names = {"a", "b", "c", "d", "e", "f"};
  const ShapeSpace s = learn_shape_space(names, X, 2, "test");
  ASSERT_EQ(s.components(), 2);
  EXPECT_NEAR(std::abs(s.basis.col(0).dot(u)), 1.0, 1e-3);
  EXPECT_NEAR(std::abs(s.basis.col(1).dot(v)), 1.0, 1e-3);
  EXPECT_NEAR(s.sd[0], 3.0, 0.1);
  EXPECT_NEAR(s.sd[1], 1.0, 0.04);
  EXPECT_GT(s.explained, 0.999);
  EXPECT_LT((s.mean - mean).cwiseAbs().maxCoeff(), 0.15);
  EXPECT_THROW(learn_shape_space(names, X.topRows(1), 2, "x"), InputError);
  EXPECT_THROW(learn_shape_space({"a"}, X, 2, "x"), InputError);
}

// Two populations whose means differ and whose spread is along one direction within each: the
// sex direction is the difference of the means and the one component is the within-sex
// direction, which a pooled PCA would have mixed with the difference.
TEST(ShapeSpace, KeepsTheSexesApart) {
  const int N = 2000;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0, 1);
  Eigen::Vector3d mf(0, 0.2, 0.4), mm(1, 0.6, 0.4), within(0, 0, 1);
  Eigen::MatrixXd X(N, 3);
  std::vector<int> male(N);
  for (int i = 0; i < N; ++i) {
    male[i] = i % 2;
    X.row(i) = ((male[i] ? mm : mf) + 0.5 * g(rng) * within).transpose();
  }
  const ShapeSpace s = learn_shape_space({"macro/gender", "macro/height", "macro/weight"}, X, 2, "test", male);
  ASSERT_TRUE(s.has_sex());
  EXPECT_LT((s.mean - mf).norm(), 0.05);
  EXPECT_LT((s.sex_direction - (mm - mf)).norm(), 0.05);
  ASSERT_EQ(s.components(), 1);  // within each sex the bodies vary along one direction only
  EXPECT_NEAR(std::abs(s.basis.col(0).dot(within)), 1.0, 1e-6);
  EXPECT_NEAR(s.sd[0], 0.5, 0.03);
  EXPECT_EQ(s.dimension(), 2);
  const MakeHuman& mh = shared_makehuman();
  const ShapeParameters man = shape_space_parameters(mh, s, Eigen::Vector2d(0.0, 1.0));
  EXPECT_NEAR(man.macros.gender, 1.0, 0.05);
  EXPECT_NEAR(man.macros.height, 0.6, 0.05);
  EXPECT_THROW(learn_shape_space({"a", "b", "c"}, X, 2, "test", std::vector<int>(3, 1)), InputError);
}

// The file keeps every number; a file of another kind is refused naming the file.
TEST(ShapeSpace, FileRoundTripAndBadFiles) {
  ShapeSpace s;
  s.parameters = {"macro/height", "macro/weight", "measure/measure-neck-circ-decr|incr"};
  s.mean = Eigen::Vector3d(0.5, 0.6, -0.1);
  s.basis = Eigen::MatrixXd::Identity(3, 2);
  s.sd = Eigen::Vector2d(0.1, 0.2);
  s.explained = 0.9;
  s.people = 7;
  s.source = "test";
  const auto dir = std::filesystem::temp_directory_path() / "bodymodel_shape_space_test";
  std::filesystem::create_directories(dir);
  write_text_file(dir / "s.json", shape_space_json(s));
  const ShapeSpace r = read_shape_space(dir / "s.json");
  EXPECT_EQ(r.parameters, s.parameters);
  EXPECT_EQ((r.mean - s.mean).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((r.basis - s.basis).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((r.sd - s.sd).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(r.people, 7);
  write_text_file(dir / "bad.json", "{\"format\": \"something-else\"}");
  try {
    read_shape_space(dir / "bad.json");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.json"), std::string::npos) << e.what();
  }
  write_text_file(dir / "short.json", "{\"format\": \"bodymodel-shape-space\", \"version\": 1, \"parameters\": [\"macro/height\"], "
                                      "\"mean\": [0.5], \"sd\": [0.1, 0.2], \"basis\": [[1]]}");
  EXPECT_THROW(read_shape_space(dir / "short.json"), InputError);
  std::filesystem::remove_all(dir);
}

// The body of a space is MakeHuman's body of its parameters: one component along the height
// slider gives exactly the body with that slider moved by c·sd; unknown names are refused.
TEST(ShapeSpace, BodyIsMakeHumansBodyOfTheParameters) {
  const MakeHuman& mh = shared_makehuman();
  ShapeSpace s;
  s.parameters = {"macro/gender", "macro/height"};
  s.mean = Eigen::Vector2d(1.0, 0.5);
  s.basis = (Eigen::MatrixXd(2, 1) << 0, 1).finished();
  s.sd = Eigen::VectorXd::Constant(1, 0.1);
  s.validate(mh, "test");
  MacroSettings m;
  m.gender = 1.0;
  m.height = 0.7;
  const Eigen::MatrixX3d expect = mh.body(m).mesh.V;
  const MakeHuman::Body b = shape_space_body(mh, s, Eigen::VectorXd::Constant(1, 2.0));
  EXPECT_LT((b.mesh.V - expect).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_EQ(shape_space_parameter_names(mh).size(),
            8 + mh.measure_modifier_names().size() + mh.shape_modifiers().size());
  s.parameters[1] = "macro/wingspan";
  EXPECT_THROW(s.validate(mh, "test"), InputError);
  EXPECT_THROW(shape_space_body(mh, s, Eigen::VectorXd::Constant(2, 0.0)), InputError);
}

}  // namespace
}  // namespace bodymodel
