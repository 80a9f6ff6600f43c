// End-to-end verbs (character, animate, crowd, demo): their building blocks and bad input.
// Bad input must give one line `bodymodel: error: ...`, exit 2, and leave no output behind.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/bvh.h"
#include "core/data_path.h"
#include "core/io/npz.h"
#include "core/makehuman.h"
#include "core/retarget.h"

#include <Eigen/Geometry>
#include "support/fixtures.h"
#include "support/run_cli.h"
#include "tools/pipeline/animate_job.h"
#include "tools/pipeline/deformation_check.h"
#include "tools/pipeline/output_folder.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;
using fixtures::run_cli;

// One folder per test process, removed when the process exits.
fs::path temp_dir() {
  static const fixtures::TempDir d;
  return d.path;
}

int count_lines(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

TEST(StagedFolder, WritesOnlyOnCommitAndRefusesAnExistingFolderWithoutForce) {
  const fs::path out = temp_dir() / "staged";
  {
    StagedFolder f(out, false);
    write_text_file(f / "a.txt", "x");
    EXPECT_FALSE(fs::exists(out));   // nothing under the final name before commit
  }
  EXPECT_FALSE(fs::exists(out));     // abandoned: staging removed, no final folder
  for (auto& e : fs::directory_iterator(temp_dir())) EXPECT_EQ(e.path().filename().string().find(".staged"), std::string::npos);
  {
    StagedFolder f(out, false);
    write_text_file(f / "a.txt", "first");
    f.commit();
  }
  EXPECT_EQ(read_text_file(out / "a.txt"), "first");
  EXPECT_THROW(StagedFolder(out, false), InputError);
  {
    StagedFolder f(out, true);
    write_text_file(f / "b.txt", "second");
    EXPECT_TRUE(fs::exists(out / "a.txt"));  // the old folder stays until commit
    f.commit();
  }
  EXPECT_FALSE(fs::exists(out / "a.txt"));
  EXPECT_EQ(read_text_file(out / "b.txt"), "second");
}

TEST(DeformationCheck, RigidMotionIsRatioOneAndAStretchedEdgeIsMeasured) {
  Mesh b = fixtures::box(1, 2, 1);
  SkinningRig lbs;
  lbs.method = SkinningMethod::lbs;
  lbs.bone_count = 1;
  lbs.rest = b.V;
  lbs.influences = Eigen::MatrixXi::Zero(b.V.rows(), 1);
  lbs.coefficients = Eigen::MatrixXd::Ones(b.V.rows(), 1);
  DeformationChecker check(b.V, b.F, lbs);
  Eigen::Affine3d M = Eigen::Translation3d(5, 0, 1) * Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, 1, 0).normalized());
  Eigen::MatrixX3d X = (b.V * M.linear().transpose()).rowwise() + M.translation().transpose();
  FrameCheck c = check.check(X, {M});
  EXPECT_NEAR(c.max_edge_ratio, 1, 1e-9);
  EXPECT_NEAR(c.min_edge_ratio, 1, 1e-9);
  EXPECT_EQ(c.flipped, 0);
  // Mirroring in x reverses every triangle: those of the four faces not facing ±x (8 of 12)
  // then point against their rest normal; the ±x faces come out facing the same way.
  Eigen::MatrixX3d Y = b.V;
  Y.col(0) *= -1;
  EXPECT_EQ(check.check(Y, {Eigen::Affine3d::Identity()}).flipped, 8);
  // Pulling one vertex away stretches its edges: the ratio is the longest edge's.
  Eigen::MatrixX3d Z = b.V;
  Z.row(0) += Eigen::RowVector3d(0, 0, -10);
  FrameCheck s = check.check(Z, {Eigen::Affine3d::Identity()});
  EXPECT_GT(s.max_edge_ratio, 5);
}

TEST(RetargetClip, AnUnmappableClipListsItsUnknownJoints) {
  const std::string text =
      "HIERARCHY\nROOT Pelvis\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
      " JOINT Tummy\n {\n  OFFSET 0 10 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "  JOINT Noggin\n  {\n   OFFSET 0 10 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "   End Site\n   {\n    OFFSET 0 5 0\n   }\n  }\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.0333\n"
      "0 0 0 0 0 0 0 0 0 0 0 0\n";
  BvhMotion clip = parse_bvh(text, "alien.bvh");
  MakeHuman mh = MakeHuman::load();
  Skeleton sk = mh.body(MacroSettings{}).skeleton;
  try {
    retarget_clip(clip, sk, mh.directory(), false, "alien.bvh");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("alien.bvh"), std::string::npos) << m;
    EXPECT_NE(m.find("Pelvis"), std::string::npos) << m;
    EXPECT_NE(m.find("Tummy"), std::string::npos) << m;
    EXPECT_NE(m.find("Noggin"), std::string::npos) << m;
  }
  // A CMU clip maps, and retargeting gives a pose per frame.
  BvhMotion cmu = read_bvh(mh.directory() / "motion" / "cmu" / "02_02.bvh");
  ClipPoses p = retarget_clip(cmu, sk, mh.directory(), true, "02_02.bvh");
  EXPECT_EQ(static_cast<int>(p.poses.size()), cmu.frame_count());
}

// ---- the verbs' bad input -------------------------------------------------------------------

void expect_one_line_error(const fixtures::CliResult& r, const std::string& needle) {
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_EQ(count_lines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("bodymodel: error:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(needle), std::string::npos) << r.output;
}

TEST(EndToEndCli, AModelOfAnOlderFormatVersionIsRefusedAndNothingIsWritten) {
  Npz z;
  z.put_text("metadata", R"({"format": "bodymodel-model", "format_version": 0})");
  z.put("format_version", 0.0);
  const fs::path old = temp_dir() / "old_model.npz";
  z.save(old);
  const fs::path out = temp_dir() / "char_old";
  // A real clip: options are checked before the model is read, so a missing clip would be reported first.
  const fs::path cmu_clip = data_file("makehuman/motion/cmu/02_02.bvh");
  expect_one_line_error(run_cli("character '" + old.string() + "' --out '" + out.string() + "'"), "version");
  EXPECT_FALSE(fs::exists(out));
  expect_one_line_error(run_cli("crowd '" + old.string() + "' --bvh '" + cmu_clip.string() + "' --out '" + (temp_dir() / "crowd_old").string() + "'"),
                        "version");
}

TEST(EndToEndCli, AnExistingOutputFolderIsRefusedWithoutForce) {
  const fs::path out = temp_dir() / "exists";
  fs::create_directories(out);
  write_text_file(out / "keep.txt", "mine");
  for (const std::string verb : {"character model.npz", "animate rig.npz --bvh clip.bvh", "demo"}) {
    auto r = run_cli(verb + " --out '" + out.string() + "'");
    expect_one_line_error(r, "--force");
    EXPECT_NE(r.output.find(out.string()), std::string::npos) << r.output;
  }
  EXPECT_EQ(read_text_file(out / "keep.txt"), "mine");
}

TEST(EndToEndCli, AnUnwritableOutputIsOneLineAndLeavesNothing) {
  const fs::path file = temp_dir() / "a_file";
  write_text_file(file, "x");
  expect_one_line_error(run_cli("character model.npz --out '" + (file / "char").string() + "'"), "a_file");
  expect_one_line_error(run_cli("demo --out '" + (file / "out").string() + "'"), "a_file");
}

TEST(EndToEndCli, AnimateRefusesARigWithoutASkeleton) {
  // A plain skinning rig (skinning/rig_io.h keys) has no skeleton to retarget a clip to.
  Npz z;
  z.put_text("format", "bodymodel-skinning-rig-1");
  z.put_text("method", "ssd");
  z.put("bone_count", 1.0);
  z.put("rest", Eigen::MatrixXd(Eigen::MatrixXd::Zero(3, 3)));
  Eigen::MatrixXi F(1, 3);
  F << 0, 1, 2;
  z.put("faces", F);
  z.put("influences", Eigen::MatrixXi(Eigen::MatrixXi::Zero(3, 1)));
  z.put("coefficients", Eigen::MatrixXd(Eigen::MatrixXd::Ones(3, 1)));
  const fs::path rig = temp_dir() / "plain_rig.npz";
  z.save(rig);
  const fs::path out = temp_dir() / "frames_plain";
  expect_one_line_error(run_cli("animate '" + rig.string() + "' --bvh '" + (MakeHuman::load().directory() / "motion" / "cmu" / "02_02.bvh").string() +
                                "' --out '" + out.string() + "'"),
                        "skeleton");
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace bodymodel

namespace bodymodel {
namespace {

// Retargeting corrects the rest pose of the limb chains only (T-pose → hm08 A-pose, leg
// directions): the clips' rest frame (every rotation zero) leaves hm08's spine, neck, head and
// clavicles at their rest rotation, symmetric left and right. Aligning those chains too bent a standing body by
// 17–39° per joint (neck01 39°, clavicle.L 23° vs clavicle.R 18° on 12_03).
TEST(RetargetClip, TheClipsRestFrameBendsOnlyTheLimbs) {
  MakeHuman mh = MakeHuman::load();
  Skeleton sk = mh.body(MacroSettings{}).skeleton;
  for (const char* name : {"02_02", "12_03"}) {
    SCOPED_TRACE(name);
    BvhMotion clip = read_bvh(mh.directory() / "motion" / "cmu" / (std::string(name) + ".bvh"));
    clip.frames.setZero();
    const Pose p = Retargeter(clip, sk, RetargetMap::for_clip(clip, mh.directory())).pose(0);
    for (int b = 0; b < sk.bone_count(); ++b) {
      const std::string& n = sk.names[b];
      const double deg = Eigen::AngleAxisd(p.rotations[b]).angle() * 180 / M_PI;
      for (const char* trunk : {"spine", "neck", "head", "clavicle", "shoulder", "root"})
        if (n.rfind(trunk, 0) == 0) EXPECT_LT(deg, 0.5) << n;
    }
    const double l = Eigen::AngleAxisd(p.rotations[sk.index("upperarm01.L")]).angle();
    const double r = Eigen::AngleAxisd(p.rotations[sk.index("upperarm01.R")]).angle();
    EXPECT_GT(l * 180 / M_PI, 30);   // A-pose arm raised to the T-pose
    EXPECT_NEAR(l, r, 0.05);         // symmetric
  }
}

}  // namespace
}  // namespace bodymodel
