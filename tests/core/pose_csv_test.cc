// Pose files (core/io/pose_csv.h) and rotation vectors (core/rotation.h): round trip, and the
// reader's answer to a bone the skeleton does not have (an error naming file, line and bone, or,
// when the caller asks, the bone skipped and named).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/io/pose_csv.h"
#include "core/rotation.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

fs::path write_file(const std::string& name, const std::string& text) {
  const fs::path p = fs::temp_directory_path() / name;
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

TEST(Rotation, VectorRoundTripAndAngle) {
  const Eigen::Vector3d v(0.3, -0.2, 0.1);
  const Eigen::Matrix3d R = rotation_from_vector(v);
  EXPECT_LT((rotation_vector_of(R) - v).norm(), 1e-12);
  EXPECT_NEAR(rotation_angle_deg(R, Eigen::Matrix3d::Identity()), v.norm() * 180 / M_PI, 1e-9);
  EXPECT_EQ(rotation_from_vector(Eigen::Vector3d::Zero()), Eigen::Matrix3d::Identity());
  EXPECT_EQ(rotation_vector_of(Eigen::Matrix3d::Identity()), Eigen::Vector3d::Zero());
}

TEST(PoseCsv, RoundTrip) {
  const std::vector<std::string> bones = {"root", "spine", "head"};
  PoseRecord r;
  r.scale = 1.05;
  r.pose = Pose::rest(3);
  r.pose.rotations[2] = rotation_from_vector({0.1, 0.2, -0.3});
  r.pose.root_translation = {1, 2, 3};
  r.global_translation = {4, 5, 6};
  const fs::path p = fs::temp_directory_path() / "bodymodel_pose_csv_test.pose.csv";
  write_pose_csv(p, bones, r);
  const PoseRecord back = read_pose_csv(p, bones);
  EXPECT_NEAR(back.scale, 1.05, 1e-9);
  EXPECT_LT(rotation_angle_deg(back.pose.rotations[2], r.pose.rotations[2]), 1e-4);
  EXPECT_LT((back.pose.root_translation - r.pose.root_translation).norm(), 1e-6);
  EXPECT_LT((back.global_translation - r.global_translation).norm(), 1e-6);
  fs::remove(p);
}

TEST(PoseCsv, UnknownBoneIsAnErrorUnlessSkipped) {
  const std::vector<std::string> bones = {"root", "spine"};
  const fs::path p = write_file("bodymodel_pose_csv_unknown.pose.csv",
                                "bone,rx,ry,rz\n_global_rotation,0,0,0\nspine,0.1,0,0\n"
                                "tail,0,0.2,0\nhead,0,0,0.3\n");
  try {
    read_pose_csv(p, bones);
    FAIL() << "an unknown bone was accepted";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(p.string() + ":4"), std::string::npos) << m;
    EXPECT_NE(m.find("'tail'"), std::string::npos) << m;
  }
  std::vector<std::string> skipped;
  const PoseRecord r = read_pose_csv(p, bones, &skipped);
  EXPECT_EQ(skipped, (std::vector<std::string>{"tail", "head"}));
  EXPECT_NEAR(rotation_vector_of(r.pose.rotations[1]).x(), 0.1, 1e-12);
  EXPECT_EQ(r.pose.rotations[0], Eigen::Matrix3d::Identity());
  fs::remove(p);
}

TEST(PoseCsv, MalformedRowsNameFileAndLine) {
  const std::vector<std::string> bones = {"root"};
  const fs::path a = write_file("bodymodel_pose_csv_bad_a.pose.csv", "bone,rx,ry,rz\nroot,0,x,0\n");
  const fs::path b = write_file("bodymodel_pose_csv_bad_b.pose.csv", "bone,rx,ry,rz\nroot,0,0\n");
  for (const fs::path& p : {a, b}) {
    try {
      read_pose_csv(p, bones);
      FAIL() << "malformed row accepted in " << p;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(p.string() + ":2"), std::string::npos) << e.what();
    }
    fs::remove(p);
  }
}

}  // namespace
}  // namespace bodymodel
