// `bodymodel skin apply` and `skin export-gltf` end to end: a 3-bone tube rig with its skeleton
// stored in the .npz, driven by a BVH written for that skeleton.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <random>

#include "core/io/atomic_write.h"
#include "core/data_path.h"
#include "core/io/bvh.h"
#include "core/makehuman.h"
#include "core/retarget.h"
#include "core/io/mesh_io.h"
#include "skinning/rig_io.h"
#include "skinning/skinning_rig.h"
#include "synthetic_tube.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {

using fixtures::run_cli;

Skeleton tube_skeleton() {
  Skeleton s;
  s.names = {"b0", "b1", "b2"};
  s.parents = {-1, 0, 1};
  s.heads.resize(3, 3);
  s.heads << 0, 0, 0, 1, 0, 0, 2, 0, 0;
  s.tails = s.heads;
  s.tails.col(0).array() += 1;
  return s;
}

struct Fixture {
  std::filesystem::path dir;
  testing::SyntheticTube t;
  Skeleton skeleton = tube_skeleton();
  SkinningRig rig;
  std::vector<Pose> poses;
};

Fixture make_fixture(const std::string& tag) {
  Fixture f;
  f.dir = std::filesystem::temp_directory_path() / ("bodymodel_skin_apply_" + tag + std::to_string(::getpid()));
  std::filesystem::remove_all(f.dir);
  std::filesystem::create_directories(f.dir);
  f.t = testing::make_tube(21, 12);
  f.rig = lbs_rig_from_weights(f.t.V, f.t.W, 3, 0.0);
  save_rig(f.dir / "rig.npz", f.rig, f.t.F, {}, &f.skeleton);
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 5; ++k) {
    Pose p = Pose::rest(3);
    for (auto& R : p.rotations)
      R = Eigen::AngleAxisd(0.8 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()).toRotationMatrix();
    f.poses.push_back(p);
  }
  write_bvh(f.dir / "clip.bvh", skeleton_poses_to_bvh(f.skeleton, f.poses));
  return f;
}

TEST(SkinApplyCli, PosesEveryFrameResumesAndRejectsARigWithoutSkeleton) {
  const Fixture f = make_fixture("a");
  std::string out;
  ASSERT_EQ(run_cli("skin apply " + (f.dir / "rig.npz").string() + " --bvh " + (f.dir / "clip.bvh").string() +
                    " --out " + (f.dir / "frames").string(), &out), 0) << out;
  for (int k = 0; k < 5; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d.obj", k);
    const Mesh m = read_mesh(f.dir / "frames" / name);
    const Eigen::MatrixX3d ref = evaluate_rig(f.rig, forward_kinematics(f.skeleton, f.poses[static_cast<size_t>(k)]));
    ASSERT_EQ(m.V.rows(), ref.rows());
    EXPECT_LT((m.V - ref).cwiseAbs().maxCoeff(), 1e-4) << name;   // BVH degrees (6 decimals), OBJ text
    EXPECT_EQ(m.F, f.t.F);
    if (k > 0) {
      EXPECT_GT((ref - f.t.V).cwiseAbs().maxCoeff(), 0.1);   // the pose moves the tube
    }
  }
  // Rerun after removing one frame: only that one is written.
  std::filesystem::remove(f.dir / "frames" / "frame_00003.obj");
  ASSERT_EQ(run_cli("skin apply " + (f.dir / "rig.npz").string() + " --bvh " + (f.dir / "clip.bvh").string() +
                    " --out " + (f.dir / "frames").string(), &out), 0) << out;
  EXPECT_NE(out.find("1 written, 4 already there"), std::string::npos) << out;
  EXPECT_TRUE(std::filesystem::exists(f.dir / "frames" / "frame_00003.obj"));
  // A rig without a skeleton (not on the MakeHuman body): one line, exit 2, nothing written.
  save_rig(f.dir / "bare.npz", f.rig, f.t.F);
  EXPECT_EQ(run_cli("skin apply " + (f.dir / "bare.npz").string() + " --bvh " + (f.dir / "clip.bvh").string() +
                    " --out " + (f.dir / "bare_frames").string(), &out), 2) << out;
  EXPECT_NE(out.find("no skeleton"), std::string::npos) << out;
  EXPECT_FALSE(std::filesystem::exists(f.dir / "bare_frames"));
  std::filesystem::remove_all(f.dir);
}

TEST(SkinApplyCli, ExportGltfWritesAnAnimatedGlbAndRefusesMwe) {
  const Fixture f = make_fixture("g");
  std::string out;
  ASSERT_EQ(run_cli("skin export-gltf --rig " + (f.dir / "rig.npz").string() + " --bvh " +
                    (f.dir / "clip.bvh").string() + " --scale 1 --out " + (f.dir / "tube.glb").string(), &out), 0) << out;
  const std::string bytes = read_text_file(f.dir / "tube.glb");
  EXPECT_EQ(bytes.substr(0, 4), "glTF");
  EXPECT_NE(out.find("5 animation frames"), std::string::npos) << out;
  // An MWE rig has no glTF form (and no SSD weights beside it).
  SkinningRig mwe = lbs_as_mwe(f.rig);
  save_rig(f.dir / "mwe.npz", mwe, f.t.F, {}, &f.skeleton);
  EXPECT_EQ(run_cli("skin export-gltf --rig " + (f.dir / "mwe.npz").string() + " --out " +
                    (f.dir / "mwe.glb").string(), &out), 2) << out;
  EXPECT_FALSE(std::filesystem::exists(f.dir / "mwe.glb"));
  std::filesystem::remove_all(f.dir);
}

// A rig on the MakeHuman body without stored skeleton keys: `skin apply` places the default
// skeleton on the rig's rest mesh and poses it like our own forward kinematics + LBS.
TEST(SkinApplyCli, MakeHumanBodyRigUsesTheDefaultSkeleton) {
  const auto mh_dir = data_file("makehuman");
  if (!std::filesystem::exists(mh_dir)) GTEST_SKIP() << "no MakeHuman data";
  const MakeHuman mh = MakeHuman::load();
  const MakeHuman::Body body = mh.body(MacroSettings{});
  const SkinningRig rig = lbs_rig_from_weights(body.mesh.V, Eigen::MatrixXd(body.weights), 4);
  const auto dir = std::filesystem::temp_directory_path() / ("bodymodel_skin_apply_mh" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  save_rig(dir / "body.npz", rig, body.mesh.F);
  const auto bvh = mh.pose_file("tpose");
  std::string out;
  ASSERT_EQ(run_cli("skin apply " + (dir / "body.npz").string() + " --bvh " + bvh.string() +
                    " --out " + (dir / "frames").string(), &out), 0) << out;
  EXPECT_NE(out.find("skeleton: makehuman"), std::string::npos) << out;
  const Mesh m = read_mesh(dir / "frames" / "frame_00000.obj");
  const Skeleton sk = mh.skeleton_from_body(rig.rest);
  const Eigen::MatrixX3d ref = evaluate_rig(rig, forward_kinematics(sk, poses_from_bvh(read_bvh(bvh), sk, mh_dir)[0]));
  EXPECT_LT((m.V - ref).cwiseAbs().maxCoeff(), 1e-3);                 // mm
  EXPECT_GT((ref - body.mesh.V).rowwise().norm().maxCoeff(), 100.0);   // the T-pose lifts the arms
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bodymodel
