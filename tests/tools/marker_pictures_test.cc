// The dense-marker pictures in the demo's report (tools/pipeline/marker_pictures.h). Known
// answers: markers moving along straight lines, one with a gap, must show the filled colour on
// that marker's line over the gap's share of it and nowhere else; a skin sheared against its truth
// must be drawn beside it at the same scale, grey on the left, blue at the feet and red at the
// head on the right. The crane clip through simulate → clean → deform checks that the report's gap
// list is the cleaning's (every filled sample in one gap) and that the pictures are made from the
// files the demo's stage writes (kept in the build folder, marker_pictures_test/, for a look).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "markers/trc.h"
#include "support/fixtures.h"
#include "support/run_cli.h"
#include "tools/pipeline/marker_pictures.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

// Whether pixel (x, y) is the colour c under the renderer's shading (a scale of 0.25-1.1): within
// 6° of its direction in RGB and at least 20 % of its brightness.
bool is_colour(const Image& img, int x, int y, const Eigen::Vector3d& c) {
  const uint8_t* p = &img.rgb[(size_t(y) * img.width + x) * 3];
  const Eigen::Vector3d q(p[0] / 255.0, p[1] / 255.0, p[2] / 255.0);
  if (q.norm() < 0.2 * c.norm()) return false;
  return std::acos(std::clamp(q.normalized().dot(c.normalized()), -1.0, 1.0)) < 6 * M_PI / 180;
}
bool is_white(const Image& img, int x, int y) {
  const uint8_t* p = &img.rgb[(size_t(y) * img.width + x) * 3];
  return p[0] == 255 && p[1] == 255 && p[2] == 255;
}

// Four markers moving along x from 0 to 1000 mm over 101 frames, at heights 0, 100, 200, 300 mm.
MarkerData lines() {
  MarkerData d;
  d.labels = {"m0", "m1", "m2", "m3"};
  d.rate = 100;
  d.xyz.resize(101, 12);
  for (int t = 0; t < 101; ++t)
    for (int m = 0; m < 4; ++m) d.xyz.block<1, 3>(t, 3 * m) << 10.0 * t, 100.0 * m, 0;
  return d;
}

TEST(MarkerPictures, FilledGapIsDrawnInItsColourOverItsShareOfTheMarkersTrail) {
  const MarkerData d = lines();
  const auto mask = filled_mask(d, {{"m2", 40, 60}});
  const Image img = marker_trails_picture(d, mask, 0, 101, 400, 300, 6);
  // Rows holding the filled colour, and per row the columns of each colour.
  int orange_rows = 0, blue_rows = 0, both_rows = 0;
  for (int y = 0; y < img.height; ++y) {
    int o0 = img.width, o1 = -1, b0 = img.width, b1 = -1, blue = 0;
    for (int x = 0; x < img.width; ++x) {
      if (is_colour(img, x, y, kTrailFilled)) o0 = std::min(o0, x), o1 = std::max(o1, x);
      if (is_colour(img, x, y, kTrailSeen)) b0 = std::min(b0, x), b1 = std::max(b1, x), ++blue;
    }
    blue_rows += blue > 0;
    if (o1 < 0) continue;
    ++orange_rows;
    // On the gap's marker: its seen samples on both sides of the filled span, in the same row,
    // and the span covers frames 39-61 of 0-100 (the segments touching a filled sample). The
    // filled ribbon is wider: its edge rows have no seen pixels.
    if (b1 < 0) continue;
    ++both_rows;
    EXPECT_LT(b0, o0);
    EXPECT_GT(b1, o1);
    const double lo = double(o0 - b0) / (b1 - b0), hi = double(o1 - b0) / (b1 - b0);
    EXPECT_NEAR(lo, 0.39, 0.03) << "row " << y;
    EXPECT_NEAR(hi, 0.61, 0.03) << "row " << y;
  }
  EXPECT_GT(both_rows, 0);
  EXPECT_LE(orange_rows, 6);  // one trail about 9 mm wide: a couple of pixels at ~2.5 mm a pixel
  EXPECT_GE(blue_rows, 4);
  // The filled rows are the third line from the top (marker m2 at 200 mm, +y up): between the
  // rows of the lines above and below it.
  std::vector<int> band_start;
  bool previous = false;
  for (int y = 0; y < img.height; ++y) {
    bool any = false;
    for (int x = 0; x < img.width && !any; ++x) any = !is_white(img, x, y);
    if (any && !previous) band_start.push_back(y);
    previous = any;
  }
  ASSERT_EQ(band_start.size(), 4u);  // four separate bands, one per marker, m3 at the top
  int first_orange = -1;
  for (int y = 0; y < img.height && first_orange < 0; ++y)
    for (int x = 0; x < img.width; ++x)
      if (is_colour(img, x, y, kTrailFilled)) { first_orange = y; break; }
  EXPECT_GE(first_orange, band_start[1]);
  EXPECT_LT(first_orange, band_start[2]);

  // Without gaps no pixel has the filled colour.
  const Image plain = marker_trails_picture(d, filled_mask(d, {}), 0, 101, 400, 300, 6);
  int orange = 0;
  for (int y = 0; y < plain.height; ++y)
    for (int x = 0; x < plain.width; ++x) orange += is_colour(plain, x, y, kTrailFilled);
  EXPECT_EQ(orange, 0);
}

TEST(MarkerPictures, RefusesGapsOutsideTheCaptureMissingSamplesAndAReportWithoutGaps) {
  MarkerData d = lines();
  EXPECT_THROW(filled_mask(d, {{"m9", 1, 2}}), InputError);
  EXPECT_THROW(filled_mask(d, {{"m1", 90, 101}}), InputError);
  EXPECT_THROW(filled_mask(d, {{"m1", 5, 4}}), InputError);
  d.clear(50, 1);
  EXPECT_THROW(marker_trails_picture(d, filled_mask(d, {}), 0, 101, 100, 100), InputError);
  EXPECT_NO_THROW(marker_trails_picture(d, filled_mask(d, {}), 0, 50, 100, 100));
  EXPECT_THROW(marker_trails_picture(d, filled_mask(d, {}), 60, 50, 100, 100), InputError);
  fixtures::TempDir tmp;
  write_text_file(tmp / "old.json", "{\"markers\": 4, \"gaps_found\": 2}\n");
  EXPECT_THROW(read_clean_gaps(tmp / "old.json"), InputError);
  write_text_file(tmp / "bad.json", "{\"gaps\": [{\"marker\": \"m1\", \"first_frame\": 2}]}\n");
  EXPECT_THROW(read_clean_gaps(tmp / "bad.json"), InputError);
  write_text_file(tmp / "ok.json", "{\"gaps\": [{\"marker\": \"m1\", \"first_frame\": 2, \"last_frame\": 7}]}\n");
  const auto gaps = read_clean_gaps(tmp / "ok.json");
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_EQ(gaps[0].marker, "m1");
  EXPECT_EQ(gaps[0].first, 2);
  EXPECT_EQ(gaps[0].last, 7);
}

// A cylinder 1.8 units tall, radius 0.15, 24 around × 30 rings.
void cylinder(Eigen::MatrixX3d& V, Eigen::MatrixX3i& F) {
  const int n = 24, rings = 30;
  V.resize(n * rings, 3);
  for (int r = 0; r < rings; ++r)
    for (int k = 0; k < n; ++k) {
      const double a = 2 * M_PI * k / n;
      V.row(r * n + k) << 0.15 * std::cos(a), 1.8 * r / (rings - 1), 0.15 * std::sin(a);
    }
  F.resize(2 * n * (rings - 1), 3);
  int f = 0;
  for (int r = 0; r + 1 < rings; ++r)
    for (int k = 0; k < n; ++k) {
      const int a = r * n + k, b = r * n + (k + 1) % n, c = a + n, e = b + n;
      F.row(f++) << a, b, e;
      F.row(f++) << a, e, c;
    }
}

TEST(MarkerPictures, SkinBesideTruthDrawsBothAtOneScaleWithTheErrorColours) {
  Eigen::MatrixX3d truth, skin;
  Eigen::MatrixX3i F;
  cylinder(truth, F);
  skin = truth;
  // Sheared forwards by 0 at the foot to 40 mm at the top (scale 30 mm: blue to red).
  for (int v = 0; v < skin.rows(); ++v) skin(v, 2) += 0.040 * skin(v, 1) / 1.8;
  const int cell = 200, h = 400;
  const Image img = skin_beside_truth_picture(truth, skin, F, 1000, 30, cell, h);
  ASSERT_EQ(img.width, 2 * cell);
  ASSERT_EQ(img.height, h + 24);
  struct Cell { int drawn = 0, saturated = 0, top = -1, bottom = -1, red_top = 0, blue_bottom = 0; };
  Cell c[2];
  for (int k = 0; k < 2; ++k) {
    for (int y = 0; y < h; ++y)
      for (int x = k * cell; x < (k + 1) * cell; ++x) {
        if (is_white(img, x, y)) continue;
        Cell& q = c[k];
        ++q.drawn;
        if (q.top < 0) q.top = y;
        q.bottom = y;
        const uint8_t* p = &img.rgb[(size_t(y) * img.width + x) * 3];
        const int mx = std::max({p[0], p[1], p[2]}), mn = std::min({p[0], p[1], p[2]});
        q.saturated += mx > 0 && (mx - mn) > 0.3 * mx;
        q.red_top += y < h / 5 && p[0] > p[1] + 60 && p[0] > p[2] + 60;
        q.blue_bottom += y > 4 * h / 5 && p[2] > p[0] + 60 && p[2] >= p[1];
      }
    EXPECT_GT(c[k].drawn, 0.05 * cell * h) << "cell " << k;
  }
  EXPECT_EQ(c[0].saturated, 0);  // the truth in grey
  EXPECT_GT(c[1].saturated, 0.9 * c[1].drawn);
  EXPECT_GT(c[1].red_top, 100);
  EXPECT_GT(c[1].blue_bottom, 100);
  EXPECT_EQ(c[0].red_top + c[0].blue_bottom, 0);
  // One scale and floor: the same height within a pixel (the shear moves no vertex up or down).
  EXPECT_NEAR(c[0].top, c[1].top, 1);
  EXPECT_NEAR(c[0].bottom, c[1].bottom, 1);
  // Nothing drawn across the border between the cells' figures.
  for (int y = 0; y < h; ++y) EXPECT_TRUE(is_white(img, cell, y)) << y;
  // The colour bar under the skin, not under the truth.
  EXPECT_TRUE(is_white(img, cell / 2, h + 12));
  EXPECT_FALSE(is_white(img, cell + cell / 2, h + 12));
  Eigen::MatrixX3d fewer = skin.topRows(10);
  EXPECT_THROW(skin_beside_truth_picture(truth, fewer, F, 1000, 30, cell, h), InputError);
}

TEST(MarkerPictures, CraneClipThroughSimulateCleanDeform) {
  const fs::path crane = data_file("animations") / "vlasic-crane";
  if (!fs::is_regular_file(crane / "mesh_0000.obj")) GTEST_SKIP() << crane << " not found";
  fixtures::TempDir tmp;
  std::string meshes;
  std::vector<fs::path> files;
  for (int m = 0; m < 10; ++m) {
    files.push_back(crane / ("mesh_" + std::string(m < 5 ? "000" : "00") + std::to_string(2 * m) + ".obj"));
    meshes += " " + files.back().string();
  }
  const fs::path dir = tmp / "markers";
  fs::create_directories(dir);
  auto run = [&](const std::string& args) {
    const auto r = fixtures::run_cli(args);
    ASSERT_EQ(r.exit_code, 0) << args << "\n" << r.output;
  };
  run("markers simulate" + meshes + " --mesh-rate 15 --out " + (dir / "sim").string());
  run("markers clean " + (dir / "sim/capture.c3d").string() + " --out " + (dir / "clean.trc").string() + " --truth " +
      (dir / "sim/truth.trc").string());
  run("markers deform " + (dir / "clean.trc").string() + " --meshes" + meshes +
      " --mesh-rate 15 --write-every 8 --out " + (dir / "deform").string());
  // The report's gaps are every sample missing after merging, once.
  const nlohmann::json report = nlohmann::json::parse(read_text_file(dir / "clean.json"));
  const auto gaps = read_clean_gaps(dir / "clean.json");
  long samples = 0;
  for (const auto& g : gaps) samples += g.last - g.first + 1;
  EXPECT_EQ(static_cast<int>(gaps.size()), report["gaps_found"].get<int>());
  EXPECT_EQ(samples, report["samples_missing"].get<long>());
  EXPECT_GT(samples, 0);

  const MarkerPictures p = marker_pictures(dir, files, 8, 1000);
  EXPECT_EQ(p.frames, 73);
  EXPECT_EQ(p.markers, 350);
  EXPECT_EQ(p.filled_samples, samples);
  EXPECT_EQ(p.held_out_capture_frame % 16, 8);  // an odd mesh frame: held out
  EXPECT_GT(p.park_mean_mm, 0);
  int filled = 0, seen = 0;
  for (int y = 0; y < p.trails.height; ++y)
    for (int x = 0; x < p.trails.width; ++x)
      filled += is_colour(p.trails, x, y, kTrailFilled), seen += is_colour(p.trails, x, y, kTrailSeen);
  EXPECT_GT(filled, 50);
  // About 15 % of the samples are missing, drawn half as wide again and on top: most is still seen.
  EXPECT_GT(seen, 2 * filled);
  const std::string csv = marker_summary_csv(dir);
  for (const char* row : {"wrong merges (truth)", "park mean / max", "mwe mean / max", "held-out frames,5"})
    EXPECT_NE(csv.find(row), std::string::npos) << row << "\n" << csv;
  fs::create_directories("marker_pictures_test");
  save_marker_pictures(p, "marker_pictures_test");
  EXPECT_TRUE(fs::is_regular_file("marker_pictures_test/marker_trails.png"));
}

}  // namespace
}  // namespace bodymodel
