// The eval-regressors verb end to end on a small synthetic .npz: report files and their columns,
// a label the linear models recover exactly, and the bad-input messages (exit code 2).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "core/io/npz.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct CliRun {
  int code;
  std::string output;  // stdout + stderr
};

CliRun run(const std::string& args) {
  const std::string cmd = std::string(BODYMODEL_EXE) + " " + args + " 2>&1";
  CliRun r{0, ""};
  FILE* p = popen(cmd.c_str(), "r");
  std::array<char, 4096> buf{};
  while (size_t n = fread(buf.data(), 1, buf.size(), p)) r.output.append(buf.data(), n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class EvalRegressorsCli : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(BODYMODEL_EXE)) GTEST_SKIP() << "bodymodel not built: " << BODYMODEL_EXE;
    dir_ = fs::temp_directory_path() / ("bodymodel_eval_regressors_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    if (!dir_.empty()) fs::remove_all(dir_, ec);
  }
  // 40 subjects, 6 features; labels: exactly linear, linear + noise, NaN-holed, constant.
  fs::path write_model(bool with_nan) {
    std::mt19937 rng(5);
    std::normal_distribution<double> n(0, 1);
    Eigen::MatrixXd X(40, 6), Y(40, 4);
    for (int i = 0; i < 40; ++i)
      for (int j = 0; j < 6; ++j) X(i, j) = n(rng);
    for (int i = 0; i < 40; ++i) {
      Y(i, 0) = 170 + 8 * X(i, 0) - 3 * X(i, 2);
      Y(i, 1) = 70 + 10 * X(i, 1) + n(rng);
      Y(i, 2) = (with_nan && i % 10 == 3) ? std::numeric_limits<double>::quiet_NaN() : 80 + 5 * X(i, 3);
      Y(i, 3) = 1.0;
    }
    Npz z;
    z.put("shape_coefficients", X);
    z.put("labels", Y);
    z.put_text("label_names", R"(["height_cm","weight_kg","waist_cm","always_one"])");
    z.put_text("label_units", R"(["cm","kg","cm",""])");
    std::string ids;
    for (int i = 0; i < 40; ++i) ids += (i ? ",s" : "s") + std::to_string(i);
    z.put_text("subject_ids", ids);
    const fs::path p = dir_ / (with_nan ? "model_nan.npz" : "model.npz");
    z.save(p);
    return p;
  }
  fs::path dir_;
};

TEST_F(EvalRegressorsCli, WritesTheReportFiles) {
  const fs::path model = write_model(true);
  const fs::path out = dir_ / "report";
  const CliRun r = run("eval-regressors " + model.string() +
                    " --folds 5 --labels height_cm,weight_kg,waist_cm"
                    " --regressors simple_linear,filtered_linear,gaussian_process --jobs 2 --out " +
                    out.string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("4 rows without a value were skipped"), std::string::npos) << r.output;
  const std::string csv = read_file(out / "regressors.csv");
  std::istringstream lines(csv);
  std::string header, line;
  std::getline(lines, header);
  EXPECT_EQ(header.rfind("regressor,label,unit,rmse,mae,folds", 0), 0u) << header;
  int rows = 0;
  while (std::getline(lines, line)) {
    ++rows;
    if (line.rfind("simple_linear,height_cm,cm,", 0) == 0) {
      const double rmse = std::stod(line.substr(std::string("simple_linear,height_cm,cm,").size()));
      EXPECT_LT(rmse, 1e-6) << line;  // an exactly linear label
    }
    if (line.rfind("gaussian_process,weight_kg,kg,", 0) == 0) {
      const double rmse = std::stod(line.substr(std::string("gaussian_process,weight_kg,kg,").size()));
      EXPECT_LT(rmse, 1.5) << line;  // noise σ 1 kg
    }
  }
  EXPECT_EQ(rows, 9);
  EXPECT_NE(read_file(out / "directions.csv").find("regressor,label,mean_deg,std_deg"), std::string::npos);
  const std::string png = read_file(out / "filtered_components.png");
  ASSERT_GT(png.size(), 1000u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
}

TEST_F(EvalRegressorsCli, BadInputGivesOneClearLine) {
  const fs::path model = write_model(false);
  CliRun r = run("eval-regressors " + model.string() + " --labels always_one --out " + (dir_ / "r1").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("'always_one' is constant"), std::string::npos) << r.output;
  r = run("eval-regressors " + model.string() + " --folds 50 --labels height_cm --out " + (dir_ / "r2").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("40 subjects but 50 folds"), std::string::npos) << r.output;
  r = run("eval-regressors " + model.string() + " --labels shoe_size --out " + (dir_ / "r3").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("'shoe_size' is not in"), std::string::npos) << r.output;
  r = run("eval-regressors " + (dir_ / "missing.npz").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_FALSE(fs::exists(dir_ / "r1" / "regressors.csv"));
}

// --inputs with a model: the named labels are the features instead of the coefficients (the
// (sex, age, stature, weight) baseline of the ANSUR study). A label that is an exact linear function
// of two other labels and unrelated to the coefficients is recovered exactly from those labels and
// not from the coefficients; an ANSUR label without a unit is in mm.
TEST_F(EvalRegressorsCli, LabelFeaturesReplaceTheCoefficients) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0, 1);
  const int N = 60;
  Eigen::MatrixXd X(N, 5), Y(N, 3);
  for (int i = 0; i < N; ++i) {
    for (int j = 0; j < 5; ++j) X(i, j) = n(rng);
    Y(i, 0) = 1700 + 80 * n(rng);                             // ansur2_stature
    Y(i, 1) = 80 + 12 * n(rng);                               // ansur2_weightkg
    Y(i, 2) = 300 + 1.0 * Y(i, 0) + 4 * Y(i, 1);              // ansur2_span
  }
  Npz z;
  z.put("shape_coefficients", X);
  z.put("labels", Y);
  z.put_text("label_names", R"(["ansur2_stature","ansur2_weightkg","ansur2_span"])");
  z.put_text("label_units", R"(["","",""])");
  const fs::path model = dir_ / "ansur_model.npz";
  z.save(model);
  const auto span_rmse = [&](const std::string& extra, const std::string& out) {
    const CliRun r = run("eval-regressors " + model.string() + " --folds 5 --labels ansur2_span --regressors "
                         "simple_linear --no-directions " + extra + " --out " + (dir_ / out).string());
    EXPECT_EQ(r.code, 0) << r.output;
    const std::string csv = read_file(dir_ / out / "regressors.csv");
    const std::string key = "simple_linear,ansur2_span,mm,";
    const auto at = csv.find(key);
    EXPECT_NE(at, std::string::npos) << csv;
    return at == std::string::npos ? -1.0 : std::stod(csv.substr(at + key.size()));
  };
  const double from_labels = span_rmse("--inputs ansur2_stature,ansur2_weightkg", "labels");
  const double from_coefficients = span_rmse("", "coefficients");
  EXPECT_GE(from_labels, 0);
  EXPECT_LT(from_labels, 1e-6);
  EXPECT_GT(from_coefficients, 50);  // sd of the span ≈ √(80² + 48²) ≈ 93 mm
  const CliRun bad = run("eval-regressors " + model.string() + " --labels ansur2_span --inputs sex,ansur2_stature --out " +
                         (dir_ / "bad").string());
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.output.find("--inputs: 'sex' is not a label"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(dir_ / "bad" / "regressors.csv"));
}

TEST_F(EvalRegressorsCli, PoseLabelsOfTheFullModelInDegreesWithScansGroupedBySubject) {
  // 20 subjects × 3 scans; a joint angle (radians) = 0.2·x0 + N(0, 0.1) → RMSE ≈ 0.1 rad ≈ 5.7°.
  std::mt19937 rng(9);
  std::normal_distribution<double> n(0, 1);
  Eigen::MatrixXd X(60, 5), Y(60, 2);
  std::string ids;
  for (int i = 0; i < 60; ++i) {
    for (int j = 0; j < 5; ++j) X(i, j) = n(rng);
    Y(i, 0) = 0.2 * X(i, 0) + 0.1 * n(rng);
    Y(i, 1) = 170 + (i / 3);
    char id[32];
    std::snprintf(id, sizeof id, "%ss%03d_p%d", i ? "," : "", i / 3, i % 3);
    ids += id;
  }
  Npz z;
  z.put("full_coefficients", X);
  z.put("full_labels", Y);
  z.put_text("full_label_names", R"(["pose:upperarm01.L:rx","height_cm"])");
  z.put_text("full_label_units", R"(["rad","cm"])");
  z.put_text("full_sample_ids", ids);
  const fs::path model = dir_ / "full.npz", out = dir_ / "pose";
  z.save(model);
  const CliRun r = run("eval-regressors " + model.string() + " --set full --folds 5 --labels 'pose:*'" +
                       " --regressors simple_linear,filtered_linear --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("(20 subjects)"), std::string::npos) << r.output;
  const std::string csv = read_file(out / "regressors.csv");
  const std::string key = "filtered_linear,pose:upperarm01.L:rx,deg,";
  const auto at = csv.find(key);
  ASSERT_NE(at, std::string::npos) << csv;
  const double rmse = std::stod(csv.substr(at + key.size()));
  EXPECT_GT(rmse, 3.5);
  EXPECT_LT(rmse, 9.0);
}

TEST_F(EvalRegressorsCli, SyntheticShapeModelInProcessWithLabelNoise) {
  // 12 MakeHuman subjects → a shape model of 11 components (every component kept), evaluated in
  // one command; the built model is saved and gives the same table from the file.
  const fs::path out = dir_ / "syn", model = dir_ / "syn.npz";
  CliRun r = run("eval-regressors --synthetic 12 --folds 3 --no-directions --regressors simple_linear,filtered_linear"
                 " --labels height_cm,weight_kg --save-model " + model.string() + " --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("12 rows (12 subjects), 11 components"), std::string::npos) << r.output;
  const std::string csv = read_file(out / "regressors.csv");
  const std::string key = "simple_linear,height_cm,cm,";
  const auto at = csv.find(key);
  ASSERT_NE(at, std::string::npos) << csv;
  const double rmse = std::stod(csv.substr(at + key.size()));
  EXPECT_GT(rmse, 0.0);
  EXPECT_LT(rmse, 10.0);  // synth-db heights spread ≈ 20 cm (sd); 8 training subjects halve that
  r = run("eval-regressors " + model.string() + " --folds 3 --no-directions --regressors simple_linear,filtered_linear"
          " --labels height_cm,weight_kg --out " + (dir_ / "from_file").string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(read_file(dir_ / "from_file" / "regressors.csv"), csv);
  // Label noise: announced with its σ, and the error against the noisy labels grows.
  r = run("eval-regressors " + model.string() + " --folds 3 --no-directions --regressors simple_linear"
          " --labels height_cm --label-noise height_cm=5 --out " + (dir_ / "noisy").string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("height_cm 5 cm"), std::string::npos) << r.output;
  const std::string noisy = read_file(dir_ / "noisy" / "regressors.csv");
  const auto at2 = noisy.find(key);
  ASSERT_NE(at2, std::string::npos) << noisy;
  EXPECT_GT(std::stod(noisy.substr(at2 + key.size())), rmse + 1.0);
  // Bad combinations: one line, exit 2.
  r = run("eval-regressors " + model.string() + " --synthetic 12 --out " + (dir_ / "x").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("give one of a model file, --synthetic N or --table FILE"), std::string::npos) << r.output;
  r = run("eval-regressors --out " + (dir_ / "x").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("no model file given"), std::string::npos) << r.output;
  r = run("eval-regressors " + model.string() + " --label-noise weight=heavy --out " + (dir_ / "x").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("not a non-negative number"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir_ / "x" / "regressors.csv"));
}

}  // namespace
}  // namespace bodymodel
