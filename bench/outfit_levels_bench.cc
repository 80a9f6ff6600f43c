// The body-through-cloth measure of a dressed crowd at the glb's keys, half-way between its samples
// and on LOD1 and LOD2 (docs/assets.md#between-keys-and-levels): each character of a crowd folder
// written by `crowd --outfits default` re-dressed from its rig.npz exactly as `crowd` dressed it
// (its seed, sex and clip frames; the drawn outfit checked against its outfit.json) into a
// temporary folder, with OutfitKit::measure_levels on, and the table printed. A measurement, not a
// test: about 2 min a character on 2 shared cores.
//
//   outfit_levels_bench CROWD [--seed S] [--bvh FILE] [--first N] [--count N] [--lod-corrections]
//                             [--halvings H] [--keep DIR] [--plain] [--vertex-push]
//
// --seed and --bvh must be the crowd's (defaults 5 and CMU 12_03, the demo's); --lod-corrections
// turns on OutfitKit::lod_corrections (as `crowd --lod-corrections`); --halvings sets
// OutfitKit::between_key_halvings (default the kit's; 0 = corrections at the keys only); --keep DIR
// keeps each character's glb as DIR/char_NNN.glb (e.g. for the Khronos validator); --plain leaves
// measure_levels off, so the seconds printed are what `crowd` spends dressing a character (the
// LOD columns are then empty unless refined); --vertex-push turns PushOutOptions::faces off (the
// garment's vertices pushed out, not its triangles' interiors).
#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/bvh.h"
#include "core/io/csv.h"
#include "tools/pipeline/animate_job.h"
#include "tools/pipeline/character.h"
#include "tools/pipeline/outfit_job.h"

using namespace bodymodel;
namespace fs = std::filesystem;

namespace {

struct Args {
  fs::path crowd, bvh, keep;
  uint64_t seed = 5;
  int first = 0, count = 1000, halvings = -1;
  bool lod_corrections = false, plain = false, vertex_push = false;
};

bool parse(int argc, char** argv, Args& a) {
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    auto value = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (s == "--seed") a.seed = std::stoull(value());
    else if (s == "--bvh") a.bvh = value();
    else if (s == "--first") a.first = std::stoi(value());
    else if (s == "--count") a.count = std::stoi(value());
    else if (s == "--halvings") a.halvings = std::stoi(value());
    else if (s == "--keep") a.keep = value();
    else if (s == "--lod-corrections") a.lod_corrections = true;
    else if (s == "--plain") a.plain = true;
    else if (s == "--vertex-push") a.vertex_push = true;
    else if (!s.empty() && s[0] != '-' && a.crowd.empty()) a.crowd = s;
    else return false;
  }
  return !a.crowd.empty();
}

// Totals over the characters: frames over the bound and the worst garment-frame of each measure.
struct Column {
  const char* name;
  int over = 0, frames = 0;
  double worst = 0;
  void add(const ClipPenetration& p, double limit) {
    over += p.frames_over(limit), frames += static_cast<int>(p.fraction.rows());
    if (p.fraction.size()) worst = std::max(worst, p.fraction.maxCoeff());
  }
};

// The clip frames `crowd` played for the character in `dir` (anim/animation.csv's source frames).
std::vector<BoneTransforms> crowd_frames(const fs::path& dir, const CharacterRigFile& ch, const BvhMotion& clip,
                                         const fs::path& bvh, double& frame_time) {
  const ClipPoses poses = retarget_clip(clip, ch.skeleton, data_file("makehuman"), true, bvh.string());
  std::vector<BoneTransforms> frames;
  std::vector<double> times;
  const auto rows = read_csv_file(dir / "anim/animation.csv");
  for (size_t r = 1; r < rows.size(); ++r) {
    frames.push_back(forward_kinematics(ch.skeleton, restrict_pose(poses.poses.at(std::stoul(rows[r].fields.at(1))), ch.driven)));
    times.push_back(std::stod(rows[r].fields.at(2)));
  }
  if (frames.size() < 2) throw InputError("'" + (dir / "anim/animation.csv").string() + "': fewer than 2 frames");
  frame_time = times[1] - times[0];
  return frames;
}

}  // namespace

int run(const Args& a);

int main(int argc, char** argv) {
  Args a;
  if (!parse(argc, argv, a)) {
    fmt::print(stderr, "usage: outfit_levels_bench CROWD [--seed S] [--bvh FILE] [--first N] [--count N] "
                       "[--lod-corrections] [--halvings H] [--keep DIR] [--plain] [--vertex-push]\n");
    return 2;
  }
  if (a.bvh.empty()) a.bvh = data_file("makehuman/motion/cmu/12_03.bvh");
  try {
    return run(a);
  } catch (const std::exception& e) {
    fmt::print(stderr, "outfit_levels_bench: {}\n", e.what());
    return 2;
  }
}

int run(const Args& a) {
  OutfitKit kit = load_outfit_kit("default", data_file("makehuman"));
  kit.measure_levels = !a.plain;
  kit.lod_corrections = a.lod_corrections;
  if (a.halvings >= 0) kit.between_key_halvings = a.halvings;
  if (a.vertex_push) kit.dress.push.faces = false;
  const BvhMotion clip = read_bvh(a.bvh);
  const fs::path tmp = fs::temp_directory_path() / fmt::format("outfit_levels_bench_{}", getpid());
  Column col[] = {{"LOD0 at the keys, as played"}, {"LOD0 at the keys without the corrections"},
                  {"LOD0 half-way between samples"}, {"LOD0 half-way between keys, keys only"},
                  {"LOD1 at the keys"}, {"LOD1 half-way between samples"}, {"LOD1 half-way between keys, keys only"},
                  {"LOD1 at the keys without LOD corrections"}, {"LOD2 at the keys"}, {"LOD2 half-way between samples"},
                  {"LOD2 half-way between keys, keys only"}, {"LOD2 at the keys without LOD corrections"}};
  int chars = 0, targets = 0, lod_targets = 0, added = 0, lod_added = 0;
  size_t smallest = SIZE_MAX, largest = 0;
  double seconds = 0;
  for (int i = a.first; i < a.first + a.count; ++i) {
    const fs::path dir = a.crowd / fmt::format("char_{:03d}", i);
    if (!fs::exists(dir / "rig.npz")) break;
    const nlohmann::json outfit = nlohmann::json::parse(read_text_file(dir / "anim/outfit.json"));
    const CharacterRigFile ch = load_character_rig(dir / "rig.npz");
    double frame_time = 0;
    const std::vector<BoneTransforms> frames = crowd_frames(dir, ch, clip, a.bvh, frame_time);
    const fs::path out = tmp / dir.filename();
    fs::create_directories(out);
    const auto t0 = std::chrono::steady_clock::now();
    const DressedCharacterResult r = write_dressed_character(kit, ch, outfit["sex"] == "male",
                                                             a.seed * 1000003ull + static_cast<uint64_t>(i), frames,
                                                             frame_time, out);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    bool same = r.drawn.items.size() == outfit["items"].size();
    for (size_t k = 0; same && k < r.drawn.items.size(); ++k) same = r.drawn.items[k].asset == outfit["items"][k]["asset"];
    if (!same) {
      fmt::print(stderr, "{}: the outfit drawn is not the crowd's (another --seed?)\n", dir.string());
      fs::remove_all(tmp);
      return 2;
    }
    const ClipPenetration none;
    auto at = [&](const std::vector<ClipPenetration>& v, size_t k) { return k < v.size() ? &v[k] : &none; };
    const auto& u = r.between_keys_unrefined;   // "keys only": before samples were added (refined levels)
    const ClipPenetration* p[] = {&r.penetration, &r.uncorrected, &r.between_keys, at(u, 0),
                                  at(r.lod_penetration, 0), at(r.lod_between, 0), at(u, 1), at(r.lod_uncorrected, 0),
                                  at(r.lod_penetration, 1), at(r.lod_between, 1), at(u, 2), at(r.lod_uncorrected, 1)};
    std::string line;
    for (size_t k = 0; k < std::size(col); ++k) {
      col[k].add(*p[k], r.limit);
      line += fmt::format(" {} ({:.2f} %)", p[k]->frames_over(r.limit), p[k]->fraction.size() ? 100 * p[k]->fraction.maxCoeff() : 0.0);
    }
    if (!a.keep.empty()) {
      fs::create_directories(a.keep);
      fs::copy_file(out / "dressed.glb", a.keep / (dir.filename().string() + ".glb"), fs::copy_options::overwrite_existing);
    }
    fs::remove_all(out);
    fmt::print("{} {}:{}; {} + {} targets ({} + {} samples between keys), {:.2f} MB, {:.0f} s\n", dir.filename().string(),
               outfit["sex"].get<std::string>(), line, r.morph_targets, r.lod_morph_targets, r.samples_added,
               r.lod_samples_added, r.glb_bytes / 1e6, s);
    std::fflush(stdout);
    ++chars, targets += r.morph_targets, lod_targets += r.lod_morph_targets, added += r.samples_added;
    lod_added += r.lod_samples_added, seconds += s;
    smallest = std::min(smallest, r.glb_bytes), largest = std::max(largest, r.glb_bytes);
  }
  fs::remove_all(tmp);
  if (chars == 0) {
    fmt::print(stderr, "{} has no char_{:03d}/rig.npz\n", a.crowd.string(), a.first);
    return 2;
  }
  fmt::print("\n{} characters (columns per character above in this order); frames with a garment over 1 % of its "
             "vertices more than 2 mm inside the body, of frames, worst garment-frame:\n",
             chars);
  for (const Column& c : col) fmt::print("| {} | {} of {} | {:.2f} % |\n", c.name, c.over, c.frames, 100 * c.worst);
  fmt::print("morph targets: LOD0 {} ({} samples between keys), LOD1 + LOD2 {} ({}); dressed.glb {:.2f}-{:.2f} MB; "
             "{:.0f} s dressing and measuring ({:.0f} s a character)\n",
             targets, added, lod_targets, lod_added, smallest / 1e6, largest / 1e6, seconds, seconds / chars);
  return 0;
}
