// BVH reader/writer, Euler helpers, and posing the MakeHuman skeleton: reproduces
// derived/reference_poses.tsv within 0.1 mm.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/bvh.h"
#include "core/makehuman.h"
#include "tests/core/makehuman_fixture.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

// A small made-up two-joint clip.
const char* kSmallBvh =
    "HIERARCHY\n"
    "ROOT hips\n"
    "{\n"
    "  OFFSET 0 10 0\n"
    "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
    "  JOINT knee\n"
    "  {\n"
    "    OFFSET 0 -5 0\n"
    "    CHANNELS 3 Zrotation Xrotation Yrotation\n"
    "    End Site\n"
    "    {\n"
    "      OFFSET 0 -5 1\n"
    "    }\n"
    "  }\n"
    "}\n"
    "MOTION\n"
    "Frames: 2\n"
    "Frame Time: 0.0333333\n"
    "0 10 0 10 20 30 0 0 45\n"
    "1 10.5 -2 -10 5 170 90 10 -20\n";

std::string bvh_error(const std::string& text) {
  try {
    parse_bvh(text, "test.bvh");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Bvh, ParsesHierarchyAndFrames) {
  const BvhMotion m = parse_bvh(kSmallBvh, "small.bvh");
  ASSERT_EQ(m.joints.size(), 2u);
  EXPECT_EQ(m.joints[1].parent, 0);
  EXPECT_EQ(m.channel_count(), 9);
  EXPECT_EQ(m.frame_count(), 2);
  EXPECT_EQ(m.joints[1].first_channel, 6);
  EXPECT_NEAR(m.frames(1, 4), 5.0, 0);
  ASSERT_TRUE(m.joints[1].end_site.has_value());
  EXPECT_NEAR((*m.joints[1].end_site - Eigen::Vector3d(0, -5, 1)).norm(), 0, 0);
  // Zrotation Xrotation Yrotation: R = Rz·Rx·Ry.
  const Eigen::Matrix3d R = bvh_joint_rotation(m, 0, 0);
  const double d = M_PI / 180;
  const Eigen::Matrix3d expected = (Eigen::AngleAxisd(10 * d, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(20 * d, Eigen::Vector3d::UnitX()) *
                                    Eigen::AngleAxisd(30 * d, Eigen::Vector3d::UnitY()))
                                       .toRotationMatrix();
  EXPECT_LT((R - expected).norm(), 1e-14);
  EXPECT_LT((bvh_root_position(m, 1) - Eigen::Vector3d(1, 10.5, -2)).norm(), 1e-15);
}

TEST(Bvh, WriteReadRoundTrip) {
  const fs::path tmp = fs::temp_directory_path() / ("bodymodel_bvh_rt_" +
                                                    std::to_string(::getpid()) + ".bvh");
  for (const std::string& name : {std::string("small"), std::string("standing01"),
                                  std::string("12_03")}) {
    SCOPED_TRACE(name);
    BvhMotion m;
    if (name == "small") m = parse_bvh(kSmallBvh, "small.bvh");
    else if (name == "12_03") m = read_bvh(data_file("makehuman/motion/cmu/12_03.bvh"));
    else m = read_bvh(data_file("makehuman/motion/poses/" + name + ".bvh"));
    write_bvh(tmp, m);
    const BvhMotion back = read_bvh(tmp);
    ASSERT_EQ(back.joints.size(), m.joints.size());
    for (size_t j = 0; j < m.joints.size(); ++j) {
      EXPECT_EQ(back.joints[j].name, m.joints[j].name);
      EXPECT_EQ(back.joints[j].parent, m.joints[j].parent);
      EXPECT_EQ(back.joints[j].channels, m.joints[j].channels);
      EXPECT_LT((back.joints[j].offset - m.joints[j].offset).cwiseAbs().maxCoeff(), 5e-7);
      EXPECT_EQ(back.joints[j].end_site.has_value(), m.joints[j].end_site.has_value());
    }
    ASSERT_EQ(back.frames.rows(), m.frames.rows());
    ASSERT_EQ(back.frames.cols(), m.frames.cols());
    EXPECT_LT((back.frames - m.frames).cwiseAbs().maxCoeff(), 5e-7);
    EXPECT_NEAR(back.frame_time, m.frame_time, 1e-8);
  }
  fs::remove(tmp);
}

TEST(Bvh, EveryShippedFileParses) {
  int files = 0;
  for (const char* sub : {"makehuman/motion/poses", "makehuman/motion/cmu"})
    for (const auto& e : fs::directory_iterator(data_file(sub)))
      if (e.path().extension() == ".bvh") {
        const BvhMotion m = read_bvh(e.path());
        EXPECT_GT(m.frame_count(), 0) << e.path();
        m.validate();
        ++files;
      }
  EXPECT_EQ(files, 17);
  const BvhMotion walk = read_bvh(data_file("makehuman/motion/cmu/12_03.bvh"));
  EXPECT_EQ(walk.frame_count(), 566);
  EXPECT_EQ(walk.channel_count(), 96);
  const BvhMotion tpose = read_bvh(data_file("makehuman/motion/poses/tpose.bvh"));
  EXPECT_EQ(tpose.joints.size(), 173u);
  EXPECT_EQ(tpose.channel_count(), 951);
  EXPECT_EQ(guess_bvh_up_axis(tpose), BvhUpAxis::kZ);
  EXPECT_EQ(guess_bvh_up_axis(walk), BvhUpAxis::kY);
}

TEST(Bvh, EulerRoundTripAllOrders) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  const std::array<std::array<int, 3>, 6> orders{
      {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
  double worst_matrix = 0, worst_angle = 0;
  for (const auto& o : orders)
    for (int t = 0; t < 200; ++t) {
      Eigen::Vector3d deg(179 * u(rng), 89 * u(rng), 179 * u(rng));
      if (t == 0) deg[1] = 90;   // gimbal lock
      if (t == 1) deg[1] = -90;
      const Eigen::Matrix3d R = euler_to_rotation(o, deg);
      const Eigen::Vector3d back = rotation_to_euler(R, o);
      worst_matrix = std::max(worst_matrix, (euler_to_rotation(o, back) - R).norm());
      if (t > 1) worst_angle = std::max(worst_angle, (back - deg).cwiseAbs().maxCoeff());
    }
  EXPECT_LT(worst_matrix, 1e-9);
  EXPECT_LT(worst_angle, 1e-7);
}

TEST(Bvh, BadInputIsAnInputErrorNamingTheLine) {
  const std::string good = kSmallBvh;
  // Truncated: the second frame line is missing.
  std::string truncated = good.substr(0, good.rfind("1 10.5"));
  std::string msg = bvh_error(truncated);
  EXPECT_NE(msg.find("test.bvh"), std::string::npos) << msg;
  EXPECT_NE(msg.find("truncated"), std::string::npos) << msg;
  // Truncated inside the hierarchy.
  msg = bvh_error(good.substr(0, good.find("  JOINT knee") + 8));
  EXPECT_NE(msg.find("end of the file"), std::string::npos) << msg;
  // Missing channel: CHANNELS 3 with only two names.
  std::string missing = good;
  missing.replace(missing.find("CHANNELS 3 Zrotation Xrotation Yrotation"),
                  std::strlen("CHANNELS 3 Zrotation Xrotation Yrotation"),
                  "CHANNELS 3 Zrotation Xrotation");
  msg = bvh_error(missing);
  EXPECT_NE(msg.find("line 10"), std::string::npos) << msg;
  EXPECT_NE(msg.find("knee"), std::string::npos) << msg;
  // Wrong value count on a frame line.
  std::string short_frame = good;
  short_frame.replace(short_frame.find("0 0 45\n"), 7, "0 45\n");
  msg = bvh_error(short_frame);
  EXPECT_NE(msg.find("line 19"), std::string::npos) << msg;
  EXPECT_NE(msg.find("8 values, expected 9"), std::string::npos) << msg;
  // A non-number.
  std::string nan = good;
  nan.replace(nan.find("10.5"), 4, "abc");
  EXPECT_NE(bvh_error(nan).find("line 20"), std::string::npos);
  // Unknown channel name.
  std::string unknown = good;
  unknown.replace(unknown.find("Xposition"), 9, "Wposition");
  EXPECT_NE(bvh_error(unknown).find("line 5"), std::string::npos);
  EXPECT_THROW(read_bvh("/nonexistent/file.bvh"), InputError);
}

// derived/reference_poses.tsv: default human, frame 0, rotations only, LBS with normalised
// weights; bounding box and probe vertices within 0.1 mm.
TEST(Bvh, ReproducesReferencePoses) {
  const MakeHuman& mh = shared_makehuman();
  const Eigen::MatrixX3d V = mh.build_vertices(MacroSettings{});
  const Skeleton skel = mh.skeleton(V);
  std::ifstream in(data_file("makehuman/derived/reference_poses.tsv"));
  std::string line;
  int rows = 0;
  double worst = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> cols;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, '\t')) cols.push_back(c);
    ASSERT_EQ(cols.size(), 10u) << line;
    SCOPED_TRACE(cols[0]);
    const BvhMotion m = read_bvh(mh.pose_file(cols[0]));
    EXPECT_EQ(cols[1], guess_bvh_up_axis(m) == BvhUpAxis::kZ ? "Z" : "Y");
    const Pose pose = bvh_frame_to_pose(m, 0, skel);
    const Eigen::MatrixX3d P = linear_blend_skinning(V, mh.weights(), forward_kinematics(skel, pose));
    auto xyz = [&](int col) {
      std::stringstream s(cols[col]);
      Eigen::RowVector3d v;
      s >> v[0] >> v[1] >> v[2];
      return Eigen::RowVector3d(v * 100.0);  // dm → mm
    };
    const Eigen::MatrixX3d body = P.topRows(MakeHuman::kBodyVertexCount);
    worst = std::max(worst, (body.colwise().minCoeff() - xyz(2)).cwiseAbs().maxCoeff());
    worst = std::max(worst, (body.colwise().maxCoeff() - xyz(3)).cwiseAbs().maxCoeff());
    const int probes[6] = {0, 1000, 5000, 10000, 13379, 15000};
    for (int k = 0; k < 6; ++k) {
      const double err = (P.row(probes[k]) - xyz(4 + k)).cwiseAbs().maxCoeff();
      EXPECT_LT(err, 0.1) << "vertex " << probes[k];
      worst = std::max(worst, err);
    }
    ++rows;
  }
  EXPECT_EQ(rows, 4);
  EXPECT_LT(worst, 0.1);
  RecordProperty("worst_mm", std::to_string(worst));
}

// tpose raises the arms level (README §9: wrist height = shoulder height within 0.01 dm).
TEST(Bvh, TposeArmsAreLevel) {
  const MakeHuman& mh = shared_makehuman();
  const MakeHuman::Body body = mh.body(MacroSettings{});
  const Pose pose = bvh_frame_to_pose(read_bvh(mh.pose_file("tpose")), 0, body.skeleton);
  const BoneTransforms M = forward_kinematics(body.skeleton, pose);
  for (const char* side : {".L", ".R"}) {
    const int wrist = body.skeleton.index(std::string("wrist") + side);
    const int shoulder = body.skeleton.index(std::string("upperarm01") + side);
    const double yw = (M[wrist] * Eigen::Vector3d(body.skeleton.heads.row(wrist))).y();
    const double ys = (M[shoulder] * Eigen::Vector3d(body.skeleton.heads.row(shoulder))).y();
    EXPECT_NEAR(yw, ys, 1.0) << side;
  }
}

// Root translation (README §7.1 step 3): standing poses land on the rest floor (y ≈ −818 mm).
TEST(Bvh, StandingPosesLandOnTheFloor) {
  const MakeHuman& mh = shared_makehuman();
  const MakeHuman::Body body = mh.body(MacroSettings{});
  const double floor = body.mesh.V.col(1).minCoeff();
  BvhPoseOptions opt;
  opt.apply_root_translation = true;
  for (const char* name : {"standing01", "standing02", "standing03", "standing04", "standing05"}) {
    const Pose pose = bvh_frame_to_pose(read_bvh(mh.pose_file(name)), 0, body.skeleton, opt);
    const Eigen::MatrixX3d P =
        linear_blend_skinning(body.mesh.V, body.weights, forward_kinematics(body.skeleton, pose));
    EXPECT_NEAR(P.col(1).minCoeff(), floor, 15.0) << name;
  }
}

// Writing skeleton poses and reading them back gives the same posed skeleton.
TEST(Bvh, SkeletonPosesRoundTrip) {
  const MakeHuman& mh = shared_makehuman();
  const MakeHuman::Body body = mh.body(MacroSettings{});
  Pose pose = bvh_frame_to_pose(read_bvh(mh.pose_file("fight01")), 0, body.skeleton);
  pose.root_translation = Eigen::Vector3d(10, -20, 30);
  const BvhMotion m = skeleton_poses_to_bvh(body.skeleton, {Pose::rest(163), pose});
  const BvhMotion back = parse_bvh(format_bvh(m), "memory.bvh");
  BvhPoseOptions opt;
  opt.apply_root_translation = true;
  opt.up_axis = BvhUpAxis::kY;
  opt.translation_scale = 1.0;
  const Pose again = bvh_frame_to_pose(back, 1, body.skeleton, opt);
  const BoneTransforms A = forward_kinematics(body.skeleton, pose);
  const BoneTransforms B = forward_kinematics(body.skeleton, again);
  double worst = 0;
  for (int b = 0; b < body.skeleton.bone_count(); ++b)
    worst = std::max(worst, (A[b].matrix() - B[b].matrix()).cwiseAbs().maxCoeff());
  EXPECT_LT(worst, 1e-3);  // 6 decimals in the file
}

}  // namespace
}  // namespace bodymodel
