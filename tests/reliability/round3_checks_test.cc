// Issue 40 ("Reliability, round 3"): units and ranges. Each case is a reproduction of the issue
// on tiny inputs made here (the tetrahedron model of tests/fuzz/tiny_files.h, spheres): the tool
// must end with exit 2 and one line `bodymodel: error: …` naming the file, row or option, and
// write nothing. The library checks have their own unit tests (tests/core/body_size_test.cc,
// tests/model/label_ranges_test.cc).
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "fuzz/tiny_files.h"
#include "model/model_file.h"
#include "reliability/cli_helpers.h"
#include "support/fixtures.h"

namespace bodymodel {
namespace {

using namespace reliability;

// Runs `bodymodel args…`; expects exit 2 and exactly one error line holding every `words`.
void expect_refused(const std::vector<std::string>& args, const fs::path& log, const std::vector<std::string>& words) {
  std::string out;
  const int code = run_bodymodel(args, log, &out);
  std::string cmd;
  for (const auto& a : args) cmd += a + " ";
  SCOPED_TRACE(cmd);
  EXPECT_EQ(code, 2) << out;
  const auto lines = error_lines(out);
  ASSERT_EQ(lines.size(), 1u) << out;
  for (const auto& w : words) EXPECT_NE(lines[0].find(w), std::string::npos) << lines[0] << "\nlacks: " << w;
}

// The tiny tetrahedron model, as if built from meshes in metres (build --scale 1000).
void write_metres_model(const fs::path& p) {
  tiny::model_npz().save(p);
  BodyModel m = load_model(p);
  m.metadata["source"] = {{"mm_per_unit", 1000}};
  save_model(p, m);
}

// The tetrahedron of the tiny model at a body's size in mm (1.7 m along each axis).
void write_body_mm(const fs::path& p) { write_mesh(p, 1700 * tiny::tetra_vertices(), tiny::tetra_faces()); }

// ---- 8. a body mesh in the wrong unit against a model ------------------------------------------

TEST(Round3Units, FitRefusesABodyInTheWrongUnit) {
  fixtures::TempDir dir;
  const fs::path model = dir / "model.npz";
  write_metres_model(model);
  write_body_mm(dir / "body_mm.obj");
  write_mesh(dir / "origin.obj", Eigen::MatrixX3d::Zero(4, 3), tiny::tetra_faces());
  // A mesh in mm against a model built from metres: --scale 1000 by default, a 1.7 km body.
  expect_refused({"fit", model.string(), "--in", (dir / "body_mm.obj").string(), "--out", (dir / "f.obj").string()},
                 dir / "log", {"body_mm.obj", "mm tall", "the model's --scale 1000", "use --scale 1"});
  // Every vertex at the origin "fitted".
  expect_refused({"fit", model.string(), "--in", (dir / "origin.obj").string(), "--scale", "1", "--out",
                  (dir / "f.obj").string()},
                 dir / "log", {"origin.obj", "one point", "not a body"});
  EXPECT_FALSE(fs::exists(dir / "f.obj"));
  EXPECT_FALSE(fs::exists(dir / "f.json"));
}

TEST(Round3Units, EvalModelRefusesTestMeshesInTheWrongUnit) {
  fixtures::TempDir dir;
  const fs::path model = dir / "model.npz";
  write_metres_model(model);
  fs::create_directories(dir / "test");
  write_body_mm(dir / "test" / "t0.obj");
  expect_refused({"eval-model", model.string(), "--test", (dir / "test").string(), "--samples", "0", "--no-baseline",
                  "--out", (dir / "q").string()},
                 dir / "log", {"test mesh", "t0.obj", "mm tall", "--scale 1"});
  EXPECT_FALSE(fs::exists(dir / "q"));
}

TEST(Round3Units, MorphAndEditRefuseABodyInMetres) {
  fixtures::TempDir dir;
  tiny::model_npz().save(dir / "model.npz");
  // The tetrahedron at 1.7 m, written in metres: 1.7 mm for verbs that take mm.
  write_mesh(dir / "metres.obj", 1.7 * tiny::tetra_vertices(), tiny::tetra_faces());
  const std::string model = (dir / "model.npz").string(), body = (dir / "metres.obj").string();
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"morph", model, "--in", body, "--set", "height_cm=170", "--out", (dir / "m.obj").string()},
           {"edit", model, "--in", body, "--handle", "0:1,0,0", "--out", (dir / "e.obj").string()}}) {
    expect_refused(args, dir / "log", {"metres.obj", "mm tall", "must be in millimetres", "looks like metres"});
  }
  EXPECT_FALSE(fs::exists(dir / "m.obj"));
  EXPECT_FALSE(fs::exists(dir / "e.obj"));
}

// ---- 8 (character) and the minor: a judge pose naming a bone the skeleton lacks ----------------

TEST(Round3Units, CharacterJudgePosesAreCheckedForUnitAndBones) {
  fixtures::TempDir dir;
  tiny::model_npz().save(dir / "model.npz");  // with a two-bone rig (root, child)
  const std::string model = (dir / "model.npz").string();
  write_mesh(dir / "small.obj", tiny::tetra_vertices(), tiny::tetra_faces());  // 1 mm
  expect_refused({"character", model, "--judge-poses", (dir / "small.obj").string(), "--out", (dir / "c").string()},
                 dir / "log", {"--judge-poses", "small.obj", "mm tall"});
  EXPECT_FALSE(fs::exists(dir / "c"));
  // A body of the right size whose pose file names a bone the model's skeleton does not have:
  // the row was skipped and the fit started from a pose the file does not describe.
  write_body_mm(dir / "reg.obj");
  write_text_file(dir / "reg.pose.csv", "bone,rx,ry,rz\nroot,0,0,0\nelbow.L,0,0,0.7\n");
  expect_refused({"character", model, "--judge-poses", (dir / "reg.obj").string(), "--out", (dir / "c").string()},
                 dir / "log", {"reg.pose.csv", "elbow.L", "unknown bone"});
  EXPECT_FALSE(fs::exists(dir / "c"));
  // The scan a judge pose was registered to, in metres while register-mesh.json says mm.
  fs::remove(dir / "reg.pose.csv");
  fs::create_directories(dir / "scans");
  write_mesh(dir / "scans" / "reg.off", 1.7 * tiny::tetra_vertices(), tiny::tetra_faces());
  write_text_file(dir / "register-mesh.json", R"({"scale": 1, "up": "y"})");
  expect_refused({"character", model, "--judge-poses", (dir / "reg.obj").string(), "--judge-scans",
                  (dir / "scans").string(), "--out", (dir / "c").string()},
                 dir / "log", {"--judge-scans", "reg.off", "register-mesh.json", "looks like it is in metres"});
  EXPECT_FALSE(fs::exists(dir / "c"));
}

// ---- 9. labels of `build --subjects` --------------------------------------------------------------

TEST(Round3Ranges, BuildRefusesNonFiniteAndHugeLabels) {
  fixtures::TempDir dir;
  fs::create_directories(dir / "reg");
  const Mesh s = fixtures::uv_sphere(450, 8, 12);
  for (const char* n : {"a", "b", "c"}) write_mesh(dir / "reg" / (std::string(n) + ".ply"), s);
  for (const auto& [value, words] : std::vector<std::pair<std::string, std::vector<std::string>>>{
           {"inf", {"not a finite number"}}, {"nan", {"not a finite number"}}, {"1e308", {"outside the range"}}}) {
    write_text_file(dir / "subjects.csv",
                    "mesh,subject,pose,height_cm\na,s0,standard,170\nb,s1,standard," + value + "\nc,s2,standard,160\n");
    std::vector<std::string> expect = {"subjects.csv' line 3, column 'height_cm'"};
    expect.insert(expect.end(), words.begin(), words.end());
    expect_refused({"build", (dir / "reg").string(), "--subjects", (dir / "subjects.csv").string(), "--out",
                    (dir / "m.npz").string()},
                   dir / "log", expect);
    EXPECT_FALSE(fs::exists(dir / "m.npz")) << value;
  }
}

// ---- 10. synth-db --reuse-fits slider values ------------------------------------------------------

TEST(Round3Ranges, SynthDbRefusesStoredSlidersOutsideTheirRange) {
  fixtures::TempDir dir;
  write_text_file(dir / "people.csv",
                  "SEQN,RIAGENDR,RIDAGEYR,BMXHT,BMXWT,BMXWAIST,BMXHIP,BMXARMC,WTMECPRP\n"
                  "1,2,40,160,60,80,95,28,1000\n2,1,50,175,80,90,100,32,1000\n");
  const std::string head =
      "id,sex,age_years,fitted,reached,extrapolated,reason,slider_gender,slider_age,slider_muscle,slider_weight,"
      "slider_height\n";
  for (const auto& [cell, words] : std::vector<std::pair<std::string, std::vector<std::string>>>{
           {"7", {"7 is outside 0 … 1"}}, {"nan", {"not a finite number"}}, {"tall", {"not a number"}}}) {
    write_text_file(dir / "fit.csv", head + "1,female,40,height_cm,1,0,,0,0.5,0.5,0.5,0.5\n" +
                                         "2,male,50,height_cm,1,0,,1,0.6,0.5,0.5," + cell + "\n");
    std::vector<std::string> expect = {"fit.csv' line 3, column 'slider_height'"};
    expect.insert(expect.end(), words.begin(), words.end());
    expect_refused({"synth-db", "--subjects", "2", "--population", (dir / "people.csv").string(),
                    "--population-measurements", "height_cm", "--reuse-fits", (dir / "fit.csv").string(),
                    "--truth-only", "--out", (dir / "db").string()},
                   dir / "log", expect);
    EXPECT_FALSE(fs::exists(dir / "db")) << cell;
  }
}

// ---- 11. eval-population's baseline on too few people ---------------------------------------------

TEST(Round3Ranges, EvalPopulationNeedsPeopleForItsBaseline) {
  fixtures::TempDir dir;
  tiny::model_npz().save(dir / "model.npz");
  write_text_file(dir / "people.csv",
                  "SEQN,RIAGENDR,RIDAGEYR,BMXHT,BMXWT,BMXWAIST,BMXHIP,BMXARMC,WTMECPRP\n"
                  "1,2,40,160,60,80,95,28,1000\n2,1,50,175,80,90,100,32,1000\n");
  // Two eligible people, both drawn: the baseline was fitted on none and predicted 0 cm.
  expect_refused({"eval-population", (dir / "model.npz").string(), "--population", (dir / "people.csv").string(),
                  "--count", "2", "--out", (dir / "r").string()},
                 dir / "log", {"people.csv", "baseline", "at least 20", "found 0"});
  EXPECT_FALSE(fs::exists(dir / "r"));
}

// ---- 16. contradictory targets, each within its range ------------------------------------------

// A closed cylinder of `radius` and `height` (mm) whose upper half is bent by `angle` about z.
Mesh bent_cylinder(double radius, double height, double angle) {
  Mesh m = fixtures::cylinder(radius, height, 12, 10);
  const double pivot = 0.5 * height;
  for (int i = 0; i < m.V.rows(); ++i) {
    Eigen::Vector3d p = m.V.row(i).transpose();
    if (p.y() <= pivot) continue;
    const double w = std::min(1.0, (p.y() - pivot) / (0.2 * height)) * angle;
    const Eigen::Vector3d o(0, pivot, 0);
    m.V.row(i) = (o + Eigen::AngleAxisd(w, Eigen::Vector3d::UnitZ()) * (p - o)).transpose();
  }
  return m;
}

TEST(Round3Ranges, ContradictoryTargetsNameTheLabels) {
  // A model of five bent cylinders (built in a fraction of a second), whose measured girths all
  // lie in 62 … 92 cm: a thick neck and hips over a thin chest and waist turn the body inside out.
  fixtures::TempDir dir;
  fs::create_directories(dir / "reg");
  std::string rows = "mesh,subject,pose\n";
  for (int s = 0; s < 5; ++s)
    for (int p = 0; p < 3; ++p) {
      const std::string name = "c" + std::to_string(s) + "_" + std::to_string(p);
      write_mesh(dir / "reg" / (name + ".ply"), bent_cylinder(100 + 12 * s, 1500 + 60 * (s % 3), 0.25 * p - 0.1 * (s % 2)));
      rows += name + ",s" + std::to_string(s) + ",p" + std::to_string(p) + "\n";
    }
  write_text_file(dir / "subjects.csv", rows);
  std::string out;
  ASSERT_EQ(run_bodymodel({"build", (dir / "reg").string(), "--subjects", (dir / "subjects.csv").string(),
                           "--standard-pose", "p0", "--full-variance", "1", "--out", (dir / "m.npz").string()},
                          dir / "log", &out),
            0)
      << out;
  expect_refused({"morph", (dir / "m.npz").string(), "--set", "neck_cm=92", "--set", "chest_cm=62", "--set",
                  "hips_cm=92", "--set", "waist_cm=62", "--out", (dir / "o.obj").string()},
                 dir / "log",
                 {"the targets neck_cm = 92, chest_cm = 62, hips_cm = 92, waist_cm = 62 ask for a body the model "
                  "cannot make"});
  EXPECT_FALSE(fs::exists(dir / "o.obj"));
}

// ---- minors: scanify's options and --subject-regex -------------------------------------------------

TEST(Round3Ranges, ScanifyBoundsItsOptionsAndWritesNothingOnABadSubjectRegex) {
  fixtures::TempDir dir;
  const Mesh s = fixtures::uv_sphere(450, 8, 12);
  write_mesh(dir / "p01_a.off", s);
  write_mesh(dir / "other.off", s);
  const std::string a = (dir / "p01_a.off").string(), b = (dir / "other.off").string();
  // A scan its own reader refused, and a bare std::bad_alloc.
  expect_refused({"scanify", a, "--noise-mm", "1e300", "--out", (dir / "n.ply").string()}, dir / "log",
                 {"--noise-mm", "1e+300"});
  expect_refused({"scanify", a, "--landmark-noise-mm", "1e300", "--out", (dir / "n.ply").string()}, dir / "log",
                 {"--landmark-noise-mm"});
  expect_refused({"scanify", a, "--points", "2000000000", "--out", (dir / "n.ply").string()}, dir / "log",
                 {"--points", "2000000000"});
  EXPECT_FALSE(fs::exists(dir / "n.ply"));
  // The pattern misses the second stem: the first scan was written before, with no scans.csv.
  expect_refused({"scanify", a, b, "--subject-regex", "^(p[0-9]+)_", "--out", (dir / "db").string()}, dir / "log",
                 {"--subject-regex", "other", "nothing written"});
  EXPECT_FALSE(fs::exists(dir / "db"));
}

}  // namespace
}  // namespace bodymodel
