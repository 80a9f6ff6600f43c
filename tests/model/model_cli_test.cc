// Model file round trip, generation, handle editing and the verbs' bad-input errors, on the
// in-test MakeHuman model (model_test_util.h).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "model/database.h"
#include "model/model_file.h"
#include "model/morph.h"
#include "model/pose_edit.h"
#include "model_test_util.h"
#include "support/run_cli.h"
#include "support/fixtures.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;
using fixtures::run_cli;
using testing::make_test_subjects;
using testing::shape_test_model;

// One folder per test process, removed when the process exits.
fs::path temp_dir() {
  static const fixtures::TempDir d;
  return d.path;
}

const fs::path& saved_model() {
  static fs::path p = [] {
    fs::path f = temp_dir() / "model.npz";
    save_model(f, *shape_test_model());
    return f;
  }();
  return p;
}

TEST(ModelFile, RoundTripKeepsEveryArray) {
  auto model = shape_test_model();
  BodyModel back = load_model(saved_model());
  EXPECT_EQ(back.shape.component_count(), model->shape.component_count());
  // Bases are stored as float32 (format version 2): every entry within float32 rounding.
  EXPECT_LT((back.shape.pca.basis - model->shape.pca.basis).cwiseAbs().maxCoeff(), 1e-7);
  EXPECT_NEAR((back.mean->values - model->mean->values).norm(), 0, 1e-12);
  // ... which moves a decoded body by far less than anything the tests resolve (0.01 mm).
  {
    Eigen::VectorXd c = model->shape.pca.coefficients.row(3).transpose();
    RelativeRotationDecoder d1(model->tmpl), d2(back.tmpl);
    Eigen::MatrixX3d a = d1.decode(model->encoding_of(model->shape.pca.reconstruct(c)));
    Eigen::MatrixX3d b = d2.decode(back.encoding_of(back.shape.pca.reconstruct(c)));
    EXPECT_LT((a - b).rowwise().norm().maxCoeff(), 0.01);
  }
  EXPECT_NEAR((back.shape.regression.gradients - model->shape.regression.gradients).norm(), 0, 1e-12);
  EXPECT_EQ(back.shape.regression.labels[2].name, model->shape.regression.labels[2].name);
  EXPECT_EQ(back.shape.sample_ids, model->shape.sample_ids);
  EXPECT_EQ(back.tmpl->faces(), model->tmpl->faces());
}

TEST(ModelFile, ReadsVersion1FilesWithFloat64Bases) {
  auto model = shape_test_model();
  Npz z = model_to_npz(*model);
  z.put("format_version", 1.0);
  z.put("shape_basis", model->shape.pca.basis);  // float64, as version 1 wrote it
  BodyModel back = model_from_npz(Npz::parse(z.serialize()), "v1.npz");
  EXPECT_NEAR((back.shape.pca.basis - model->shape.pca.basis).norm(), 0, 1e-12);
}

TEST(ModelFile, BasesTakeHalfTheSpaceOfFloat64) {
  auto model = shape_test_model();
  Npz z = model_to_npz(*model);
  const size_t v2 = z.serialize().size();
  z.put("shape_basis", model->shape.pca.basis);
  z.put("full_basis", model->full.pca.basis);
  const size_t v1 = z.serialize().size();
  EXPECT_LT(static_cast<double>(v2), 0.6 * static_cast<double>(v1)) << v2 << " vs " << v1 << " bytes";
}

// A population subject's unrecorded NHANES value is a missing label (NaN): the file keeps it;
// an infinite label is still corruption.
TEST(ModelFile, MissingLabelValuesLoadInfiniteOnesDoNot) {
  Npz z = model_to_npz(*shape_test_model());
  Eigen::MatrixXd labels = z.matrix("labels");
  ASSERT_GT(labels.rows(), 0);
  const Eigen::Index c = labels.cols() - 1;
  labels(0, c) = std::numeric_limits<double>::quiet_NaN();
  z.put("labels", labels);
  const BodyModel m = model_from_npz(z, "m.npz");
  EXPECT_TRUE(std::isnan(m.shape.labels(0, c)));
  EXPECT_TRUE(std::isfinite(m.shape.labels(labels.rows() - 1, c)));
  labels(0, c) = std::numeric_limits<double>::infinity();
  z.put("labels", labels);
  EXPECT_THROW(model_from_npz(z, "m.npz"), InputError);
}

// A population database's subjects.csv: the person id (seqn) and text or all-empty columns are
// not labels; an empty cell of a label is a missing value.
TEST(SubjectTable, PersonIdsAndEmptyColumnsAreNotLabels) {
  fixtures::TempDir dir;
  std::ofstream(dir / "subjects.csv") << "subject_id,sex,seqn,height_cm,fit_reached,fit_reason\n"
                                         "s0,female,109273,160.5,yes,\n"
                                         "s1,male,109312,,no,\n";
  const SubjectTable t = read_subject_table(dir / "subjects.csv");
  ASSERT_EQ(t.labels.size(), 2u);
  EXPECT_EQ(t.labels[0].name, "sex");
  EXPECT_EQ(t.labels[1].name, "height_cm");
  EXPECT_DOUBLE_EQ(t.values(0, 1), 160.5);
  EXPECT_TRUE(std::isnan(t.values(1, 1)));
  EXPECT_DOUBLE_EQ(t.values(1, 0), 1.0);
}

TEST(ModelFile, ForeignOrWrongVersionFilesAreInputErrors) {
  Npz foreign;
  foreign.put("something", Eigen::VectorXd(Eigen::VectorXd::Ones(3)));
  EXPECT_THROW(model_from_npz(foreign), InputError);
  Npz z = model_to_npz(*shape_test_model());
  z.put("format_version", 99.0);
  try {
    model_from_npz(z, "m.npz");
    FAIL() << "no error for version 99";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("version"), std::string::npos) << e.what();
  }
  z.put("format_version", 0.0);
  try {
    model_from_npz(z, "m.npz");
    FAIL() << "no error for version 0";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("model format version 0"), std::string::npos) << e.what();
  }
  fs::path corrupt = temp_dir() / "corrupt.npz";
  std::ofstream(corrupt) << "PK\x03\x04 this is not a zip";
  EXPECT_THROW(load_model(corrupt), InputError);
}

TEST(Generate, BodiesMeetWeightAndHeightConditionsAsMeasured) {
  ShapeMorpher morpher(shape_test_model());
  std::vector<LabelCondition> cond = {LabelCondition::exact("sex", 0), LabelCondition::exact("weight_kg", 65),
                                      LabelCondition::range("height_cm", 160, 180)};
  for (uint64_t seed : {1u, 2u, 3u}) {
    GeneratedBody g = generate_body(morpher, cond, seed);
    EXPECT_NEAR(g.measured.weight_kg, 65, 2.0) << g.summary.report();
    EXPECT_GE(g.measured.height_cm, 160) << g.summary.report();
    EXPECT_LE(g.measured.height_cm, 180) << g.summary.report();
    // No triangle faces against the template's after a rigid fit: the folds decoding leaves
    // (toes, eyelids) are repaired, and the conditions above are measured after the repair.
    EXPECT_EQ(flipped_triangle_count(morpher.model(), g.V), 0) << "seed " << seed;
    EXPECT_EQ(g.folds.flipped_after, 0) << "seed " << seed;
  }
}

TEST(Edit, HandlesLandWithin5mmAndTheBodyStaysPlausible) {
  auto model = shape_test_model();
  RelativeRotationDecoder decoder(model->tmpl);
  auto probe = make_test_subjects(1, 97)[0];
  // Top of the head up by 40 mm: the body has to grow.
  int top = 0;
  probe.V.col(1).maxCoeff(&top);
  EditSummary s;
  Eigen::MatrixX3d out = edit_with_handles(*model, decoder, probe.V, {{top, Eigen::Vector3d(0, 40, 0)}}, {}, &s);
  EXPECT_LT(s.max_handle_error_mm, 5.0);
  EXPECT_LE(flipped_triangle_count(*model, out), 5);
  // The change is a body change, not a stretched head: height grows by roughly the drag.
  double h0 = probe.V.col(1).maxCoeff() - probe.V.col(1).minCoeff();
  double h1 = out.col(1).maxCoeff() - out.col(1).minCoeff();
  EXPECT_NEAR(h1 - h0, 40, 10);
}

TEST(ModelCli, BadInputGivesClearErrors) {
  const std::string m = "'" + saved_model().string() + "'";
  auto probe = make_test_subjects(1, 96)[0];
  fs::path body = temp_dir() / "body.ply";
  write_mesh(body, probe.V, testing::test_makehuman().body_faces());
  const std::string b = "'" + body.string() + "'";
  const std::string out = "'" + (temp_dir() / "out.obj").string() + "'";

  auto r = run_cli("morph " + m + " --in " + b + " --set hight_cm=180 --out " + out);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("unknown label 'hight_cm'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("height_cm"), std::string::npos) << r.output;  // lists the valid ones

  r = run_cli("morph " + m + " --in " + b + " --set height_cm=400 --out " + out);
  EXPECT_NE(r.output.find("far outside the data"), std::string::npos) << r.output;

  fs::path cube = temp_dir() / "cube.obj";
  std::ofstream(cube) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
  r = run_cli("morph " + m + " --in '" + cube.string() + "' --set height_cm=170 --out " + out);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("registered to the model's template"), std::string::npos) << r.output;

  fs::path foreign = temp_dir() / "foreign.npz";
  Npz z;
  z.put("weights", Eigen::VectorXd(Eigen::VectorXd::Ones(4)));
  z.save(foreign);
  r = run_cli("generate '" + foreign.string() + "' --count 1 --out '" + (temp_dir() / "crowd").string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("not a bodymodel model file"), std::string::npos) << r.output;

  r = run_cli("generate " + m + " --count 1 --where weight_kg=abc --out '" + (temp_dir() / "crowd").string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;

  // Conditions no body of the data can meet: the crowd is written, and the exit code says so.
  const fs::path heavy = temp_dir() / "heavy_crowd";
  r = run_cli("generate " + m + " --count 1 --where weight_kg=250 --where height_cm=150 --no-girths --out '" +
              heavy.string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("1 of 1 bodies did not meet every condition"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(heavy / "labels.csv"));
}

TEST(ModelCli, GenerateRerunSkipsExistingBodiesAndReportsIt) {
  const std::string m = "'" + saved_model().string() + "'";
  const fs::path crowd = temp_dir() / "resume_crowd";
  auto args_with_seed = [&](int seed) {
    return "generate " + m + " --count 2 --where sex=female --where weight_kg=65 --seed " + std::to_string(seed) +
           " --no-girths --jobs 2 --out '" + crowd.string() + "'";
  };
  const std::string args = args_with_seed(3);
  auto r = run_cli(args);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("constraints met        2 of 2"), std::string::npos) << r.output;
  const std::string first = read_text_file(crowd / "body_001.obj");
  fs::remove(crowd / "body_001.obj");
  r = run_cli(args);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("skipped 1 existing"), std::string::npos) << r.output;
  EXPECT_TRUE(read_text_file(crowd / "body_001.obj") == first);
  r = run_cli(args_with_seed(4));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("other settings"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace bodymodel
