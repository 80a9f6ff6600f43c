// `bodymodel animate`'s frames on every CMU clip of makehuman/motion/cmu/ (issue #8: no flipped
// or exploded triangles; exploded = an edge longer than 3 × its rest length), with the fold
// repair of the frames on (AnimateOptions::repair, the default) and off.
//
// Test character: a heavy MakeHuman body (not the default one) rigged with the SSD base a
// `bodymodel character` rig builds on — MakeHuman's weights smoothed 10 steps, 4 influences
// (tools/pipeline/character.h) — and no MWE refinement, so the test needs no model. The skinning
// is linear blend skinning as in the character's SSD, which makes the same armpit and groin
// folds as its MWE rig (demo character 02_02: worst frame 11 vs 10 flipped). Frames: every 3rd
// (--fps 10), which keeps the test a few seconds long.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "core/io/bvh.h"
#include "core/makehuman.h"
#include "tools/pipeline/animate_job.h"
#include "tools/pipeline/character.h"
#include "tools/pipeline/character_file.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

const MakeHuman& makehuman() {
  static MakeHuman mh = MakeHuman::load();
  return mh;
}

const CharacterRigFile& test_character() {
  static CharacterRigFile c = [] {
    MacroSettings ms;
    ms.gender = 0.1;
    ms.weight = 0.8;
    ms.height = 0.3;
    const MakeHuman::Body b = makehuman().body(ms);
    CharacterRigFile ch;
    ch.F = b.mesh.F;
    ch.skeleton = b.skeleton;
    const Eigen::MatrixXd W = smooth_skin_weights(Eigen::MatrixXd(b.weights), ch.F, 10);
    ch.lbs = lbs_rig_from_weights(b.mesh.V, W, 4);
    ch.rig = ch.lbs;
    ch.template_lbs = lbs_rig_from_weights(b.mesh.V, Eigen::MatrixXd(b.weights), 4);
    ch.driven.assign(ch.skeleton.bone_count(), 1);
    return ch;
  }();
  return c;
}

std::vector<fs::path> cmu_clips() {
  std::vector<fs::path> out;
  for (auto& e : fs::directory_iterator(makehuman().directory() / "motion" / "cmu"))
    if (e.path().extension() == ".bvh") out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name)
      : path(fs::temp_directory_path() / ("bodymodel_animate_flips_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

AnimateResult animate(const fs::path& clip_file, bool repair, const fs::path& dir) {
  const CharacterRigFile& ch = test_character();
  const ClipPoses clip =
      retarget_clip(read_bvh(clip_file), ch.skeleton, makehuman().directory(), true, clip_file.string());
  AnimateOptions o;
  o.fps = 10;
  o.format = "none";
  o.write_glb = false;
  o.sheet_frames = 0;
  o.repair = repair;
  return animate_character(ch, clip, dir, o);
}

TEST(AnimateFlips, EveryCmuClipHasNoFlippedTrianglesAndEdgesWithinThreeTimesRest) {
  const auto clips = cmu_clips();
  ASSERT_GE(clips.size(), 3u);
  for (const auto& path : clips) {
    SCOPED_TRACE(path.filename().string());
    TempDir dir(path.stem().string());
    const AnimateResult r = animate(path, true, dir.path);
    ASSERT_GE(r.frames, 20);
    ASSERT_EQ(r.rig.size(), r.rig_before_repair.size());
    int frames_with_flips_before = 0;
    for (int i = 0; i < r.frames; ++i) {
      EXPECT_EQ(r.rig[i].flipped, 0) << "frame " << i << " (clip frame " << r.source_frames[i] << ")";
      EXPECT_LE(r.rig[i].max_edge_ratio, 3.0) << "frame " << i;
      // The repair moves only the flipped areas: the bulk of the edges is unchanged.
      EXPECT_NEAR(r.rig[i].p99_edge_ratio, r.rig_before_repair[i].p99_edge_ratio, 0.02) << "frame " << i;
      frames_with_flips_before += r.rig_before_repair[i].flipped > 0;
    }
    // The skinned frames do fold (else this test would check nothing): armpit and groin.
    EXPECT_GT(frames_with_flips_before, r.frames / 2);
    EXPECT_GT(r.max_flipped(r.rig_before_repair), 3);
    // The check and the csv agree with what the result says.
    EXPECT_TRUE(fs::exists(dir.path / "animation.csv"));
  }
}

TEST(AnimateFlips, WithoutTheRepairTheFramesAreTheSkinnedOnes) {
  const fs::path clip = makehuman().directory() / "motion" / "cmu" / "02_02.bvh";
  TempDir a("on"), b("off");
  const AnimateResult on = animate(clip, true, a.path), off = animate(clip, false, b.path);
  ASSERT_EQ(on.frames, off.frames);
  for (int i = 0; i < on.frames; ++i) {
    // Same skinning before the repair; off leaves it as it is.
    EXPECT_EQ(on.rig_before_repair[i].flipped, off.rig[i].flipped);
    EXPECT_EQ(off.rig[i].flipped, off.rig_before_repair[i].flipped);
    EXPECT_LE(on.rig[i].flipped, off.rig[i].flipped);
  }
  EXPECT_GT(off.max_flipped(off.rig), 0);
  EXPECT_EQ(off.repair_seconds, 0.0);
  EXPECT_EQ(off.repaired_frames, 0);
  EXPECT_GT(on.repaired_frames, 0);
}

}  // namespace
}  // namespace bodymodel
