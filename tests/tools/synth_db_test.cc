// The synthetic scan database, checked against its own ground truth.
#include <gtest/gtest.h>

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "core/landmarks.h"
#include "core/measure.h"
#include "core/point_index.h"
#include "support/fixtures.h"
#include "support/run_cli.h"

using namespace bodymodel;
namespace fs = std::filesystem;

namespace {

using K = CGAL::Simple_cartesian<double>;
using Triangle = K::Triangle_3;
using Iterator = std::vector<Triangle>::const_iterator;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, CGAL::AABB_triangle_primitive<K, Iterator>>>;

std::vector<std::vector<std::string>> read_csv(const fs::path& p) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(read_text_file(p));
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ls(line);
    std::string c;
    while (std::getline(ls, c, ',')) cells.push_back(c);
    rows.push_back(cells);
  }
  return rows;
}

// One small database shared by the tests of this file.
const fs::path& database() {
  static fixtures::TempDir dir;
  static bool made = false;
  if (!made) {
    auto r = fixtures::run_cli("synth-db --subjects 2 --poses-per-subject 1 --seed 5 --out '" +
                               (dir / "db").string() + "'");
    EXPECT_EQ(r.exit_code, 0) << r.output;
    made = true;
  }
  static fs::path db = dir / "db";
  return db;
}

}  // namespace

TEST(SynthDb, ScanNoiseAndHolesMatchTheScannerModel) {
  const fs::path db = database();
  auto scans = read_csv(db / "scans.csv");
  ASSERT_EQ(scans.size(), 1u + 4u);  // header + 2 subjects × (standard + 1 pose)
  for (size_t i = 1; i < scans.size(); ++i) {
    const std::string id = scans[i][0];
    PointCloud scan = read_point_cloud(db / "scans" / (id + ".ply"));
    Mesh truth = read_mesh(db / "truth" / (id + ".ply"));
    EXPECT_GE(scan.P.rows(), 50000) << id;
    ASSERT_TRUE(scan.has_normals());
    std::vector<Triangle> tris;
    for (int f = 0; f < truth.F.rows(); ++f) {
      auto p = [&](int k) {
        return K::Point_3(truth.V(truth.F(f, k), 0), truth.V(truth.F(f, k), 1),
                          truth.V(truth.F(f, k), 2));
      };
      tris.emplace_back(p(0), p(1), p(2));
    }
    Tree tree(tris.begin(), tris.end());
    tree.accelerate_distance_queries();
    double sum2 = 0;
    int n = 0;
    for (int k = 0; k < scan.P.rows(); k += 10, ++n)
      sum2 += tree.squared_distance(K::Point_3(scan.P(k, 0), scan.P(k, 1), scan.P(k, 2)));
    // Isotropic noise σ = 1 mm: the distance to the surface is about the normal component,
    // RMS ≈ 1 mm (a little less where the surface curves).
    double rms = std::sqrt(sum2 / n);
    EXPECT_GT(rms, 0.7) << id;
    EXPECT_LT(rms, 1.3) << id;
    // Holes: some true vertices are far from every scan point (soles, armpits, crotch).
    PointIndex index(scan.P);
    int far = 0;
    for (int v = 0; v < truth.V.rows(); ++v) {
      double d2;
      index.nearest(truth.V.row(v).transpose(), &d2);
      far += d2 > 25.0;
    }
    double hole_fraction = double(far) / truth.V.rows();
    EXPECT_GT(hole_fraction, 0.01) << id;
    EXPECT_LT(hole_fraction, 0.25) << id;
    // Landmarks: about 5 mm of noise around their template vertices.
    auto lm = nlohmann::json::parse(read_text_file(db / "scans" / (id + ".landmarks.json")));
    double lsum2 = 0;
    for (auto& [name, v] : body_landmarks()) {
      ASSERT_TRUE(lm.contains(name));
      Eigen::Vector3d p(lm[name][0], lm[name][1], lm[name][2]);
      lsum2 += (p - truth.V.row(v).transpose()).squaredNorm();
    }
    double lrms = std::sqrt(lsum2 / (3 * body_landmarks().size()));  // per coordinate
    EXPECT_GT(lrms, 2.5) << id;
    EXPECT_LT(lrms, 8.0) << id;
  }
}

TEST(SynthDb, LabelsAgreeWithMeasureOnTheTruthMeshes) {
  const fs::path db = database();
  auto subjects = read_csv(db / "subjects.csv");
  ASSERT_EQ(subjects.size(), 3u);
  auto col = [&](const std::string& name) {
    for (size_t c = 0; c < subjects[0].size(); ++c)
      if (subjects[0][c] == name) return c;
    ADD_FAILURE() << "no column " << name;
    return size_t(0);
  };
  for (size_t i = 1; i < subjects.size(); ++i) {
    Mesh truth = read_mesh(db / "truth" / (subjects[i][0] + "_p0.ply"));
    Sex sex = subjects[i][col("sex")] == "male" ? Sex::male : Sex::female;
    BodyMeasurements m = measure_body(truth.V, truth.F, sex);
    // The truth PLY stores float32 and the subject is turned on the platform: allow rounding.
    EXPECT_NEAR(std::stod(subjects[i][col("height_cm")]), m.height_cm, 0.02);
    EXPECT_NEAR(std::stod(subjects[i][col("weight_kg")]), m.weight_kg, 0.05);
    EXPECT_NEAR(std::stod(subjects[i][col("waist_cm")]), m.waist_cm, 0.3);
    EXPECT_NEAR(std::stod(subjects[i][col("hips_cm")]), m.hips_cm, 0.3);
    EXPECT_NEAR(std::stod(subjects[i][col("body_fat_pct")]), m.body_fat_pct, 0.5);
  }
}

TEST(Cli, BadInputGivesOneLineErrorAndNonZeroExit) {
  fixtures::TempDir dir;
  std::ofstream(dir / "trunc.obj") << "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 4\n";
  auto r = fixtures::run_cli("measure '" + (dir / "trunc.obj").string() + "'");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("trunc.obj' line 4"), std::string::npos) << r.output;
  r = fixtures::run_cli("measure '" + (dir / "nope.obj").string() + "'");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("nope.obj"), std::string::npos) << r.output;
  // An existing non-empty output folder is refused.
  std::ofstream(dir / "keep.txt") << "data";
  r = fixtures::run_cli("synth-db --subjects 1 --out '" + dir.path.string() + "'");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--force"), std::string::npos) << r.output;
  // Data folder that does not exist.
  r = fixtures::run_cli("synth-db --subjects 1 --out '" + (dir / "y").string() + "'",
                        "BODYMODEL_DATA=/nonexistent");
  EXPECT_NE(r.output.find("/nonexistent"), std::string::npos) << r.output;
  EXPECT_EQ(r.exit_code, 2);
  // An output folder that cannot be created (its parent is a file), and a data "folder" that is
  // a file: one line naming the path, exit 2, nothing written.
  r = fixtures::run_cli("synth-db --subjects 1 --out '" + (dir / "keep.txt" / "db").string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("keep.txt/db"), std::string::npos) << r.output;
  r = fixtures::run_cli("synth-db --subjects 1 --out '" + (dir / "z").string() + "'",
                        "BODYMODEL_DATA='" + (dir / "keep.txt").string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("keep.txt"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "z" / "subjects.csv"));
}

// synth-db --population refuses bad people files before anything is written: one line naming
// the file and what is wrong, exit 2, no output folder.
TEST(Cli, BadPopulationFilesAreRefusedBeforeWriting) {
  fixtures::TempDir dir;
  const auto run = [&](const std::string& csv, const std::string& extra = "") {
    std::ofstream(dir / "people.csv") << csv;
    return fixtures::run_cli("synth-db --subjects 2 --population '" + (dir / "people.csv").string() + "' " + extra +
                             " --out '" + (dir / "db").string() + "'");
  };
  auto r = run("SEQN,RIAGENDR,RIDAGEYR,BMXHT\n1,2,40,160\n");  // no weight, waist, ...
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("BMXWT"), std::string::npos) << r.output;
  const std::string header = "SEQN,RIAGENDR,RIDAGEYR,BMXHT,BMXWT,BMXWAIST,BMXHIP,BMXARMC,WTMECPRP\n";
  r = run(header + "1,2,12,150,40,60,70,20,1000\n2,1,15,160,50,70,80,22,1000\n");  // children only
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("under 18"), std::string::npos) << r.output;
  r = run(header + "1,2,40,160,60,80,95,28,1000\n", "--population-measurements height_cm,shoe_size");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("shoe_size"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "db"));
}
