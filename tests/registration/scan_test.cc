#include "registration/scan.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/io/pose_csv.h"
#include "core/rotation.h"
#include "registration/fixtures.h"
#include "registration/landmarks.h"
#include "registration/metrics.h"

namespace bodymodel {
namespace {

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(PrepareScan, RejectsBadScansWithClearMessages) {
  Mesh tpl = test::potato(200.0, 3);
  PointCloud empty;
  EXPECT_NE(message_of([&] { prepare_scan(empty, tpl.V, "a.ply"); }).find("no points"),
            std::string::npos);
  PointCloud nan = test::scan_of(tpl, 2000, 1);
  nan.P(17, 1) = std::nan("");
  EXPECT_NE(message_of([&] { prepare_scan(nan, tpl.V, "a.ply"); }).find("point 17"),
            std::string::npos);
  // A scan in metres against a template in millimetres: the message suggests the unit flag.
  PointCloud metres = test::scan_of(tpl, 2000, 1);
  metres.P /= 1000.0;
  const std::string m = message_of([&] { prepare_scan(metres, tpl.V, "a.ply"); });
  EXPECT_NE(m.find("unit"), std::string::npos) << m;
}

TEST(PrepareScan, EstimatesMissingNormals) {
  Mesh tpl = test::potato(200.0, 3);
  PointCloud scan = test::scan_of(tpl, 5000, 2);
  const Eigen::MatrixX3d truth = scan.N;
  scan.N.resize(0, 3);
  ScanCheckReport r = prepare_scan(scan, tpl.V, "a.ply");
  EXPECT_TRUE(r.normals_estimated);
  ASSERT_EQ(scan.N.rows(), scan.P.rows());
  // Unoriented, but parallel to the true normals (|cos| > cos 15° for 95% of the points).
  int good = 0;
  for (Eigen::Index i = 0; i < scan.P.rows(); ++i)
    if (std::abs(scan.N.row(i).dot(truth.row(i))) > std::cos(15 * M_PI / 180)) ++good;
  EXPECT_GT(good, 0.95 * scan.P.rows());
}

TEST(Landmarks, UnknownNamesAndBadValues) {
  const auto dir = std::filesystem::temp_directory_path() / "bodymodel_reg_landmarks_test";
  std::filesystem::create_directories(dir);
  LandmarkTable table = {{"chin", 3}, {"navel", 7}};
  std::ofstream(dir / "ok.json") << R"({"chin": [1, 2, 3], "navel": [4, 5, 6]})";
  std::vector<Landmark> l = read_landmarks(dir / "ok.json", table);
  ASSERT_EQ(l.size(), 2u);
  EXPECT_EQ(l[1].vertex, 7);
  EXPECT_DOUBLE_EQ(l[1].target.z(), 6.0);
  std::ofstream(dir / "unknown.json") << R"({"chin": [1, 2, 3], "elbow": [4, 5, 6]})";
  const std::string m = message_of([&] { read_landmarks(dir / "unknown.json", table); });
  EXPECT_NE(m.find("elbow"), std::string::npos);
  EXPECT_NE(m.find("chin, navel"), std::string::npos);
  std::ofstream(dir / "short.json") << R"({"chin": [1, 2]})";
  EXPECT_THROW(read_landmarks(dir / "short.json", table), InputError);
  std::ofstream(dir / "broken.json") << R"({"chin": [1, 2, )";
  EXPECT_THROW(read_landmarks(dir / "broken.json", table), InputError);
  std::filesystem::remove_all(dir);
}

TEST(Metrics, PointTriangleDistanceAndPoseRoundTrip) {
  const Eigen::Vector3d a(0, 0, 0), b(10, 0, 0), c(0, 10, 0);
  EXPECT_NEAR(point_triangle_distance({2, 2, 5}, a, b, c), 5.0, 1e-12);      // above the face
  EXPECT_NEAR(point_triangle_distance({-3, -4, 0}, a, b, c), 5.0, 1e-12);    // vertex region
  EXPECT_NEAR(point_triangle_distance({5, -2, 0}, a, b, c), 2.0, 1e-12);     // edge region
  test::Limb limb = test::limb();
  PoseRecord r;
  r.scale = 1.05;
  r.pose = Pose::rest(3);
  r.pose.rotations[1] = rotation_from_vector({0.3, -0.2, 0.1});
  r.pose.root_translation = {1, 2, 3};
  const auto path = std::filesystem::temp_directory_path() / "bodymodel_reg_pose_test.csv";
  write_pose_csv(path, limb.skeleton.names, r);
  PoseRecord back = read_pose_csv(path, limb.skeleton.names);
  EXPECT_NEAR(back.scale, 1.05, 1e-9);
  EXPECT_LT(rotation_angle_deg(back.pose.rotations[1], r.pose.rotations[1]), 1e-4);  // acos near 1: ~1e-6° noise
  EXPECT_LT((back.pose.root_translation - r.pose.root_translation).norm(), 1e-6);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace bodymodel
