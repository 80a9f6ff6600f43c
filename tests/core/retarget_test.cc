// Retargeting the CMU clips onto the MakeHuman skeleton: plausible bodies in every frame.
#include <gtest/gtest.h>

#include <algorithm>

#include "core/data_path.h"
#include "core/error.h"
#include "core/geometry.h"
#include "core/io/bvh.h"
#include "core/makehuman.h"
#include "core/retarget.h"
#include "tests/core/makehuman_fixture.h"

namespace bodymodel {
namespace {

Eigen::VectorXd edge_lengths(const Eigen::MatrixX3d& V, const Eigen::MatrixX2i& E) {
  Eigen::VectorXd l(E.rows());
  for (Eigen::Index e = 0; e < E.rows(); ++e) l[e] = (V.row(E(e, 0)) - V.row(E(e, 1))).norm();
  return l;
}

double joint_y(const BoneTransforms& M, const Skeleton& s, const char* bone, bool tail = false) {
  const int b = s.index(bone);
  const Eigen::Vector3d x = tail ? s.tails.row(b).transpose() : s.heads.row(b).transpose();
  return (M[b] * x).y();
}

// Largest edge-length ratio (posed / rest) and its 99.9th percentile.
std::pair<double, double> edge_ratio(const Eigen::MatrixX3d& P, const Eigen::MatrixX2i& E,
                                     const Eigen::VectorXd& rest) {
  Eigen::VectorXd r = edge_lengths(P, E).array() / rest.array();
  const double max_ratio = r.maxCoeff();
  double* nth = r.data() + static_cast<Eigen::Index>(0.999 * (r.size() - 1));
  std::nth_element(r.data(), nth, r.data() + r.size());
  return {max_ratio, *nth};
}

// MakeHuman's own weights already stretch one or two armpit/groin edges by 4x in its own
// static poses (tpose 4.1, standing04 4.3; README §9 gives 1st–99th percentiles 0.65–1.6), so
// the bound on the maximum is relative to those; the 99.9th percentile must stay ≤ 3.
double native_max_edge_ratio(const MakeHuman& mh, const MakeHuman::Body& body,
                             const Eigen::MatrixX2i& E, const Eigen::VectorXd& rest) {
  double worst = 0;
  for (const char* name : {"tpose", "standing01", "standing02", "standing03", "standing04",
                           "standing05"}) {
    const Pose p = bvh_frame_to_pose(read_bvh(mh.pose_file(name)), 0, body.skeleton);
    const Eigen::MatrixX3d P =
        linear_blend_skinning(body.mesh.V, body.weights, forward_kinematics(body.skeleton, p));
    worst = std::max(worst, edge_ratio(P, E, rest).first);
  }
  return worst;
}

class RetargetClip : public ::testing::TestWithParam<const char*> {};

// Every frame of every CMU clip: no exploded limbs (99.9% of edges within 3x their rest
// length, the worst edge no worse than 1.2x MakeHuman's own standing/T poses), legs below
// the hips, arms hanging (a walk), feet near the rest floor with the root translation.
TEST_P(RetargetClip, EveryFramePlausible) {
  const MakeHuman& mh = shared_makehuman();
  const MakeHuman::Body body = mh.body(MacroSettings{});
  const BvhMotion clip = read_bvh(data_file(std::string("makehuman/motion/cmu/") + GetParam() + ".bvh"));
  RetargetOptions with_translation;
  with_translation.apply_root_translation = true;
  const Retargeter rt(clip, body.skeleton, RetargetMap::for_clip(clip, mh.directory()),
                      with_translation);
  EXPECT_GE(rt.driven_bone_count(), 24);
  // Default: rotations only, the root stays put.
  const Retargeter still(clip, body.skeleton, RetargetMap::for_clip(clip, mh.directory()));
  EXPECT_EQ(still.pose(rt.frame_count() - 1).root_translation.norm(), 0.0);
  EXPECT_GT(rt.pose(rt.frame_count() - 1).root_translation.norm(), 500.0);  // a walk travels
  EXPECT_GT(rt.translation_scale(), 0);
  const Eigen::MatrixX2i E = unique_edges(body.mesh.F);
  const Eigen::VectorXd rest = edge_lengths(body.mesh.V, E);
  const double floor = body.mesh.V.col(1).minCoeff();
  const Skeleton& s = body.skeleton;
  const double leg = (s.tails.row(s.index("lowerleg02.L")) - s.heads.row(s.index("upperleg02.L"))).norm();
  const double native = native_max_edge_ratio(mh, body, E, rest);
  double worst_ratio = 0, worst_p999 = 0, lowest = 1e9, highest_low = -1e9;
  int arms_down = 0;
  double max_flexion = 0;
  for (int f = 0; f < rt.frame_count(); ++f) {
    const Pose pose = rt.pose(f);
    const BoneTransforms M = forward_kinematics(s, pose);
    const Eigen::MatrixX3d P = linear_blend_skinning(body.mesh.V, body.weights, M);
    ASSERT_TRUE(P.allFinite());
    const auto [max_ratio, p999] = edge_ratio(P, E, rest);
    worst_ratio = std::max(worst_ratio, max_ratio);
    worst_p999 = std::max(worst_p999, p999);
    const double low = P.col(1).minCoeff();
    lowest = std::min(lowest, low);
    highest_low = std::max(highest_low, low);
    for (const char* side : {".L", ".R"}) {
      const std::string S = side;
      const double hip = joint_y(M, s, ("upperleg02" + S).c_str());
      const double ankle = joint_y(M, s, ("lowerleg02" + S).c_str(), true);
      EXPECT_LT(ankle, hip - 0.6 * leg) << "frame " << f << side;
      // Knees bend forward, never backwards (flexion about the body's left axis ≥ −5°).
      const Eigen::Vector3d left = world_rotations(s, pose)[0] * Eigen::Vector3d::UnitX();
      auto at = [&](const std::string& bone, bool tail) {
        const int b = s.index(bone);
        return Eigen::Vector3d(M[b] * Eigen::Vector3d(tail ? s.tails.row(b) : s.heads.row(b)));
      };
      const Eigen::Vector3d thigh = (at("lowerleg01" + S, false) - at("upperleg01" + S, false)).normalized();
      const Eigen::Vector3d shin = (at("lowerleg02" + S, true) - at("lowerleg01" + S, false)).normalized();
      const double flexion = std::asin(std::clamp(thigh.cross(shin).dot(left), -1.0, 1.0)) * 180 / M_PI;
      EXPECT_GT(flexion, -5.0) << "frame " << f << side;
      max_flexion = std::max(max_flexion, flexion);
      const double shoulder = joint_y(M, s, ("upperarm01" + S).c_str());
      const double wrist = joint_y(M, s, ("wrist" + S).c_str());
      arms_down += wrist < shoulder - 200.0;
    }
  }
  EXPECT_GT(max_flexion, 45.0);  // a walk's swing phase bends the knee
  EXPECT_LT(max_flexion, 100.0);
  EXPECT_LE(worst_p999, 3.0);
  EXPECT_LE(worst_ratio, 1.2 * native);
  // 02_02/03_03 start with a few T-pose calibration frames.
  EXPECT_GE(arms_down, 2 * rt.frame_count() * 3 / 4);
  // Feet stay near the rest floor (uneven terrain in 03_03: within 15 cm).
  EXPECT_NEAR(lowest, floor, 150.0);
  EXPECT_NEAR(highest_low, floor, 150.0);
  RecordProperty("max_edge_ratio", std::to_string(worst_ratio));
  RecordProperty("p999_edge_ratio", std::to_string(worst_p999));
  RecordProperty("native_max_edge_ratio", std::to_string(native));
}

INSTANTIATE_TEST_SUITE_P(Cmu, RetargetClip, ::testing::Values("02_02", "03_03", "12_03"));

// The rest-pose correction: the source's rest T-pose (all rotations zero) puts the hm08 arms
// level and the legs straight down.
TEST(Retarget, SourceRestPoseIsATpose) {
  const MakeHuman& mh = shared_makehuman();
  const MakeHuman::Body body = mh.body(MacroSettings{});
  const Skeleton& s = body.skeleton;
  for (const char* name : {"02_02", "12_03"}) {
    SCOPED_TRACE(name);
    BvhMotion clip = read_bvh(data_file(std::string("makehuman/motion/cmu/") + name + ".bvh"));
    clip.frames.setZero();
    const Retargeter rt(clip, s, RetargetMap::for_clip(clip, mh.directory()));
    const BoneTransforms M = forward_kinematics(s, rt.pose(0));
    for (const char* side : {".L", ".R"}) {
      const std::string S = side;
      EXPECT_NEAR(joint_y(M, s, ("wrist" + S).c_str()), joint_y(M, s, ("upperarm01" + S).c_str()),
                  60.0);
      // hand far out to the side
      const int w = s.index("wrist" + S);
      const double x = (M[w] * Eigen::Vector3d(s.heads.row(w).transpose())).x();
      EXPECT_GT(std::abs(x), 600.0);
    }
  }
}

TEST(Retarget, MapsAndErrors) {
  const MakeHuman& mh = shared_makehuman();
  const RetargetMap cmu = RetargetMap::from_mhskel(mh.directory() / "rig" / "cmu_mb.mhskel");
  bool finger_alias = false;
  for (const auto& e : cmu.entries) finger_alias |= e.source == "LeftHandIndex1";
  EXPECT_TRUE(finger_alias);
  const BvhMotion walk = read_bvh(data_file("makehuman/motion/cmu/12_03.bvh"));
  const Retargeter rt(walk, mh.body(MacroSettings{}).skeleton, cmu);
  EXPECT_TRUE(rt.unmatched_sources().empty());
  // A clip with unknown names cannot be retargeted.
  BvhMotion odd = walk;
  for (auto& j : odd.joints) j.name = "x" + j.name;
  EXPECT_THROW(RetargetMap::for_clip(odd, mh.directory()), InputError);
  EXPECT_THROW(rt.pose(10000), InputError);
}

}  // namespace
}  // namespace bodymodel
