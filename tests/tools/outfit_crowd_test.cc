// A small dressed crowd (tools/pipeline/outfit_job.h, what `crowd --outfits` writes per
// character): characters with only their 13380 skin vertices and SSD weights, as a model's
// characters are, dressed in outfits drawn from the default street, walking CMU 02_02. Checks
// the body-through-cloth bound as the glb plays the clip (no frame with more than 1 % of a
// garment's vertices over 2 mm inside), the glb's size, and that each glb has the outfit's parts
// with the drawn colours; the frames over the bound without the per-frame garment corrections
// (baked as morph targets) are printed alongside. BODYMODEL_OUTFIT_CROWD=N (default 3) and BODYMODEL_OUTFIT_STRIDE=k
// (every k-th clip frame, default 24) scale it up for the figures in docs/assets.md.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>

#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>  // declarations only: the implementation is in skinning/gltf_export.cc

#include "core/data_path.h"
#include "core/io/atomic_write.h"
#include "core/io/bvh.h"
#include "core/makehuman.h"
#include "core/retarget.h"
#include "skinning/skinning_rig.h"
#include "support/fixtures.h"
#include "support/makehuman_assets.h"
#include "tools/pipeline/outfit_job.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

int env_int(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v && *v ? std::atoi(v) : fallback;
}

TEST(OutfitCrowd, DressedCharactersKeepTheBodyInsideTheirClothesThroughAClip) {
  const fs::path mh_dir = fixtures::makehuman_with_assets();
  if (mh_dir.empty()) GTEST_SKIP() << "makehuman/assets not found";
  const MakeHuman mh = MakeHuman::load(mh_dir);
  OutfitKit kit = load_outfit_kit("default", mh_dir);
  // Experiments (not the defaults checked here): BODYMODEL_OUTFIT_NEAR / _FAR / _CLEARANCE in mm.
  kit.dress.skin_weights_near = env_int("BODYMODEL_OUTFIT_NEAR", static_cast<int>(kit.dress.skin_weights_near));
  kit.dress.skin_weights_far = env_int("BODYMODEL_OUTFIT_FAR", static_cast<int>(kit.dress.skin_weights_far));
  kit.dress.push.clearance = env_int("BODYMODEL_OUTFIT_CLEARANCE", static_cast<int>(kit.dress.push.clearance));
  const BvhMotion clip = read_bvh(mh_dir / "motion/cmu/02_02.bvh");
  const int count = env_int("BODYMODEL_OUTFIT_CROWD", 3), stride = env_int("BODYMODEL_OUTFIT_STRIDE", 24);
  const int nb = MakeHuman::kBodyVertexCount;
  fixtures::TempDir tmp;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  int frames_total = 0, frames_over = 0, frames_over_uncorrected = 0, targets = 0;
  double worst = 0, worst_uncorrected = 0;
  size_t max_bytes = 0;
  const int first = env_int("BODYMODEL_OUTFIT_FIRST", 0);  // reproduce one character of a larger run
  for (int i = 0; i < first + count; ++i) {
    MacroSettings s;
    s.gender = i % 2 ? 0.85 + 0.15 * u(rng) : 0.15 * u(rng);
    s.weight = 0.2 + 0.6 * u(rng), s.height = 0.2 + 0.6 * u(rng), s.muscle = 0.3 + 0.4 * u(rng);
    s.age = 0.4 + 0.4 * u(rng);
    if (i < first) continue;
    const Eigen::MatrixX3d full = mh.build_vertices(s);
    // A character as a model makes it: skin only, with its SSD weights (4 influences).
    CharacterRigFile ch;
    ch.skeleton = mh.skeleton(full);
    ch.F = mh.body_faces();
    ch.lbs = lbs_rig_from_weights(full.topRows(nb), Eigen::MatrixXd(mh.weights().topRows(nb)), 4);
    const Retargeter rt(clip, ch.skeleton, RetargetMap::for_clip(clip, mh.directory()));
    std::vector<BoneTransforms> frames;
    for (int f = 0; f < rt.frame_count(); f += stride) frames.push_back(forward_kinematics(ch.skeleton, rt.pose(f)));
    const fs::path dir = tmp / ("char_" + std::to_string(i));
    fs::create_directories(dir);
    const DressedCharacterResult r = write_dressed_character(kit, ch, i % 2, 1000003ull + i, frames, 1.0 / 10, dir);

    const int over = r.penetration.frames_over(0.01);
    const double w = r.penetration.fraction.size() ? r.penetration.fraction.maxCoeff() : 0;
    std::string items;
    for (const DrawnItem& it : r.drawn.items) items += " " + it.asset;
    items += ";";
    for (size_t g = 0; g < r.penetration.garments.size(); ++g)
      items += " " + r.penetration.garments[g] + " " +
               std::to_string(static_cast<int>(std::lround(1e4 * r.penetration.fraction.col(g).maxCoeff()))) + "bp";
    const int over_u = r.uncorrected.frames_over(0.01);
    const double w_u = r.uncorrected.fraction.size() ? r.uncorrected.fraction.maxCoeff() : 0;
    std::printf("char %d (%s):%s; %d frames, %d over 1 %%, worst %.2f %% (without the clip corrections %d, %.2f %%; "
                "%d morph targets, %lld displacements), %.2f MB\n",
                i, i % 2 ? "male" : "female", items.c_str(), static_cast<int>(frames.size()), over, 100 * w, over_u,
                100 * w_u, r.morph_targets, r.corrected_vertices, r.glb_bytes / 1e6);
    frames_total += static_cast<int>(frames.size()), frames_over += over, frames_over_uncorrected += over_u;
    worst = std::max(worst, w), worst_uncorrected = std::max(worst_uncorrected, w_u);
    targets += r.morph_targets;
    max_bytes = std::max(max_bytes, r.glb_bytes);
    EXPECT_EQ(over, 0) << "character " << i;
    EXPECT_LE(r.glb_bytes, 4u << 20);

    // The glb: one primitive and material per part (body first) at LOD0, the drawn colours, the clip.
    const std::string bytes = read_text_file(dir / "dressed.glb");
    tinygltf::Model m;
    tinygltf::TinyGLTF loader;
    std::string err, warn;
    ASSERT_TRUE(loader.LoadBinaryFromMemory(&m, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                            static_cast<unsigned>(bytes.size())))
        << err;
    ASSERT_EQ(m.materials.size(), r.drawn.items.size() + 1);
    ASSERT_EQ(m.meshes.size(), 3u);   // the levels of detail (tests/tools/outfit_lods_test.cc); LOD0 first
    EXPECT_EQ(m.meshes[0].primitives.size(), r.drawn.items.size() + 1);
    EXPECT_EQ(m.animations.size(), 1u);
    auto expect_colour = [&](const tinygltf::Material& mat, const Eigen::Vector3d& c) {
      const auto& f = mat.pbrMetallicRoughness.baseColorFactor;
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(f[k], c[k], 1e-6) << mat.name;
    };
    EXPECT_EQ(m.materials[0].name, "body");
    expect_colour(m.materials[0], r.drawn.skin);
    for (size_t k = 0; k < r.drawn.items.size(); ++k) {
      EXPECT_EQ(m.materials[k + 1].name, r.drawn.items[k].asset);
      expect_colour(m.materials[k + 1], r.drawn.items[k].colour);
    }
    EXPECT_TRUE(fs::exists(dir / "outfit.json") && fs::exists(dir / "penetration.csv"));
  }
  std::printf("%d characters, %d frames: %d over 1 %% at 2 mm, worst garment-frame %.2f %% (without the clip "
              "corrections: %d, %.2f %%; %d morph targets), largest glb %.2f MB\n",
              count, frames_total, frames_over, 100 * worst, frames_over_uncorrected, 100 * worst_uncorrected, targets,
              max_bytes / 1e6);
}

}  // namespace
}  // namespace bodymodel
