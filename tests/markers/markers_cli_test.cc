// `bodymodel markers simulate`, `markers clean` and `markers deform` end to end on the Vlasic jumping capture, and
// their refusals: bad input exits 2 with one line and leaves no output.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unistd.h>

#include "core/data_path.h"
#include "core/io/atomic_write.h"
#include "markers/marker_data.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

int run(const std::string& args, std::string* err = nullptr) {
  const fs::path log = fs::temp_directory_path() / ("bodymodel_markers_cli_" + std::to_string(::getpid()) + ".log");
  const int rc = std::system((BODYMODEL_EXE + " " + args + " >/dev/null 2>" + log.string()).c_str());
  if (err) *err = read_text_file(log);
  fs::remove(log);
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

// markers deform --clean-report: a report that is not JSON, lacks the gaps, or names a marker or
// frames the capture does not have ends with one line naming it, exit 2, nothing written (the
// report is read before the meshes, so none are needed here).
TEST(MarkersCli, DeformRefusesABadCleanReport) {
  const fs::path dir = fs::temp_directory_path() / ("bodymodel_markers_report_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  MarkerData d;
  d.rate = 120;
  d.labels = {"A", "B", "C"};
  d.xyz = Eigen::MatrixXd::Zero(10, 9);
  write_markers(dir / "m.trc", d);
  const std::pair<std::string, std::string> cases[] = {
      {"{not json", "not a markers clean report"},
      {"{\"merged\": 3}", "not a markers clean report"},
      {"{\"gaps\": [{\"marker\": \"A\", \"first_frame\": 2}]}", "gap 0 is not"},
      {"{\"gaps\": [{\"marker\": \"Z\", \"first_frame\": 2, \"last_frame\": 3}]}", "gap of marker 'Z'"},
      {"{\"gaps\": [{\"marker\": \"B\", \"first_frame\": 8, \"last_frame\": 12}]}", "not within the capture's 10 frames"}};
  for (const auto& [text, expected] : cases) {
    write_text_file(dir / "report.json", text);
    std::string err;
    EXPECT_EQ(run("markers deform " + (dir / "m.trc").string() + " --meshes " + (dir / "none").string() + " --clean-report " +
                      (dir / "report.json").string() + " --out " + (dir / "out").string(), &err), 2) << text;
    EXPECT_NE(err.find(expected), std::string::npos) << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    EXPECT_FALSE(fs::exists(dir / "out"));
  }
  std::string err;
  EXPECT_EQ(run("markers deform " + (dir / "m.trc").string() + " --meshes " + (dir / "none").string() + " --clean-report " +
                    (dir / "missing.json").string() + " --out " + (dir / "out").string(), &err), 2);
  EXPECT_NE(err.find("missing.json"), std::string::npos) << err;
  fs::remove_all(dir);
}

TEST(MarkersCli, SimulateThenCleanWritesEveryMarkerAndAReport) {
  const fs::path dir = fs::temp_directory_path() / ("bodymodel_markers_cli_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string meshes = (data_root() / "animations" / "vlasic-jumping").string();
  ASSERT_EQ(run("markers simulate " + meshes + " --out " + (dir / "sim").string()), 0);
  for (const char* f : {"capture.c3d", "truth.trc", "pieces.csv", "simulate.json"}) EXPECT_TRUE(fs::exists(dir / "sim" / f)) << f;
  const auto summary = nlohmann::json::parse(read_text_file(dir / "sim" / "simulate.json"));
  EXPECT_GE(summary["missing_fraction"].get<double>(), 0.15);
  std::string err;
  EXPECT_EQ(run("markers simulate " + meshes + " --out " + (dir / "sim").string(), &err), 2) << "an existing folder needs --force";
  EXPECT_NE(err.find("--force"), std::string::npos) << err;

  ASSERT_EQ(run("markers clean " + (dir / "sim" / "capture.c3d").string() + " --out " + (dir / "clean.c3d").string() +
                " --truth " + (dir / "sim" / "truth.trc").string()), 0);
  const MarkerData cleaned = read_markers(dir / "clean.c3d");
  EXPECT_EQ(cleaned.marker_count(), 350);
  EXPECT_EQ(cleaned.frame_count(), 349);
  EXPECT_TRUE(cleaned.xyz.allFinite()) << "every labelled marker at every frame";
  const auto report = nlohmann::json::parse(read_text_file(dir / "clean.json"));
  EXPECT_EQ(report["gaps_left"].get<int>(), 0);
  EXPECT_GT(report["merged"].get<int>(), 0);
  EXPECT_EQ(report["evaluation"]["wrong_merges"].get<int>(), 0);
  EXPECT_LE(report["evaluation"]["median_fill_5_to_60_mm"].get<double>(), 5.0);

  // markers deform: Park's skin driven by the cleaned markers, below the SSD and MWE rigs on the
  // held-out frames (docs/markers.md has the figures); a capture that does not match the meshes'
  // frame count is refused with one line and nothing written.
  ASSERT_EQ(run("markers deform " + (dir / "clean.c3d").string() + " --meshes " + meshes + " --out " + (dir / "deform").string() +
                " --write-every 100"), 0);
  const auto deform = nlohmann::json::parse(read_text_file(dir / "deform" / "deform.json"));
  const auto& errors = deform["errors"];
  EXPECT_LT(errors["park"]["mean_mm"].get<double>(), errors["ssd"]["mean_mm"].get<double>());
  EXPECT_LT(errors["park"]["mean_mm"].get<double>(), errors["mwe"]["mean_mm"].get<double>());
  EXPECT_LT(errors["park"]["mean_mm"].get<double>(), 10.0);
  EXPECT_EQ(deform["test_frames"].size(), 15u);
  EXPECT_TRUE(fs::exists(dir / "deform" / "errors.csv"));
  EXPECT_TRUE(fs::exists(dir / "deform" / "park_00300.obj"));
  EXPECT_EQ(run("markers deform " + (dir / "clean.c3d").string() + " --meshes " + meshes + " --mesh-rate 15 --out " +
                (dir / "deform15").string(), &err), 2);
  EXPECT_NE(err.find("the capture has 349 frames but 30 meshes"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_FALSE(fs::exists(dir / "deform15"));

  // A truncated capture: exit 2, one line naming the file, nothing written.
  const std::string bytes = read_text_file(dir / "sim" / "capture.c3d");
  write_text_file(dir / "cut.c3d", bytes.substr(0, bytes.size() / 2));
  EXPECT_EQ(run("markers clean " + (dir / "cut.c3d").string() + " --out " + (dir / "cut_clean.trc").string(), &err), 2);
  EXPECT_NE(err.find("cut.c3d"), std::string::npos) << err;
  EXPECT_NE(err.find("truncated"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_FALSE(fs::exists(dir / "cut_clean.trc"));
  EXPECT_FALSE(fs::exists(dir / "cut_clean.json"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bodymodel
