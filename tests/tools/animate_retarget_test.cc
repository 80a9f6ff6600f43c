// The retarget's limb twist split and finger handling for animation (core/retarget.h,
// RetargetOptions::for_animation), on
// every CMU clip in makehuman/motion/cmu/: the armpit and groin flips of `bodymodel animate`
// came from the limbs' whole twist sitting at upperarm01 / upperleg01.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>

#include "core/io/bvh.h"
#include "core/makehuman.h"
#include "core/retarget.h"
#include "tools/pipeline/animate_job.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

// Twist (rad, in (-π, π]) of the rotation R about the unit axis a: R = S·T, T about a.
double twist_about(const Eigen::Matrix3d& R, const Eigen::Vector3d& a) {
  const Eigen::Quaterniond q(R);
  double t = 2 * std::atan2(q.vec().dot(a), q.w());  // (-2π, 2π]
  if (t > M_PI) t -= 2 * M_PI;
  if (t <= -M_PI) t += 2 * M_PI;
  return t;
}

std::vector<fs::path> cmu_clips(const fs::path& makehuman_dir) {
  std::vector<fs::path> out;
  for (auto& e : fs::directory_iterator(makehuman_dir / "motion" / "cmu"))
    if (e.path().extension() == ".bvh") out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

TEST(AnimateRetarget, LimbTwistIsSharedAndChainEndsUnchanged) {
  const MakeHuman mh = MakeHuman::load();
  const Skeleton sk = mh.body(MacroSettings{}).skeleton;
  const auto clips = cmu_clips(mh.directory());
  ASSERT_GE(clips.size(), 3u);
  for (const auto& path : clips) {
    SCOPED_TRACE(path.filename().string());
    const BvhMotion m = read_bvh(path);
    const RetargetMap map = RetargetMap::for_clip(m, mh.directory());
    const Retargeter split(m, sk, map, RetargetOptions::for_animation()), unsplit(m, sk, map);
    double worst_end = 0, largest_chain_twist = 0;
    for (int f = 0; f < m.frame_count(); f += 7) {
      const Pose ps = split.pose(f), pu = unsplit.pose(f);
      const auto Qs = world_rotations(sk, ps), Qu = world_rotations(sk, pu);
      for (const char* bone : {"upperarm01.L", "upperarm01.R", "upperleg01.L", "upperleg01.R", "lowerarm01.L"}) {
        const int b1 = sk.index(bone);
        std::string second = bone;
        second[second.size() - 3] = '2';
        const int b2 = sk.index(second);
        // The chain's second bone (and so everything below) ends where it did.
        worst_end = std::max(worst_end, (Qs[b2] - Qu[b2]).norm());
        const Eigen::Vector3d a = (sk.tails.row(b1) - sk.heads.row(b1)).transpose().normalized();
        const double whole_twist = twist_about(pu.rotations[b1], a);
        const double first_twist = twist_about(ps.rotations[b1], a);
        largest_chain_twist = std::max(largest_chain_twist, std::abs(whole_twist));
        // The first bone keeps half of the twist (for_animation: first_bone_twist 0.5).
        EXPECT_NEAR(first_twist, 0.5 * whole_twist, 1e-6) << bone << " frame " << f;
        // Same swing: the first bone points where it did.
        EXPECT_LT((Qs[b1] * a - Qu[b1] * a).norm(), 1e-9) << bone << " frame " << f;
      }
    }
    EXPECT_LT(worst_end, 1e-9);
    // The clips do twist the limbs (else this test would check nothing).
    EXPECT_GT(largest_chain_twist, 10 * M_PI / 180);
  }
}

TEST(AnimateRetarget, CmuFingersKeepTheirRestPoseWhenAnimating) {
  const MakeHuman mh = MakeHuman::load();
  const Skeleton sk = mh.body(MacroSettings{}).skeleton;
  const BvhMotion m = read_bvh(mh.directory() / "motion" / "cmu" / "12_03.bvh");
  const RetargetMap map = RetargetMap::for_clip(m, mh.directory());
  const Retargeter off(m, sk, map, RetargetOptions::for_animation()), on(m, sk, map);
  double moved_off = 0, moved_on = 0;
  for (int f = 0; f < m.frame_count(); f += 11) {
    const Pose a = off.pose(f), b = on.pose(f);
    for (int bone = 0; bone < sk.bone_count(); ++bone) {
      const std::string& n = sk.names[bone];
      if (n.rfind("finger", 0) && n.rfind("metacarpal", 0)) continue;
      moved_off = std::max(moved_off, Eigen::AngleAxisd(a.rotations[bone]).angle());
      moved_on = std::max(moved_on, Eigen::AngleAxisd(b.rotations[bone]).angle());
    }
  }
  EXPECT_EQ(moved_off, 0.0);
  EXPECT_GT(moved_on, 20 * M_PI / 180);  // 12_03's thumb swings ~54 degrees
  EXPECT_GT(on.driven_bone_count(), off.driven_bone_count());
}

// cgspeed's CMU conversions start with the rest T-pose one frame before the motion (12_03: the
// upper arms turn about 80° from frame 0 to frame 1, about 1° a frame after it). retarget_clip
// drops that frame; the Poser-style clips (02_02, 03_03) start with motion and keep every frame.
TEST(AnimateRetarget, ALeadInRestFrameIsDroppedAndMotionKept) {
  const MakeHuman mh = MakeHuman::load();
  const Skeleton sk = mh.body(MacroSettings{}).skeleton;
  for (const fs::path& f : cmu_clips(mh.directory())) {
    const BvhMotion clip = read_bvh(f);
    const ClipPoses p = retarget_clip(clip, sk, mh.directory(), true, f.string());
    const bool cgspeed = f.stem() == "12_03";
    EXPECT_EQ(p.lead_in, cgspeed ? 1 : 0) << f;
    EXPECT_EQ(static_cast<int>(p.poses.size()), clip.frame_count() - p.lead_in) << f;
    if (cgspeed) {
      EXPECT_GT(p.lead_in_jump_deg, 60) << f;
    }
  }
  // Known answers on made-up clips: a bone at rest, then turning 1° a frame from 40°: a lead-in;
  // the same bone turning 40° every frame: motion.
  auto clip_of = [](double first, double step) {
    std::vector<Pose> poses(8, Pose::rest(2));
    for (size_t k = 1; k < poses.size(); ++k)
      poses[k].rotations[1] = Eigen::AngleAxisd((first + step * (k - 1)) * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    return poses;
  };
  double jump = 0;
  EXPECT_EQ(lead_in_frames(clip_of(40, 1), &jump), 1);
  EXPECT_NEAR(jump, 40, 1e-9);
  EXPECT_EQ(lead_in_frames(clip_of(40, 40)), 0);
  EXPECT_EQ(lead_in_frames(clip_of(20, 0.1)), 0);   // under 30°: a small settle, kept
}

}  // namespace
}  // namespace bodymodel
