// .tgf / .dmat / .Tmat readers: generated files, the real format samples, and bad input.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/libigl_formats.h"
#include "support/fixtures.h"

namespace bodymodel {
namespace {

// One folder per test process, removed when the process exits.
std::filesystem::path temp_dir() {
  static const fixtures::TempDir d;
  return d.path;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(LibiglFormats, DmatRoundTripsAsciiAndBinary) {
  const auto d = temp_dir();
  Eigen::MatrixXd M(3, 2);
  M << 1, -2.5, 3e-7, 4, 5, 6.125;
  write_dmat(d / "a.dmat", M, true);
  write_dmat(d / "b.dmat", M, false);
  EXPECT_EQ((read_dmat(d / "a.dmat") - M).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((read_dmat(d / "b.dmat") - M).cwiseAbs().maxCoeff(), 0.0);
  // ASCII is column-major with the column count first.
  write_text_file(d / "c.dmat", "2 3\n1 2 3\n4 5 6\n");
  const Eigen::MatrixXd C = read_dmat(d / "c.dmat");
  ASSERT_EQ(C.rows(), 3);
  EXPECT_EQ(C(0, 1), 4);
  EXPECT_EQ(C(2, 0), 3);
}

TEST(LibiglFormats, DmatBadInputNamesFileAndLine) {
  const auto d = temp_dir();
  write_text_file(d / "short.dmat", "2 3\n1 2 3\n4 5\n");
  EXPECT_NE(error_of([&] { read_dmat(d / "short.dmat"); }).find("promises 6 values"), std::string::npos);
  write_text_file(d / "word.dmat", "1 2\n1\nabc\n");
  const std::string e = error_of([&] { read_dmat(d / "word.dmat"); });
  EXPECT_NE(e.find("word.dmat:3"), std::string::npos) << e;
  write_text_file(d / "nan.dmat", "1 1\nnan\n");
  EXPECT_NE(error_of([&] { read_dmat(d / "nan.dmat"); }).find("not finite"), std::string::npos);
  write_text_file(d / "trunc.dmat", std::string("0 0\n2 2\n") + std::string(20, '\0'));
  EXPECT_NE(error_of([&] { read_dmat(d / "trunc.dmat"); }).find("rows is larger than the file"), std::string::npos);
}

TEST(LibiglFormats, TgfReadsJointsAndEdgesAndRejectsBadIndices) {
  const auto d = temp_dir();
  write_text_file(d / "s.tgf", "1 0 0 0 9 9\n2\t1 0 0\n3 2 0 0\n#\n1 2 1 0 0\n   2 \t3\n#\n");
  const TgfGraph g = read_tgf(d / "s.tgf");
  ASSERT_EQ(g.C.rows(), 3);
  ASSERT_EQ(g.E.rows(), 2);
  EXPECT_EQ(g.E(1, 0), 1);
  EXPECT_EQ(g.E(1, 1), 2);
  EXPECT_EQ(g.C(2, 0), 2);
  write_text_file(d / "bad.tgf", "1 0 0 0\n2 1 0 0\n#\n1 5\n#\n");
  const std::string e = error_of([&] { read_tgf(d / "bad.tgf"); });
  EXPECT_NE(e.find("bad.tgf:4"), std::string::npos) << e;
  EXPECT_NE(e.find("out of range"), std::string::npos) << e;
}

TEST(LibiglFormats, RealFormatSamples) {
  const auto cyl = data_file("animations/_format-samples/hyperspectral-cylinder");
  const TgfGraph g = read_tgf(cyl / "cylinder.tgf");
  EXPECT_EQ(g.E.rows(), 4);
  EXPECT_EQ(g.E(2, 0), 0);   // edge "1 4" → 0, 3
  EXPECT_EQ(g.E(2, 1), 3);
  const BoneTransforms T = read_tmat(cyl / "cylinder-1.Tmat");
  ASSERT_EQ(T.size(), 4u);
  EXPECT_LT((T[0].matrix() - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff(), 1e-6);
  const TgfGraph arm = read_tgf(data_file("animations/arm-rig/arm.tgf"));
  EXPECT_EQ(arm.C.rows(), 5);
  EXPECT_EQ(arm.E.rows(), 4);
  const Eigen::MatrixXd W = read_dmat(data_file("animations/arm-rig/arm-weights.dmat"));
  EXPECT_EQ(W.rows(), 8311);
  EXPECT_EQ(W.cols(), 4);
  EXPECT_LT((W.rowwise().sum().array() - 1).abs().maxCoeff(), 1e-6);
}

TEST(LibiglFormats, StackedTransformsRoundTrip) {
  BoneTransforms M(2, Eigen::Affine3d::Identity());
  M[1].linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  M[1].translation() << 1, 2, 3;
  const BoneTransforms back = bone_transforms_from_stacked(stacked_from_bone_transforms(M), "test");
  EXPECT_LT((back[1].matrix() - M[1].matrix()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_THROW(bone_transforms_from_stacked(Eigen::MatrixXd::Zero(5, 3), "test"), InputError);
}

}  // namespace
}  // namespace bodymodel
