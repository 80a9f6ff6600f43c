// A dressed character's glb (`bodymodel dress --out .glb`) in a real browser: three.js's
// GLTFLoader in headless Chromium loads it, poses it with its clip (GPU skinning) and draws it
// (tests/assets/dress_browser.html); the page reports the skinned primitives, the clip, and the
// pixels drawn in the garments' blue and in warm colours (skin, hair, shoes). Skipped, saying
// why, without chromium or three.js (scripts/setup.sh installs both; BODYMODEL_THREE names a
// three package folder elsewhere).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <regex>

#include "core/data_path.h"
#include "support/fixtures.h"
#include "support/browser.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;
using fixtures::run_cli;

TEST(DressBrowser, ThreeJsLoadsPosesAndDrawsTheDressedGlb) {
  const std::string chromium = fixtures::chromium_path();
  if (!fs::exists(chromium)) GTEST_SKIP() << chromium << " not found (Debian package chromium)";
  if (!fs::exists(fixtures::three_dir() / "examples/jsm/loaders/GLTFLoader.js"))
    GTEST_SKIP() << fixtures::three_dir() << " has no three.js (scripts/setup.sh; or set BODYMODEL_THREE)";
  if (!fs::exists(BODYMODEL_EXE)) GTEST_SKIP() << "bodymodel not built";
  try {
    if (!fs::is_directory(data_root() / "makehuman" / "assets")) GTEST_SKIP() << "makehuman/assets not found";
  } catch (const std::exception& e) {
    GTEST_SKIP() << e.what();
  }
  fixtures::TempDir tmp;
  const auto r = run_cli("dress --gender 1 --outfit male_casualsuit01,shoes01,short02 --pose fight01 --out " +
                         (tmp / "dressed.glb").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  fs::copy_file(fs::path(__FILE__).parent_path() / "dress_browser.html", tmp / "index.html");
  fs::create_directory_symlink(fixtures::three_dir(), tmp / "three");
  const std::string dom = fixtures::headless_dom("file://" + (tmp / "index.html").string());
  std::smatch m;
  ASSERT_TRUE(std::regex_search(dom, m, std::regex("<title>([^<]*)</title>"))) << dom.substr(0, 500);
  const std::string title = m[1];
  std::printf("%s\n", title.c_str());
  ASSERT_TRUE(std::regex_search(title, m, std::regex(
      "ok prims=(\\d+) animations=(\\d+) drawn=(\\d+) blue=(\\d+) warm=(\\d+)"))) << title;
  const int prims = std::stoi(m[1]), anims = std::stoi(m[2]), drawn = std::stoi(m[3]), blue = std::stoi(m[4]),
            warm = std::stoi(m[5]);
  EXPECT_EQ(prims, 4);      // body, suit, shoes, hair
  EXPECT_EQ(anims, 1);
  EXPECT_GT(drawn, 5000);   // of 150 000 pixels: a person, not an empty frame
  EXPECT_GT(blue, drawn / 3);  // mostly the suit
  EXPECT_GT(warm, 200);     // the face, hands, hair and shoes
}

}  // namespace
}  // namespace bodymodel
