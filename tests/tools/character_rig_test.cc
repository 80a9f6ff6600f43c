// A character end to end on a small model made in-test: MakeHuman subjects in the standard
// pose and a few poses (posed by linear blend skinning with MakeHuman's weights, as synth-db
// poses its truth meshes; joint angles as pose labels), the full model built from them, a
// character pose-morphed into a small range of motion and rigged (SSD, AS, MWE), then
// `bodymodel animate` on every CMU clip with the saved rig.
//   - MWE reproduces held-out pose morphs better than SSD (mean vertex error, mm);
//   - `bodymodel animate` on every clip of makehuman/motion/cmu/ (every 3rd frame: --fps 10)
//     keeps every edge within 3 × its rest length (the check,
//     tools/pipeline/deformation_check.h) and below the template weights' own stretch.
//     Flipped triangles are NOT yet zero: after the retarget's limb twist split and undriven
//     CMU fingers (core/retarget.h) the armpit (upperarm02, two triangles per arm) and the groin
//     crease (spine05) still fold under linear blend skinning in most frames. The test bounds the
//     worst frame (see kMaxFlipped) and requires fewer flips than the template weights.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <sstream>

#include "core/io/bvh.h"
#include "core/makehuman.h"
#include "core/retarget.h"
#include "model/model_rig.h"
#include "support/run_cli.h"
#include "support/small_full_model.h"
#include "tools/pipeline/character.h"
#include "tools/pipeline/character_file.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

const MakeHuman& makehuman() {
  static MakeHuman mh = MakeHuman::load();
  return mh;
}

// Poses the subjects are seen in: a few MakeHuman static poses and CMU frames.
std::vector<Pose> model_pose_pool(const Skeleton& sk) {
  const MakeHuman& mh = makehuman();
  std::vector<Pose> out;
  for (const char* name : {"fight01", "run01", "fly01", "standing02", "tpose"})
    out.push_back(bvh_frame_to_pose(read_bvh(mh.pose_file(name)), 0, sk));
  for (const char* clip : {"02_02", "12_03"}) {
    BvhMotion m = read_bvh(mh.directory() / "motion" / "cmu" / (std::string(clip) + ".bvh"));
    Retargeter r(m, sk, RetargetMap::for_clip(m, mh.directory()));
    for (int k = 0; k < 3; ++k) out.push_back(r.pose((2 * k + 1) * m.frame_count() / 6));
  }
  return out;
}

struct SmallWorld {
  std::shared_ptr<const BodyModel> model;
  Eigen::MatrixX3d body;
  CharacterExamples examples;
  CharacterRigs rigs;
  std::vector<RigErrorRow> errors;
};

const SmallWorld& world() {
  static std::unique_ptr<SmallWorld> w = [] {
    auto out = std::make_unique<SmallWorld>();
    const MakeHuman& mh = makehuman();
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0.2, 0.8);
    const int subjects = 10;
    std::vector<Pose> pool;
    std::vector<bodymodel::testing::SmallFullModelSubject> rows;
    for (int s = 0; s < subjects; ++s) {
      MacroSettings ms;
      ms.gender = s % 2 ? 0.95 : 0.05;
      ms.weight = u(rng);
      ms.height = u(rng);
      ms.muscle = u(rng);
      MakeHuman::Body b = mh.body(ms);
      if (pool.empty()) pool = model_pose_pool(b.skeleton);
      const double height = b.mesh.V.col(1).maxCoeff() - b.mesh.V.col(1).minCoeff();
      // Each subject in 4 poses of the pool (rotating through it).
      std::vector<Pose> poses;
      for (int k = 0; k < 4; ++k) poses.push_back(pool[(s * 4 + k) % pool.size()]);
      rows.push_back({std::move(b), height / 10, 50 + 40 * ms.weight, std::move(poses)});
    }
    out->body = mh.body(MacroSettings{}).mesh.V;
    BodyModel model = bodymodel::testing::build_small_full_model(mh, rows);
    out->model = std::make_shared<const BodyModel>(std::move(model));

    CharacterOptions o;
    o.range_of_motion.excluded_static = {"benchmark", "gym01",      "sit01",      "fight02",    "fight03",
                                         "fly01",     "standing01", "standing02", "standing03", "standing04",
                                         "standing05"};
    o.range_of_motion.training_frames_per_clip = 3;
    o.range_of_motion.held_out_frames_per_clip = 1;
    o.range_of_motion.training_blends = 4;
    o.range_of_motion.held_out_blends = 3;
    out->examples = make_character_examples(*out->model, out->body, mh.directory(), o);
    out->rigs = fit_character_rigs(out->examples, o);
    out->errors = evaluate_character_rigs(out->examples, out->rigs);
    return out;
  }();
  return *w;
}

const RigErrorRow& row(const std::vector<RigErrorRow>& rows, const std::string& method, const std::string& split) {
  for (auto& r : rows)
    if (r.method == method && r.split == split) return r;
  static RigErrorRow none;
  ADD_FAILURE() << "no row " << method << "/" << split;
  return none;
}

// Fold repair bounds (see TrainingMorphsAreFoldRepaired; the aim is 0).
constexpr int kMaxFlippedAfterRepair = 480;   // measured 1870 -> 411
constexpr int kMaxFlippedPoseAfterRepair = 80;  // measured 64 (run01: 331 -> 64)

TEST(CharacterRig, MweReproducesHeldOutPoseMorphsBetterThanSsd) {
  const SmallWorld& w = world();
  int held = 0;
  for (auto& p : w.examples.poses) held += p.held_out;
  ASSERT_GE(held, 3);
  for (auto& r : w.errors)
    std::cout << r.method << " " << r.split << " poses " << r.poses << " mean " << r.mean_mm << " max " << r.max_mm
              << " mm\n";
  // Mean AND max over the held-out poses, against every SSD rig.
  const RigErrorRow& mwe = row(w.errors, "mwe", "held_out");
  for (const char* ssd : {"lbs", "smooth_lbs", "template_lbs"}) {
    EXPECT_LT(mwe.mean_mm, row(w.errors, ssd, "held_out").mean_mm) << ssd;
    EXPECT_LT(mwe.max_mm, row(w.errors, ssd, "held_out").max_mm) << ssd;
  }
  // MWE learns the refinement: on its training poses it is closer still.
  EXPECT_LT(row(w.errors, "mwe", "train").mean_mm, row(w.errors, "smooth_lbs", "train").mean_mm);
}

// The range of motion is fold-repaired before the rigs are fitted (CharacterOptions::repair_folds):
// the pose morphs fold the armpits and groin (flip test of `animate`), the repair removes most.
TEST(CharacterRig, TrainingMorphsAreFoldRepaired) {
  const SmallWorld& w = world();
  const CharacterExamples& ex = w.examples;
  ASSERT_EQ(ex.flipped_before.size(), ex.poses.size());
  int before = 0, after = 0, worst = 0;
  for (size_t p = 0; p < ex.poses.size(); ++p) {
    EXPECT_LE(ex.flipped_after[p], ex.flipped_before[p]) << ex.poses[p].name;
    before += ex.flipped_before[p];
    after += ex.flipped_after[p];
    worst = std::max(worst, ex.flipped_after[p]);
    std::cout << ex.poses[p].name << ": flipped " << ex.flipped_before[p] << " -> " << ex.flipped_after[p] << "\n";
  }
  std::cout << "range of motion: flipped " << before << " -> " << after << ", worst pose " << worst << "\n";
  EXPECT_EQ(ex.flipped_before[0], 0);   // the rest pose
  EXPECT_GT(before, 0);
  EXPECT_LE(after, kMaxFlippedAfterRepair);
  EXPECT_LE(worst, kMaxFlippedPoseAfterRepair);
}

// Flipped triangles in the worst frame of any clip (measured 18 / 18 / 22 on 02_02 / 03_03 /
// 12_03; over the sampled frames the template weights flip 731 / 731 / 1345, the rig 295 / 295 /
// 761).
constexpr int kMaxFlipped = 32;

TEST(CharacterRig, AnimateOnCmuClipsKeepsEdgesWithinThreeTimesRest) {
  const SmallWorld& w = world();
  const fs::path dir = fs::temp_directory_path() / ("bodymodel_character_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  CharacterRigFile f;
  f.rig = w.rigs.mwe;
  f.lbs = w.rigs.smooth_lbs;
  f.template_lbs = w.rigs.template_lbs;
  f.F = w.examples.F;
  f.skeleton = w.examples.skeleton;
  f.driven = w.examples.driven;
  f.character = {{"test", true}};
  save_character_rig(dir / "rig.npz", f);
  std::vector<fs::path> clips;
  for (auto& e : fs::directory_iterator(makehuman().directory() / "motion" / "cmu"))
    if (e.path().extension() == ".bvh") clips.push_back(e.path());
  std::sort(clips.begin(), clips.end());
  ASSERT_GE(clips.size(), 3u);
  for (const fs::path& bvh : clips) {
    const std::string clip = bvh.stem().string();
    SCOPED_TRACE(clip);
    const fs::path out = dir / clip;
    const auto r = fixtures::run_cli("animate '" + (dir / "rig.npz").string() + "' --bvh '" + bvh.string() +
                                     "' --out '" + out.string() + "' --fps 10 --format none");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    std::ifstream csv(out / "animation.csv");
    std::string line;
    std::getline(csv, line);
    ASSERT_EQ(line.rfind("frame,clip_frame,time_s,max_edge_ratio,min_edge_ratio,flipped", 0), 0u) << line;
    int frames = 0;
    double worst = 0;
    int flipped = 0, flipped_total = 0, template_flipped_total = 0;
    double template_worst = 0;
    std::string where;
    while (std::getline(csv, line)) {
      std::stringstream ss(line);
      std::string cell;
      std::vector<std::string> c;
      while (std::getline(ss, cell, ',')) c.push_back(cell);
      ASSERT_GE(c.size(), 15u) << line;
      if (std::stod(c[3]) > worst && c.size() >= 15) where = "clip frame " + c[1] + ", vertex " + c[11] + ", bone " + c[14];
      worst = std::max(worst, std::stod(c[3]));
      template_worst = std::max(template_worst, std::stod(c[8]));
      flipped = std::max(flipped, std::stoi(c[5]));
      flipped_total += std::stoi(c[5]);
      template_flipped_total += std::stoi(c[9]);
      ++frames;
    }
    EXPECT_GE(frames, 10);
    EXPECT_LE(worst, 3.0) << where;
    EXPECT_LT(worst, template_worst) << where;
    EXPECT_LE(flipped, kMaxFlipped) << where;  // the target: 0
    EXPECT_LT(flipped_total, 0.75 * template_flipped_total);
    std::cout << clip << ": " << frames << " frames, max edge ratio " << worst << " (" << where
              << "), template weights " << template_worst << ", flipped worst frame " << flipped << ", total "
              << flipped_total << " (template weights " << template_flipped_total << ")\n";
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bodymodel
