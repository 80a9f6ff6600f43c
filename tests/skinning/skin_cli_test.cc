// `bodymodel skin eval` end to end on a small generated sequence, and its bad-input error.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "core/io/mesh_io.h"
#include "core/mesh.h"
#include <algorithm>
#include "skinning/skinning_rig.h"
#include "synthetic_tube.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {

using fixtures::run_cli;

TEST(SkinCli, EvalWritesTheJackaTableAndRejectsMismatchedFrames) {
  const auto dir = std::filesystem::temp_directory_path() / ("bodymodel_skin_cli_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "seq");
  const auto t = testing::make_tube(21, 12);
  const SkinningRig truth = lbs_rig_from_weights(t.V, t.W, 3, 0.0);
  std::mt19937 rng(4);
  for (int f = 0; f < 8; ++f) {
    const BoneTransforms M = f == 0 ? BoneTransforms(3, Eigen::Affine3d::Identity())
                                    : testing::random_chain_pose(rng, 0.7, true);
    char name[32];
    std::snprintf(name, sizeof name, "frame_%02d.obj", f);
    write_mesh(dir / "seq" / name, evaluate_rig(truth, M), t.F);
  }
  std::string out;
  ASSERT_EQ(run_cli("skin eval " + (dir / "seq").string() +
                    " --train-count 4 --bones 3 --out " + (dir / "report").string(), &out), 0) << out;
  std::ifstream csv(dir / "report" / "skinning.csv");
  std::string header, line;
  std::getline(csv, header);
  EXPECT_EQ(header,
            "method,split,mean_geometric,max_geometric,mean_normal_deg,max_normal_deg,rms_vertex,e_rms,frames,fit_cpu_s");
  int rows = 0;
  while (std::getline(csv, line)) {
    ++rows;
    std::stringstream ss(line);
    std::string method, split, mean;
    std::getline(ss, method, ',');
    std::getline(ss, split, ',');
    std::getline(ss, mean, ',');
    // The data are exact 3-bone LBS: every method reproduces them to well below the tube's size.
    EXPECT_LT(std::stod(mean), 0.01) << line;
  }
  EXPECT_EQ(rows, 14);   // 7 methods (ssd, dqs, as, mwe, psd, eigenskin, quadratic) × train, unseen
  EXPECT_TRUE(std::filesystem::exists(dir / "report" / "unseen_error_mwe.ply"));
  EXPECT_TRUE(std::filesystem::exists(dir / "report" / "unseen_error_quadratic.ply"));
  EXPECT_TRUE(std::filesystem::exists(dir / "report" / "skinning_cv.csv"));
  // A frame with a different vertex count: one clear error line, exit code 2.
  write_mesh(dir / "seq" / "frame_99.obj", t.V.topRows(t.V.rows() - 2), Eigen::MatrixX3i(t.F.topRows(10)));
  EXPECT_EQ(run_cli("skin eval " + (dir / "seq").string() + " --out " +
                    (dir / "report2").string(), &out), 2);
  EXPECT_NE(out.find("frame_99.obj"), std::string::npos) << out;
  EXPECT_NE(out.find("vertices"), std::string::npos) << out;
  std::filesystem::remove_all(dir);
}

// Writes frames of the 3-bone tube posed by its true LBS rig: `count` frames, frame 0 at rest.
void write_tube_frames(const std::filesystem::path& dir, int count, const char* ext, unsigned seed) {
  std::filesystem::create_directories(dir);
  const auto t = testing::make_tube(21, 12);
  const SkinningRig truth = lbs_rig_from_weights(t.V, t.W, 3, 0.0);
  std::mt19937 rng(seed);
  for (int f = 0; f < count; ++f) {
    const BoneTransforms M = f == 0 ? BoneTransforms(3, Eigen::Affine3d::Identity())
                                    : testing::random_chain_pose(rng, 0.7, true);
    const Eigen::MatrixX3d V = evaluate_rig(truth, M);
    char name[32];
    std::snprintf(name, sizeof name, "pose%02d.%s", f, ext);
    if (std::string(ext) == "off") {   // OFF, as SCAPE: 0-based triangles
      std::ofstream o(dir / name);
      o << "OFF\n" << V.rows() << " " << t.F.rows() << " 0\n";
      for (Eigen::Index i = 0; i < V.rows(); ++i) o << V(i, 0) << " " << V(i, 1) << " " << V(i, 2) << "\n";
      for (Eigen::Index i = 0; i < t.F.rows(); ++i) o << "3 " << t.F(i, 0) << " " << t.F(i, 1) << " " << t.F(i, 2) << "\n";
    } else {
      write_mesh(dir / name, V, t.F);
    }
  }
}

TEST(SkinCli, UnorderedPosesWithAnExplicitSplitAndEveryBadInput) {
  const auto dir = std::filesystem::temp_directory_path() / ("bodymodel_skin_split_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  write_tube_frames(dir / "poses", 9, "off", 6);
  std::ofstream(dir / "train.txt") << "# training poses\npose00\npose02\npose03\npose05\npose06\npose08\n";
  std::string out;
  // OFF files listed one by one, an explicit split: pose01, pose04 unseen, pose07 ignored.
  std::string files;
  for (int f = 0; f < 9; ++f) files += " " + (dir / "poses" / ("pose0" + std::to_string(f) + ".off")).string();
  ASSERT_EQ(run_cli("skin eval" + files + " --methods ssd,mwe,psd --train @" + (dir / "train.txt").string() +
                    " --test pose01,pose04 --bones 3 --out " + (dir / "r").string(), &out), 0) << out;
  EXPECT_NE(out.find("explicit split: 6 training frames (--train), 2 unseen (--test)"), std::string::npos) << out;
  std::ifstream frames(dir / "r" / "skinning_frames.csv");
  std::string line;
  int rows = 0;
  std::getline(frames, line);
  while (std::getline(frames, line)) {
    ++rows;
    EXPECT_EQ(line.find("pose07"), std::string::npos) << "an ignored frame was evaluated: " << line;
  }
  EXPECT_EQ(rows, 8);
  // The same through a folder, with `skin fit` of a pose-space rig.
  ASSERT_EQ(run_cli("skin fit --rest " + (dir / "poses" / "pose00.off").string() + " --poses " +
                    (dir / "poses").string() + " --bones 3 --method eigenskin --cv folds:3 --out " +
                    (dir / "rig.npz").string(), &out), 0) << out;
  EXPECT_NE(out.find("eigenskin rig over ssd"), std::string::npos) << out;
  // Bad input: one clear line, exit 2, nothing half-written.
  auto fails = [&](const std::string& args, const std::string& expect) {
    std::string o;
    EXPECT_EQ(run_cli(args, &o), 2) << args << "\n" << o;
    EXPECT_NE(o.find(expect), std::string::npos) << args << "\n" << o;
    EXPECT_EQ(std::count(o.begin(), o.end(), '\n'), 1) << o;
  };
  const std::string seq = (dir / "poses").string();
  fails("skin eval " + seq + " --train pose00,pose99 --out " + (dir / "x").string(),
        "--train names frame 'pose99', which is not among the 9 frames");
  fails("skin eval " + seq + " --train pose00,pose01 --test pose01 --out " + (dir / "x").string(),
        "frame 'pose01' is in both --train and --test");
  fails("skin eval " + seq + " --train pose00 --methods as --cv none --out " + (dir / "x").string(),
        "as needs at least 2 training frames, 1 given");
  fails("skin eval " + seq + " --train pose00,pose01 --methods psd --cv folds:2 --out " + (dir / "x").string(),
        "a fold leaves 1 training example(s), the method needs 2");
  fails("skin eval " + seq + " --methods ssd,nope --out " + (dir / "x").string(), "unknown skinning method 'nope'");
  fails("skin eval " + seq + " --cv folds:x --out " + (dir / "x").string(), "--cv: expected auto, none, folds:K or last:N");
  fails("skin eval " + seq + " --cv-nesting leaky --out " + (dir / "x").string(), "--cv-nesting: expected full or weights");
  // Full nesting: the report says so and counts the folds' bone fits.
  ASSERT_EQ(run_cli("skin eval " + seq + " --methods ssd,as --cv folds:3 --cv-nesting full --bones 3 --out " +
                    (dir / "n").string(), &out), 0) << out;
  EXPECT_NE(out.find("nesting full"), std::string::npos) << out;
  EXPECT_NE(out.find("and bones, nesting full"), std::string::npos) << out;
  // A frame with other faces (same vertex count): refused unless --per-frame-faces.
  {
    const Mesh m = read_mesh(dir / "poses" / "pose01.off");
    Eigen::MatrixX3i F = m.F;
    std::swap(F(0, 1), F(0, 2));
    write_mesh(dir / "poses" / "pose09.obj", m.V, F);
  }
  fails("skin eval " + seq + " --methods ssd --out " + (dir / "x").string(), "its faces differ from");
  EXPECT_EQ(run_cli("skin eval " + seq + " --methods ssd --per-frame-faces --bones 3 --out " + (dir / "y").string(), &out),
            0) << out;
  // A frame with another vertex count.
  write_mesh(dir / "poses" / "pose10.obj", Eigen::MatrixX3d(Eigen::MatrixX3d::Random(5, 3)),
             Eigen::MatrixX3i(Eigen::MatrixX3i::Zero(1, 3)));
  fails("skin eval " + seq + " --per-frame-faces --out " + (dir / "x").string(), "pose10.obj: 5 vertices, expected");
  EXPECT_FALSE(std::filesystem::exists(dir / "x" / "skinning.csv"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bodymodel
