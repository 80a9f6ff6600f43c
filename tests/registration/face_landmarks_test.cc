// Face landmarks (core/landmarks.h face_landmarks()) and `eval-correspondence --landmarks`, which
// measures where a registration put them.
#include <gtest/gtest.h>

#include <filesystem>

#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/mesh_io.h"
#include "core/landmarks.h"
#include "core/makehuman.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

int landmark(const char* name) {
  for (const auto& [n, v] : registration_landmarks())
    if (n == name) return v;
  return -1;
}

// The nose tip is the rule it states on MakeHuman's default body: the most forward vertex of the
// head's midline, between the chin and the top of the head.
TEST(FaceLandmarks, NoseTipIsTheFrontOfTheHeadsMidline) {
  const Mesh body = MakeHuman::load().body(MacroSettings{}).mesh;
  const int nose = landmark("nose_tip"), chin = landmark("chin"), top = landmark("head_top");
  ASSERT_GE(nose, 0);
  int best = -1;
  for (int i = 0; i < body.V.rows(); ++i)
    if (std::abs(body.V(i, 0)) < 8 && body.V(i, 1) > body.V(chin, 1) && (best < 0 || body.V(i, 2) > body.V(best, 2)))
      best = i;
  EXPECT_EQ(nose, best);
  EXPECT_GT(body.V(nose, 1), body.V(chin, 1) + 50);  // well above the chin, below the top
  EXPECT_LT(body.V(nose, 1), body.V(top, 1) - 100);
}

// Registrations in the template's topology against truths of the same numbering: one exact, one
// moved 10 mm up. The landmark distances are 0 and 10 mm, for a face landmark as for the others.
TEST(FaceLandmarks, EvalCorrespondenceReportsLandmarkDistances) {
  const Mesh body = MakeHuman::load().body(MacroSettings{}).mesh;
  const fs::path dir = fs::temp_directory_path() / "bodymodel_face_landmarks";
  fs::remove_all(dir);
  fs::create_directories(dir / "reg");
  fs::create_directories(dir / "truth");
  for (const char* n : {"a", "b"}) write_mesh(dir / "truth" / (std::string(n) + ".off"), body.V / 1000.0, body.F);
  write_mesh(dir / "reg" / "a.ply", body.V, body.F);
  write_mesh(dir / "reg" / "b.ply", body.V.rowwise() + Eigen::RowVector3d(0, 10, 0), body.F);
  write_text_file(dir / "lm.json", "{\"nose_tip\": " + std::to_string(landmark("nose_tip")) +
                                       ", \"chin\": " + std::to_string(landmark("chin")) + "}");
  const auto r = fixtures::run_cli("eval-correspondence '" + (dir / "reg").string() + "' --truth '" +
                                   (dir / "truth").string() + "' --truth-scale 1000 --landmarks '" +
                                   (dir / "lm.json").string() + "' --out '" + (dir / "eval").string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("landmark nose_tip: mean 5.0 mm, max 10.0 mm (b)"), std::string::npos) << r.output;
  const std::vector<CsvRecord> rows = read_csv_file(dir / "eval" / "landmarks.csv");
  ASSERT_EQ(rows.size(), 5u);  // header and 2 meshes × 2 landmarks
  for (size_t k = 1; k < rows.size(); ++k) {
    const std::vector<std::string>& f = rows[k].fields;
    ASSERT_EQ(f.size(), 3u);
    EXPECT_NEAR(std::stod(f[2]), f[0] == "a" ? 0.0 : 10.0, 0.01) << f[0] << " " << f[1];
  }
  // An unknown landmark name: one line naming the file, exit 2.
  write_text_file(dir / "bad.json", "{\"nose_bridge\": 3}");
  const auto bad = fixtures::run_cli("eval-correspondence '" + (dir / "reg").string() + "' --truth '" +
                                     (dir / "truth").string() + "' --truth-scale 1000 --landmarks '" +
                                     (dir / "bad.json").string() + "' --out '" + (dir / "eval2").string() + "'");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("bad.json"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(dir / "eval2"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bodymodel
