// `bodymodel skin eval` end to end on a small generated sequence, and its bad-input error.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "core/io/mesh_io.h"
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

}  // namespace
}  // namespace bodymodel
