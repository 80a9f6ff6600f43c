// The body-through-cloth measure half-way between the glb's keys and on LOD1 and LOD2
// (OutfitKit::measure_levels, docs/assets.md#between-keys-and-levels), on a crowd written by
// `crowd --outfits default` (the demo's model): each character re-dressed from its rig.npz as
// `crowd` dressed it (the same seed, sex and clip frames; the drawn outfit checked against its
// outfit.json) into a temporary folder. Needs BODYMODEL_LEVELS_CROWD=DIR (a crowd's output folder
// made with --seed BODYMODEL_LEVELS_SEED, default 5, and the clip BODYMODEL_LEVELS_BVH, default
// CMU 12_03); skipped otherwise. BODYMODEL_LEVELS_COUNT limits the characters and
// BODYMODEL_LEVELS_FIRST skips the first ones; BODYMODEL_LEVELS_LOD_CORRECTIONS (any value) turns
// on OutfitKit::lod_corrections.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/data_path.h"
#include "core/io/atomic_write.h"
#include "core/io/bvh.h"
#include "core/io/csv.h"
#include "support/fixtures.h"
#include "tools/pipeline/animate_job.h"
#include "tools/pipeline/character.h"
#include "tools/pipeline/outfit_job.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

std::string env_or(const char* name, const std::string& fallback) {
  const char* v = std::getenv(name);
  return v && *v ? v : fallback;
}

TEST(OutfitLevels, DemoCrowdBetweenKeysAndOnTheLevels) {
  const std::string crowd = env_or("BODYMODEL_LEVELS_CROWD", "");
  if (crowd.empty()) GTEST_SKIP() << "set BODYMODEL_LEVELS_CROWD to a crowd folder written with --outfits default";
  const uint64_t crowd_seed = std::stoull(env_or("BODYMODEL_LEVELS_SEED", "5"));
  const int count = std::stoi(env_or("BODYMODEL_LEVELS_COUNT", "1000"));
  const fs::path bvh = env_or("BODYMODEL_LEVELS_BVH", data_file("makehuman/motion/cmu/12_03.bvh").string());
  OutfitKit kit = load_outfit_kit("default", data_file("makehuman"));
  kit.measure_levels = true;
  kit.lod_corrections = std::getenv("BODYMODEL_LEVELS_LOD_CORRECTIONS") != nullptr;   // default off, as in the kit
  const BvhMotion clip = read_bvh(bvh);
  fixtures::TempDir tmp;
  // keys, uncorrected, between, LOD1, LOD2, LOD1 and LOD2 without their corrections
  int chars = 0, keys = 0, mids = 0, over[7] = {0, 0, 0, 0, 0, 0, 0}, lod_targets = 0;
  double worst[7] = {0, 0, 0, 0, 0, 0, 0};
  size_t largest = 0;
  const int first = std::stoi(env_or("BODYMODEL_LEVELS_FIRST", "0"));
  for (int i = first; i < first + count; ++i) {
    const fs::path dir = fs::path(crowd) / fmt::format("char_{:03d}", i);
    if (!fs::exists(dir / "rig.npz")) break;
    const nlohmann::json outfit = nlohmann::json::parse(read_text_file(dir / "anim/outfit.json"));
    const CharacterRigFile ch = load_character_rig(dir / "rig.npz");
    const ClipPoses poses = retarget_clip(clip, ch.skeleton, data_file("makehuman"), true, bvh.string());
    std::vector<BoneTransforms> frames;
    std::vector<double> times;
    const auto rows = read_csv_file(dir / "anim/animation.csv");
    for (size_t r = 1; r < rows.size(); ++r) {
      frames.push_back(forward_kinematics(ch.skeleton, restrict_pose(poses.poses.at(std::stoul(rows[r].fields.at(1))), ch.driven)));
      times.push_back(std::stod(rows[r].fields.at(2)));
    }
    ASSERT_GE(frames.size(), 2u);
    const fs::path out = tmp / dir.filename();
    fs::create_directories(out);
    const DressedCharacterResult r = write_dressed_character(kit, ch, outfit["sex"] == "male", crowd_seed * 1000003ull + i,
                                                             frames, times[1] - times[0], out);
    ASSERT_EQ(r.drawn.items.size(), outfit["items"].size()) << dir;
    for (size_t k = 0; k < r.drawn.items.size(); ++k) ASSERT_EQ(r.drawn.items[k].asset, outfit["items"][k]["asset"]) << dir;
    const ClipPenetration* p[7] = {&r.penetration, &r.uncorrected, &r.between_keys, &r.lod_penetration.at(0),
                                   &r.lod_penetration.at(1), &r.lod_uncorrected.at(0), &r.lod_uncorrected.at(1)};
    std::string line;
    for (int k = 0; k < 7; ++k) {
      const int o = p[k]->frames_over(r.limit);
      const double w = p[k]->fraction.size() ? p[k]->fraction.maxCoeff() : 0;
      over[k] += o, worst[k] = std::max(worst[k], w);
      line += fmt::format(" {} ({:.2f} %)", o, 100 * w);
    }
    // BODYMODEL_LEVELS_KEEP=DIR keeps each glb (char_NNN.glb), e.g. for the Khronos validator.
    if (const char* keep = std::getenv("BODYMODEL_LEVELS_KEEP"); keep && *keep)
      fs::copy_file(out / "dressed.glb", fs::path(keep) / (dir.filename().string() + ".glb"),
                    fs::copy_options::overwrite_existing);
    std::printf("%s %s: keys / uncorrected / between keys / LOD1 / LOD2 / LOD1, LOD2 uncorrected over the bound:%s; "
                "%d + %d targets, %.2f MB\n",
                dir.filename().string().c_str(), outfit["sex"].get<std::string>().c_str(), line.c_str(), r.morph_targets,
                r.lod_morph_targets, r.glb_bytes / 1e6);
    lod_targets += r.lod_morph_targets;
    std::fflush(stdout);
    ++chars, keys += static_cast<int>(frames.size()), mids += static_cast<int>(frames.size()) - 1;
    largest = std::max(largest, r.glb_bytes);
    EXPECT_LE(r.glb_bytes, 4u << 20);
  }
  ASSERT_GT(chars, 0) << crowd << " has no char_000/rig.npz";
  std::printf("%d characters: frames over 1 %% at 2 mm (worst garment-frame): at the keys %d of %d (%.2f %%), "
              "uncorrected %d (%.2f %%), half-way between keys %d of %d (%.2f %%), LOD1 %d of %d (%.2f %%), LOD2 %d (%.2f %%); "
              "LOD1, LOD2 without their corrections %d (%.2f %%), %d (%.2f %%), %d LOD targets; largest glb %.2f MB\n",
              chars, over[0], keys, 100 * worst[0], over[1], 100 * worst[1], over[2], mids, 100 * worst[2], over[3], keys,
              100 * worst[3], over[4], 100 * worst[4], over[5], 100 * worst[5], over[6], 100 * worst[6], lod_targets,
              largest / 1e6);
}

}  // namespace
}  // namespace bodymodel
