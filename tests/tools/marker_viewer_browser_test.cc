// Markers in the viewer (`bodymodel viewer --markers FILE --marker-report REPORT`), in headless
// Chromium (tests/support/browser.h). A 5 × 4 grid of markers sways along x; one marker has a gap
// over frames 20-39. A probe script, loaded after viewer.js, waits for the page, checks that the
// play loop's marker frame follows the clock at the capture's rate (stepped by the probe: headless
// virtual time runs timers, not animation frames), then stops at frames 10 and 30 and reads the drawn pixel where each
// marker's position (computed here, in C++) projects with the page's camera. With the cleaned file
// and the report every marker is drawn in the seen colour except the gap's marker inside the gap,
// drawn in the filled colour; with the raw capture the gap's marker is not drawn inside it.
// Skipped, saying why, when Chromium or three.js is missing (scripts/setup.sh installs them).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <regex>

#include "core/io/atomic_write.h"
#include "markers/marker_data.h"
#include "support/browser.h"
#include "support/fixtures.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

constexpr int kMarkers = 20, kFrames = 60, kGapMarker = 7, kGapFirst = 20, kGapLast = 39;

Eigen::Vector3d position(int m, int t) {
  return {100.0 * (m % 5) + 50 * std::sin(2 * M_PI * t / kFrames), 1000 + 100.0 * (m / 5), 20.0 * (m % 3)};
}

MarkerData sway(bool with_gap) {
  MarkerData d;
  d.rate = 60;
  for (int m = 0; m < kMarkers; ++m) d.labels.push_back("m" + std::to_string(m));
  d.xyz.resize(kFrames, 3 * kMarkers);
  for (int t = 0; t < kFrames; ++t)
    for (int m = 0; m < kMarkers; ++m) d.set(t, m, position(m, t));
  if (with_gap)
    for (int t = kGapFirst; t <= kGapLast; ++t) d.clear(t, kGapMarker);
  return d;
}

// The probe: the colour class (b seen, o filled, w background, ? other) of the pixel under each
// marker at each frame given, and whether the markers advanced by themselves in 0.5 s.
std::string probe_js(const std::vector<int>& frames) {
  std::string pts = "[";
  for (int f : frames) {
    pts += "[";
    for (int m = 0; m < kMarkers; ++m) {
      const Eigen::Vector3d p = position(m, f);
      pts += "[" + std::to_string(p.x()) + "," + std::to_string(p.y()) + "," + std::to_string(p.z()) + "],";
    }
    pts += "],";
  }
  pts += "]";
  std::string frame_list;
  for (int f : frames) frame_list += std::to_string(f) + ",";
  return "'use strict';\n(function () {\nconst frames = [" + frame_list + "], points = " + pts + R"JS(;
function cls(px, i) {
  const r = px[i], g = px[i + 1], b = px[i + 2];
  if (r >= 250 && g >= 250 && b >= 250) return 'w';
  if (b > r + 60 && b > g + 20) return 'b';
  if (r > 200 && g > 70 && g < 150 && b < 60) return 'o';
  return '?';
}
function run(t0, f0) {
  const s = window.viewerState;
  if (!s || !s.ready || s.framesDrawn < 3) { setTimeout(() => run(), 50); return; }
  if (t0 === undefined) {
    const now = performance.now(), first = viewerApi.step();
    setTimeout(() => run(now, first), 500);
    return;
  }
  const to = viewerApi.step(), ms = performance.now() - t0;
  const out = [`advanced=${(to - f0 + 60) % 60}`, `expected=${Math.floor(ms / 1000 * 60) % 60}`];
  frames.forEach((f, k) => {
    const cam = viewerApi.showMarkers(f), m = cam.vp, W = cam.width, H = cam.height;
    const px = Uint8Array.from(atob(viewerApi.pixels()), (c) => c.charCodeAt(0));
    let classes = '', filled = 0;
    for (let i = 0; i < px.length; i += 4) filled += cls(px, i) === 'o';
    for (const [X, Y, Z] of points[k]) {
      const w = m[3] * X + m[7] * Y + m[11] * Z + m[15];
      const sx = Math.floor(((m[0] * X + m[4] * Y + m[8] * Z + m[12]) / w * 0.5 + 0.5) * W);
      const sy = Math.floor(((m[1] * X + m[5] * Y + m[9] * Z + m[13]) / w * 0.5 + 0.5) * H);
      classes += sx >= 0 && sy >= 0 && sx < W && sy < H ? cls(px, 4 * (sy * W + sx)) : 'x';
    }
    out.push(`f${f}=${classes}`, `filled${f}=${filled}`);
  });
  document.title = 'probe ' + out.join(' ');
}
window.addEventListener('error', (e) => { document.title = 'probe error ' + e.message; });
run();
})();
)JS";
}

// The viewer folder for `args`, opened with the probe; the probe's title ("" when it never ran).
std::string run_probe(const fs::path& dir, const std::string& args, const fs::path& three) {
  const auto r = fixtures::run_cli("viewer " + args + " --three " + three.string() + " --out " + dir.string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  if (r.exit_code != 0) return "";
  write_text_file(dir / "probe.js", probe_js({10, 30}));
  std::string page = read_text_file(dir / "index.html");
  page.replace(page.find("</body>"), 7, "<script src=\"probe.js\"></script>\n</body>");
  write_text_file(dir / "probe.html", page);
  const std::string dom = fixtures::headless_dom("file://" + (dir / "probe.html").string());
  std::smatch m;
  const std::regex title("<title>(probe [^<]*)</title>");
  if (!std::regex_search(dom, m, title)) {
    ADD_FAILURE() << "no probe result in the page (" << dom.size() << " bytes of DOM): " << dom.substr(0, 400);
    return "";
  }
  return m[1].str();
}

std::string field(const std::string& text, const std::string& key) {
  std::smatch m;
  const std::regex re(key + "=([^ ]*)");
  return std::regex_search(text, m, re) ? m[1].str() : "";
}

// Bad marker input ends with one line naming what is wrong, and writes no folder.
TEST(MarkerViewer, RefusesAReportOfAnotherCaptureAndAReportWithoutMarkers) {
  fixtures::TempDir tmp;
  write_markers(tmp / "clean.trc", sway(false));
  write_text_file(tmp / "other.json", "{\"gaps\": [{\"marker\": \"Z9\", \"first_frame\": 1, \"last_frame\": 2}]}\n");
  write_text_file(tmp / "late.json", "{\"gaps\": [{\"marker\": \"m1\", \"first_frame\": 50, \"last_frame\": 60}]}\n");
  write_text_file(tmp / "three.min.js", "// not used: the input is refused first\n");
  const std::string three = " --three " + (tmp / "three.min.js").string() + " --out " + (tmp / "v").string();
  const std::pair<std::string, std::string> cases[] = {
      {"--markers " + (tmp / "clean.trc").string() + " --marker-report " + (tmp / "other.json").string(), "'Z9'"},
      {"--markers " + (tmp / "clean.trc").string() + " --marker-report " + (tmp / "late.json").string(), "50-60"},
      {"--markers " + (tmp / "missing.trc").string(), "missing.trc"},
      {"--mesh " + (tmp / "x.obj").string() + " --marker-report " + (tmp / "other.json").string(), "--marker-report needs --markers"}};
  for (const auto& [args, needle] : cases) {
    const auto r = fixtures::run_cli("viewer " + args + three);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(needle), std::string::npos) << args << "\n" << r.output;
    EXPECT_LE(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(tmp / "v")) << args;
  }
}

TEST(MarkerViewerBrowser, PlaysTheMarkersAndDrawsTheFilledSamplesInTheirColour) {
  if (!fs::exists(fixtures::chromium_path())) GTEST_SKIP() << fixtures::chromium_path() << " not found";
  fs::path three = fixtures::three_dir() / "build" / "three.min.js";
  if (const char* t = std::getenv("BODYMODEL_THREE"); t && fs::is_regular_file(t)) three = t;
  if (!fs::is_regular_file(three)) GTEST_SKIP() << three << " not found (scripts/setup.sh installs three.js)";
  fixtures::TempDir tmp;
  write_markers(tmp / "clean.trc", sway(false));
  write_markers(tmp / "raw.trc", sway(true));
  write_text_file(tmp / "clean.json", "{\"gaps\": [{\"marker\": \"m" + std::to_string(kGapMarker) + "\", \"first_frame\": " +
                                          std::to_string(kGapFirst) + ", \"last_frame\": " + std::to_string(kGapLast) + "}]}\n");
  const std::string all_seen(kMarkers, 'b');
  std::string gap_filled = all_seen, gap_missing = all_seen;
  gap_filled[kGapMarker] = 'o';
  gap_missing[kGapMarker] = 'w';

  const std::string cleaned = run_probe(
      tmp / "v1", "--markers " + (tmp / "clean.trc").string() + " --marker-report " + (tmp / "clean.json").string(), three);
  ASSERT_FALSE(cleaned.empty()) << "the probe did not finish in headless Chromium";
  // The play loop's frame advances with the clock at the capture's rate (60 Hz: 30 frames in the
  // probe's 0.5 s; rounding may take one).
  const int advanced = std::atoi(field(cleaned, "advanced").c_str()), expected = std::atoi(field(cleaned, "expected").c_str());
  EXPECT_GE(expected, 29) << cleaned;
  EXPECT_NEAR(advanced, expected, 1) << cleaned;
  EXPECT_EQ(field(cleaned, "f10"), all_seen) << cleaned;
  EXPECT_EQ(field(cleaned, "f30"), gap_filled) << cleaned;
  EXPECT_EQ(field(cleaned, "filled10"), "0") << cleaned;
  // One point of 6 × 6 pixels in the filled colour (less where a neighbour overlaps it).
  const int filled30 = std::atoi(field(cleaned, "filled30").c_str());
  EXPECT_GE(filled30, 16) << cleaned;
  EXPECT_LE(filled30, 36) << cleaned;

  const std::string raw = run_probe(tmp / "v2", "--markers " + (tmp / "raw.trc").string(), three);
  ASSERT_FALSE(raw.empty()) << "the probe did not finish in headless Chromium";
  EXPECT_EQ(field(raw, "f10"), all_seen) << raw;
  EXPECT_EQ(field(raw, "f30"), gap_missing) << raw;
  EXPECT_EQ(field(raw, "filled30"), "0") << raw;
}

}  // namespace
}  // namespace bodymodel
