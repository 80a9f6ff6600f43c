// "No body colour through a jacket at a fixed frame" (issue 39), checked on pixels drawn by
// three.js in headless Chromium (tests/tools/jacket_browser.html): two MakeHuman women (weights 0.6
// and 0.9) cut to their skin as a model's characters are, each in a short-sleeved suit whose side
// the upper arm sinks through as the arms come down (docs/assets.md#outfits), walking CMU 02_02. At the key where the garment is
// deepest inside the body without the per-frame corrections, the page counts the pixels showing
// visible skin where a garment surface lies more than 2 mm inside the body along the ray: with the
// corrections (as the glb plays them) and, as the control, with the morph weights forced to 0.
// The jacket is the garment above the waist without its edge band (two rings of vertices at the
// collar, hems and sleeve ends, where the cloth's edge sits a few mm into the hidden skin).
// The glb is written with the hidden skin kept (OutfitKit::keep_hidden_skin, both arms), because
// a ray that enters the neck must leave the body before it meets the jacket's back: with the
// hidden skin deleted it never leaves. Skipped, saying why, without chromium, three.js or the data.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <regex>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/io/atomic_write.h"
#include "core/io/bvh.h"
#include "core/makehuman.h"
#include "core/retarget.h"
#include "skinning/skinning_rig.h"
#include "support/browser.h"
#include "support/fixtures.h"
#include "support/makehuman_assets.h"
#include "tools/pipeline/outfit_job.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

const std::string garment = "female_casualsuit02";   // short sleeves over a closed top

// The check on one woman (gender 0.1, the given weight) walking `keys` keys of CMU 02_02 from frame
// `first` (every 12th frame, 0.1 s apart; 0 keys = to the end of the clip).
void check_jacket(const MakeHuman& mh, const OutfitKit& kit, const fs::path& three, double weight, int first,
                  int keys) {
  SCOPED_TRACE(fmt::format("weight {}", weight));
  fixtures::TempDir tmp;
  MacroSettings s;
  s.gender = 0.1;
  s.weight = weight;
  const Eigen::MatrixX3d full = mh.build_vertices(s);
  const int nb = MakeHuman::kBodyVertexCount;
  CharacterRigFile ch;
  ch.skeleton = mh.skeleton(full);
  ch.F = mh.body_faces();
  ch.lbs = lbs_rig_from_weights(full.topRows(nb), Eigen::MatrixXd(mh.weights().topRows(nb)), 4);
  const BvhMotion clip = read_bvh(mh.directory() / "motion/cmu/02_02.bvh");
  const Retargeter rt(clip, ch.skeleton, RetargetMap::for_clip(clip, mh.directory()));
  std::vector<BoneTransforms> frames;
  for (int f = first; f < rt.frame_count() && (keys == 0 || f < first + 12 * keys); f += 12)
    frames.push_back(forward_kinematics(ch.skeleton, rt.pose(f)));
  const double frame_time = 0.1;
  const DressedCharacterResult r = write_dressed_character(kit, ch, false, 7, frames, frame_time, tmp.path);
  ASSERT_EQ(r.parts.back().name, "body_hidden");
  ASSERT_EQ(r.penetration.garments.at(0), garment);   // then the shoes
  // The fixed frame: the key where the garment is deepest inside the body without the corrections.
  Eigen::Index key;
  const double before = r.uncorrected.fraction.col(0).maxCoeff(&key);
  const double after = r.penetration.fraction(key, 0);
  std::printf("weight %.1f, %s at key %ld of %zu: %.2f %% of its vertices over 2 mm inside without the corrections, %.2f %% with "
              "them (%d morph targets)\n",
              weight, garment.c_str(), static_cast<long>(key), frames.size(), 100 * before, 100 * after, r.morph_targets);
  ASSERT_GT(before, 0.01) << "the control must poke through (over the 1 % bound) for the check to mean anything";

  fs::copy_file(fs::path(__FILE__).parent_path() / "jacket_browser.html", tmp / "index.html");
  fs::create_directory_symlink(three, tmp / "three");
  // The jacket: the garment above the posed head of spine03 (mid-abdomen), so that the hands
  // swinging into the shorts and the thighs crossing at the crotch (the body through itself,
  // which no garment correction can remove) are not counted.
  const auto spine = std::find(ch.skeleton.names.begin(), ch.skeleton.names.end(), "spine03");
  ASSERT_NE(spine, ch.skeleton.names.end());
  const int b = static_cast<int>(spine - ch.skeleton.names.begin());
  const double waist = (frames[key][b] * Eigen::Vector3d(ch.skeleton.heads.row(b).transpose())).y() / 1000;   // metres
  const std::string url = fmt::format("file://{}?time={}&garments={}&views=8&size=640&tol=2&edge=2&above={}",
                                      (tmp / "index.html").string(), static_cast<double>(key) * frame_time, garment, waist);
  // BODYMODEL_PIXELS_KEEP=DIR keeps the page, the glb and the URL's query (to look at: ?debug=VIEW).
  if (const char* keep = std::getenv("BODYMODEL_PIXELS_KEEP"); keep && *keep) {
    const fs::path dir = fs::path(keep) / fmt::format("weight{}", weight);
    fs::create_directories(dir);
    for (const char* f : {"index.html", "dressed.glb"}) fs::copy_file(tmp / f, dir / f, fs::copy_options::overwrite_existing);
    write_text_file(dir / "query.txt", url.substr(url.find('?')) + "\n");
  }
  const std::string dom = fixtures::headless_dom(url);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(dom, m, std::regex("<pre id=\"result\"[^>]*>([^<]*)</pre>"))) << dom.substr(0, 800);
  const nlohmann::json j = nlohmann::json::parse(std::string(m[1]));
  std::printf("%s\n", j.dump().c_str());
  ASSERT_TRUE(j.value("ok", false)) << j.dump();
  EXPECT_NEAR(j["morph_weight_sum"].get<double>(), 1.0, 1e-6) << "the key's correction is played";
  const nlohmann::json &c = j["corrected"], &u = j["uncorrected"];
  // Both arms drew the same scene: the garment and the skin on screen, the body wound outward.
  for (const nlohmann::json* a : {&c, &u}) {
    EXPECT_GT((*a)["garment"].get<int>(), 20000);
    EXPECT_GT((*a)["skin"].get<int>(), 5000);
    EXPECT_LT((*a)["inverted"].get<int>(), (*a)["skin"].get<int>() / 100);
  }
  const int through = c["through"].get<int>(), control = u["through"].get<int>();
  std::printf("weight %.1f: body colour through the jacket: %d pixels with the corrections, %d without (of %d jacket pixels, %d "
              "views, %.2f mm a pixel; at the garment's edges, not counted: %d and %d)\n",
              weight, through, control, u["jacket"].get<int>(), j["views"].get<int>(), 1000 * j["metres_per_pixel"].get<double>(),
              c["edge_through"].get<int>(), u["edge_through"].get<int>());
  // The check (about 0.02 % of the jacket's pixels), and the control it must fail on.
  constexpr int kBound = 30;
  EXPECT_GT(c["jacket"].get<int>(), 50000);
  EXPECT_LE(through, kBound);
  EXPECT_GT(control, 5 * kBound) << "without the corrections the skin must show through (the control)";
}

// Two women: weight 0.6 over the whole clip, and a heavier one (weight 0.9) over the five keys
// around her deepest (key 18 of the whole clip; 5 keys keep the test short). With the vertex push
// alone (PushOutOptions::faces off) the heavier one shows patches of upper arm through the
// sleeve's side and fails (docs/assets.md#body-colour-through-a-jacket); the kit's default push
// (faces on, as in the crowd) must clear them.
TEST(OutfitPixels, NoBodyColourThroughTheJacketAtAFixedFrame) {
  const std::string chromium = fixtures::chromium_path();
  if (!fs::exists(chromium)) GTEST_SKIP() << chromium << " not found (Debian package chromium)";
  const fs::path three = fixtures::three_dir();
  if (!fs::exists(three / "examples/jsm/loaders/GLTFLoader.js"))
    GTEST_SKIP() << three << " has no three.js (scripts/setup.sh; or set BODYMODEL_THREE)";
  const fs::path mh_dir = fixtures::makehuman_with_assets();
  if (mh_dir.empty()) GTEST_SKIP() << "makehuman/assets not found";
  fixtures::TempDir tmp;
  write_text_file(tmp / "outfits.json",
                  "{\"female\": {\"suit\": [{\"asset\": \"" + garment + "\"}], \"shoes\": [{\"asset\": \"shoes01\"}]},\n"
                  " \"male\": {\"suit\": [{\"asset\": \"male_casualsuit01\"}]}}\n");
  const MakeHuman mh = MakeHuman::load(mh_dir);
  OutfitKit kit = load_outfit_kit((tmp / "outfits.json").string(), mh_dir);
  kit.lods = false;
  kit.keep_hidden_skin = true;
  check_jacket(mh, kit, three, 0.6, 0, 0);
  check_jacket(mh, kit, three, 0.9, 12 * 16, 5);
}

}  // namespace
}  // namespace bodymodel
