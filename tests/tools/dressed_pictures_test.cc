// The dressed crowd's pictures in the demo's report (tools/pipeline/dressed_pictures.h): two
// MakeHuman bodies cut to their skin with their SSD weights (as a model's characters are), dressed
// by the default outfits with levels of detail (write_dressed_character, the rest pose), then the
// line-up, the LOD chain and the close-up rendered from their dressed.glb files and written as PNG.
// Checks that each picture is not blank and shows what was drawn: each character's cloth colour
// in its cell of the line-up, the skin and hair colours in the close-up, every level of detail
// filling about the same area as the full one.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#define STB_IMAGE_IMPLEMENTATION
#include <stb/stb_image.h>

#include "core/data_path.h"
#include "core/error.h"
#include "core/makehuman.h"
#include "skinning/skinning_rig.h"
#include "support/fixtures.h"
#include "support/makehuman_assets.h"
#include "tools/pipeline/dressed_pictures.h"
#include "tools/pipeline/outfit_job.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

Eigen::Vector3d rgb_of_hex(const std::string& hex) {
  const unsigned v = static_cast<unsigned>(std::stoul(hex.substr(1), nullptr, 16));
  return Eigen::Vector3d((v >> 16) & 255, (v >> 8) & 255, v & 255) / 255.0;
}

struct Coverage {
  int pixels = 0, drawn = 0, matching = 0;  // all, not background, shaded versions of the colour
  double stddev = 0;                        // of the drawn pixels' values
};

// Pixels of columns [x0, x1) that are the colour `c` (sRGB) under the renderer's shading, which
// scales a colour by 0.25-1.1: within 4° of its direction in RGB and at least 20 % of its brightness.
Coverage coverage(const Image& img, int x0, int x1, const Eigen::Vector3d& c) {
  Coverage r;
  double sum = 0, sum2 = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = x0; x < x1; ++x) {
      ++r.pixels;
      const uint8_t* p = &img.rgb[(size_t(y) * img.width + x) * 3];
      if (p[0] == 255 && p[1] == 255 && p[2] == 255) continue;
      ++r.drawn;
      const Eigen::Vector3d q(p[0] / 255.0, p[1] / 255.0, p[2] / 255.0);
      sum += q.sum(), sum2 += q.squaredNorm();
      if (q.norm() < 0.2 * c.norm() || q.norm() < 1e-3) continue;
      if (std::acos(std::clamp(q.normalized().dot(c.normalized()), -1.0, 1.0)) < 4 * M_PI / 180) ++r.matching;
    }
  if (r.drawn) r.stddev = std::sqrt(std::max(0.0, sum2 / (3.0 * r.drawn) - std::pow(sum / (3.0 * r.drawn), 2)));
  return r;
}

TEST(DressedPictures, LineupLodsAndCloseUpShowTheDrawnOutfits) {
  const fs::path mh_dir = fixtures::makehuman_with_assets();
  if (mh_dir.empty()) GTEST_SKIP() << "makehuman/assets not found";
  const MakeHuman mh = MakeHuman::load(mh_dir);
  const OutfitKit kit = load_outfit_kit("default", mh_dir);
  const int nb = MakeHuman::kBodyVertexCount;
  fixtures::TempDir tmp;
  std::vector<DressedCharacterResult> dressed;
  for (int i = 0; i < 2; ++i) {
    MacroSettings s;
    s.gender = i ? 0.9 : 0.1;
    s.weight = i ? 0.7 : 0.4;
    const Eigen::MatrixX3d full = mh.build_vertices(s);
    CharacterRigFile ch;
    ch.skeleton = mh.skeleton(full);
    ch.F = mh.body_faces();
    ch.lbs = lbs_rig_from_weights(full.topRows(nb), Eigen::MatrixXd(mh.weights().topRows(nb)), 4);
    const fs::path dir = tmp / "crowd" / ("char_00" + std::to_string(i)) / "anim";
    fs::create_directories(dir);
    dressed.push_back(write_dressed_character(kit, ch, i == 1, 1000003ull + i, {}, 0.1, dir));
  }
  const DressedCrowdPictures p = dressed_crowd_pictures(tmp / "crowd", 3);   // char_002 absent: skipped
  ASSERT_EQ(p.lineup.width, 2 * 150);
  ASSERT_EQ(p.lods.width, 3 * 220);

  // What is written reads back as the picture made.
  const fs::path png = tmp / "lineup.png";
  p.lineup.save_png(png);
  int w = 0, h = 0, n = 0;
  unsigned char* data = stbi_load(png.c_str(), &w, &h, &n, 3);
  ASSERT_NE(data, nullptr);
  EXPECT_EQ(w, p.lineup.width);
  EXPECT_EQ(h, p.lineup.height);
  EXPECT_TRUE(std::equal(p.lineup.rgb.begin(), p.lineup.rgb.end(), data));
  stbi_image_free(data);

  // The line-up: each cell a body (10-60 % of the cell, shaded), in its cloth colours.
  for (int i = 0; i < 2; ++i) {
    const Coverage all = coverage(p.lineup, 150 * i, 150 * (i + 1), rgb_of_hex(dressed[i].drawn.skin_hex));
    EXPECT_GT(all.drawn, 0.10 * all.pixels) << "character " << i;
    EXPECT_LT(all.drawn, 0.60 * all.pixels) << "character " << i;
    EXPECT_GT(all.stddev, 0.05) << "character " << i;
    int cloth = 0;
    for (const DrawnItem& it : dressed[i].drawn.items) {
      if (it.palette != "cloth") continue;
      ++cloth;
      const Coverage c = coverage(p.lineup, 150 * i, 150 * (i + 1), rgb_of_hex(it.hex));
      EXPECT_GT(c.matching, 0.15 * c.drawn) << "character " << i << " " << it.asset << " " << it.hex;
    }
    EXPECT_GE(cloth, 1) << "character " << i;
  }

  // The levels of detail: fewer triangles each, LOD2 within 2000, each filling about the area of LOD0.
  ASSERT_EQ(p.level_triangles.size(), 3u);
  EXPECT_GT(p.level_triangles[0], p.level_triangles[1]);
  EXPECT_GT(p.level_triangles[1], p.level_triangles[2]);
  EXPECT_LE(p.level_triangles[2], 2000);
  const Coverage lod0 = coverage(p.lods, 0, 220, Eigen::Vector3d::Ones());
  EXPECT_GT(lod0.drawn, 0.10 * lod0.pixels);
  for (int k = 1; k < 3; ++k) {
    const Coverage l = coverage(p.lods, 220 * k, 220 * (k + 1), Eigen::Vector3d::Ones());
    EXPECT_NEAR(l.drawn, lod0.drawn, 0.15 * lod0.drawn) << "LOD" << k;
    EXPECT_GT(l.stddev, 0.05) << "LOD" << k;
  }

  // The close-up: the head fills the frame; skin in the front view, hair (when drawn) in both.
  const DressedCharacterResult& f = dressed[static_cast<size_t>(p.featured)];
  const int half = p.closeup.width / 2;
  const Coverage front = coverage(p.closeup, 0, half, rgb_of_hex(f.drawn.skin_hex));
  EXPECT_GT(front.drawn, 0.30 * front.pixels);
  EXPECT_GT(front.matching, 0.10 * front.drawn);
  for (const DrawnItem& it : f.drawn.items)
    if (it.slot == "hair")
      for (int v = 0; v < 2; ++v) {
        const Coverage hair = coverage(p.closeup, v * half, (v + 1) * half, rgb_of_hex(it.hex));
        EXPECT_GT(hair.matching, 0.05 * hair.pixels) << it.asset << " " << it.hex << " view " << v;
      }
  std::printf("featured char_%03d; levels %d / %d / %d triangles; close-up drawn %.0f %%, skin %.0f %% of it\n",
              p.featured, p.level_triangles[0], p.level_triangles[1], p.level_triangles[2],
              100.0 * front.drawn / front.pixels, 100.0 * front.matching / front.drawn);
  if (const char* keep = std::getenv("BODYMODEL_KEEP_PICTURES"); keep && *keep) save_dressed_crowd_pictures(p, keep);

  // The report's part (tmp as the demo's OUT): the three pictures, and the crowd viewer's link with
  // the http note only when the page and its three.js modules are there.
  fs::create_directories(tmp / "pictures");
  save_dressed_crowd_pictures(p, tmp / "pictures");
  std::string html = dressed_crowd_html(tmp.path, p);
  for (const char* f : {"crowd_dressed.png", "crowd_lods.png", "crowd_closeup.png"}) {
    EXPECT_NE(html.find(std::string("<img src=\"pictures/") + f + "\""), std::string::npos) << f;
    EXPECT_GT(fs::file_size(tmp / "pictures" / f), 10000u) << f;
  }
  EXPECT_EQ(html.find("missing picture"), std::string::npos);
  EXPECT_EQ(html.find("crowd/crowd.html"), std::string::npos);
  std::ofstream(tmp / "crowd" / "crowd.html") << "<!doctype html>";
  fs::create_directories(tmp / "crowd" / "three");
  html = dressed_crowd_html(tmp.path, p);
  EXPECT_NE(html.find("<a href=\"crowd/crowd.html\">"), std::string::npos);
  EXPECT_NE(html.find("served over http"), std::string::npos);
}

TEST(DressedPictures, RefusesAFolderWithoutDressedCharacters) {
  fixtures::TempDir tmp;
  EXPECT_THROW(dressed_crowd_pictures(tmp.path, 4), InputError);
  const fs::path bad = tmp / "char_000" / "anim";
  fs::create_directories(bad);
  std::ofstream(bad / "dressed.glb") << "not a glb";
  EXPECT_THROW(dressed_crowd_pictures(tmp.path, 1), InputError);
}

}  // namespace
}  // namespace bodymodel
