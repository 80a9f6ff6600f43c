// Model quality (model/model_quality.h) against a hand-computed case, and the build / fit /
// eval-model verbs on small bent cylinders (fast), including their bad-input errors.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "model/model_file.h"
#include "model/model_quality.h"
#include "model/part_pca.h"
#include "core/statistics.h"
#include "support/fixtures.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;
using fixtures::run_cli;

// A regular tetrahedron centred at the origin (circumradius √3).
Eigen::MatrixX3d tetrahedron() {
  Eigen::MatrixX3d P(4, 3);
  P << 1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1;
  return P;
}

// Hand-computed generalisation of a one-component vertex PCA. Training meshes P and P + d,
// with d a deformation that no rigid motion can absorb (Σ d_i = 0, Σ p_i × d_i = 0): the model
// is mean P + d/2 and direction d/‖d‖. The test mesh P + 0.3 d + ε P adds a radial stretch
// (orthogonal to d and to every rigid motion), which the model cannot represent: the best fit is
// P + 0.3 d with the identity as rigid placement, so every vertex is off by ε ‖p_i‖ = ε √3.
TEST(ModelQuality, VertexPcaGeneralisationHandComputed) {
  const Eigen::MatrixX3d P = tetrahedron();
  // d_i = S p_i with S symmetric and traceless (stretch along x, squeeze along y): with
  // PᵀP = 4 I this has no translation, no rotation and no radial part.
  const Eigen::Matrix3d S = Eigen::Vector3d(0.1, -0.1, 0).asDiagonal();
  const Eigen::MatrixX3d d = P * S;
  // The hand case's assumptions hold:
  ASSERT_LT(d.colwise().sum().norm(), 1e-15);
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();
  for (int i = 0; i < 4; ++i) torque += P.row(i).transpose().cross(d.row(i).transpose());
  ASSERT_LT(torque.norm(), 1e-15);
  double dot = 0;
  for (int i = 0; i < 4; ++i) dot += d.row(i).dot(P.row(i));
  ASSERT_LT(std::abs(dot), 1e-15);  // d ⟂ the radial stretch

  const VertexPcaModel model = build_vertex_pca({P, P + d});
  ASSERT_EQ(model.pca.component_count(), 1);
  // λ = ‖d‖² / 2 (two samples ±d/2, divided by N − 1 = 1); ‖d‖² = 4 · 0.02 = 0.08.
  EXPECT_NEAR(model.pca.eigenvalues(0), 0.04, 1e-12);
  const double eps = 0.05;
  const Eigen::MatrixX3d test = P + 0.3 * d + eps * P;
  const VertexPcaFit fit = fit_vertex_pca(model, test, 1);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(fit.vertex_error(i), eps * std::sqrt(3.0), 1e-9) << i;
  // The coefficient is the projection of 0.3 d − d/2 = −0.2 d on d/‖d‖: −0.2 ‖d‖ (up to the
  // basis' sign).
  EXPECT_NEAR(std::abs(fit.coefficients(0)), 0.2 * std::sqrt(0.08), 1e-9);

  // Pooling: the mean of per-mesh means and the 95th percentile of all vertices (numpy's
  // linear interpolation): errors {1, 2, 3, 4} and {10, 10, 10, 10} → means 2.5 and 10, mean
  // 6.25; pooled sorted 1 2 3 4 10 10 10 10, position 0.95 · 7 = 6.65 → 10.
  EXPECT_DOUBLE_EQ(percentile({1, 2, 3, 4, 10, 10, 10, 10}, 95), 10.0);
  EXPECT_DOUBLE_EQ(percentile({1, 2, 3, 4}, 50), 2.5);
  EXPECT_DOUBLE_EQ(percentile({1, 2, 3, 4}, 95), 3.85);  // position 2.85 → 3 + 0.85
}

// ---- the verbs ------------------------------------------------------------------------------

// A cylinder of `radius` and `height` bent by `angle` about the z axis at mid-height: a body
// with one joint. Closed, 12 × 10 quads.
Mesh bent_cylinder(double radius, double height, double angle) {
  Mesh m = fixtures::cylinder(radius, height, 12, 10);
  const double pivot = 0.5 * height;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (int i = 0; i < m.V.rows(); ++i) {
    Eigen::Vector3d p = m.V.row(i).transpose();
    if (p.y() > pivot) {
      // Blend the rotation in over the upper fifth above the pivot, so the bend is smooth.
      const double w = std::min(1.0, (p.y() - pivot) / (0.2 * height));
      const Eigen::Matrix3d Rw = Eigen::AngleAxisd(w * angle, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      const Eigen::Vector3d o(0, pivot, 0);
      p = o + Rw * (p - o);
    }
    m.V.row(i) = p.transpose();
  }
  (void)R;
  return m;
}

struct CylinderFolder {
  fixtures::TempDir dir;
  fs::path reg, csv;
  CylinderFolder() {
    reg = dir / "reg";
    fs::create_directories(reg);
    std::string rows = "mesh,subject,pose\n";
    for (int s = 0; s < 5; ++s)
      for (int p = 0; p < 3; ++p) {
        const std::string name = "c" + std::to_string(s) + "_" + std::to_string(p);
        const Mesh m = bent_cylinder(100 + 12 * s, 1500 + 60 * (s % 3), 0.25 * p - 0.1 * (s % 2));
        write_mesh(reg / (name + ".ply"), m);
        rows += name + ",s" + std::to_string(s) + ",p" + std::to_string(p) + "\n";
      }
    csv = dir / "subjects.csv";
    write_text_file(csv, rows);
  }
};

const CylinderFolder& folder() {
  static CylinderFolder f;
  return f;
}

std::string q(const fs::path& p) { return "'" + p.string() + "'"; }

const fs::path& built_model() {
  static fs::path p = [] {
    const fs::path out = folder().dir / "m.npz";
    auto r = run_cli("build " + q(folder().reg) + " --subjects " + q(folder().csv) +
                     " --standard-pose p0 --full-variance 1 --out " + q(out));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return out;
  }();
  return p;
}

TEST(ModelCli, BuildFitAndEvalOnRegisteredFolder) {
  const fs::path& model = built_model();
  ASSERT_TRUE(fs::exists(model));
  // Fit a new subject (not in the model) in a pose between the training poses.
  const fs::path in = folder().dir / "new.ply";
  write_mesh(in, bent_cylinder(118, 1560, 0.18));
  const fs::path out = folder().dir / "fitted.ply";
  auto r = run_cli("fit " + q(model) + " --in " + q(in) + " --out " + q(out) + " --pose");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out));
  std::ifstream js(folder().dir / "fitted.json");
  const nlohmann::json j = nlohmann::json::parse(js);
  EXPECT_EQ(j["sub_model"], "full");
  EXPECT_EQ(j["coefficients"].size(), j["components"].get<size_t>());
  EXPECT_GE(j["start_mean_vertex_error_mm"].get<double>(), j["vertex_error_mm"]["mean"].get<double>());
  // eval-model with a model file: test meshes from a folder.
  const fs::path test = folder().dir / "test";
  fs::create_directories(test);
  write_mesh(test / "t0.ply", bent_cylinder(118, 1560, 0.18));
  write_mesh(test / "t1.ply", bent_cylinder(95, 1480, -0.05));
  const fs::path q1 = folder().dir / "q1";
  // Model files keep no absolute paths: the training meshes' folder is given.
  r = run_cli("eval-model " + q(model) + " --test " + q(test) + " --train " + q(folder().reg) + " --samples 20 --out " +
              q(q1));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* f : {"quality.csv", "quality.md", "generalisation.csv", "model_quality.png"})
    EXPECT_TRUE(fs::exists(q1 / f)) << f;
  // Cross-validation: one model per left-out subject, built in memory.
  const fs::path q2 = folder().dir / "q2";
  r = run_cli("eval-model --cross-validate subject --registered " + q(folder().reg) + " --subjects " +
              q(folder().csv) + " --standard-pose p0 --samples 10 --out " + q(q2));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream qc(q2 / "quality.csv");
  std::string header;
  std::getline(qc, header);
  EXPECT_EQ(header.rfind("model,components,generalisation_mean_mm", 0), 0u) << header;
}

// Unconverged fits are reported, never silent: `fit --iterations 1` warns and writes converged
// false; eval-model counts them (warning, quality.csv's unconverged_fits, generalisation.csv's
// converged 0 with the fit's iterations), and with enough iterations the count is 0. The
// training starts name the training mesh the fit started from.
TEST(ModelCli, FitAndEvalModelReportUnconvergedFits) {
  const fs::path& model = built_model();
  const fs::path dir = folder().dir.path;
  const fs::path in = dir / "unconverged_in.ply";
  write_mesh(in, bent_cylinder(118, 1560, 0.18));
  auto r = run_cli("fit " + q(model) + " --in " + q(in) + " --out " + q(dir / "capped.ply") + " --pose --iterations 1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("NOT CONVERGED"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("did not converge"), std::string::npos) << r.output;
  nlohmann::json j = nlohmann::json::parse(std::ifstream(dir / "capped.json"));
  EXPECT_FALSE(j["converged"].get<bool>());
  EXPECT_TRUE(j["start_training_mesh"].is_null());
  r = run_cli("fit " + q(model) + " --in " + q(in) + " --out " + q(dir / "nearest.ply") +
              " --pose --start mean --training-starts --iterations 100");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  j = nlohmann::json::parse(std::ifstream(dir / "nearest.json"));
  EXPECT_TRUE(j["converged"].get<bool>()) << j["stop_reason"];
  ASSERT_TRUE(j["start_training_mesh"].is_string()) << r.output;
  EXPECT_EQ(j["start_training_mesh"].get<std::string>().rfind("c", 0), 0u);  // a training mesh's name
  const fs::path test = dir / "unconverged_test";
  fs::create_directories(test);
  write_mesh(test / "t0.ply", bent_cylinder(118, 1560, 0.18));
  write_mesh(test / "t1.ply", bent_cylinder(95, 1480, -0.05));
  auto unconverged = [&](const fs::path& out) {
    std::ifstream qc(out / "quality.csv");
    std::string line;
    std::getline(qc, line);
    EXPECT_EQ(line.substr(line.rfind(',') + 1), "unconverged_fits");
    std::getline(qc, line);  // the rotation-invariant model's row
    EXPECT_EQ(line.rfind("rre,", 0), 0u) << line;
    return std::stoi(line.substr(line.rfind(',') + 1));
  };
  const std::string base = "eval-model " + q(model) + " --test " + q(test) + " --train " + q(folder().reg) +
                           " --samples 0 --no-baseline --components 3 ";
  r = run_cli(base + "--iterations 1 --out " + q(dir / "q_capped"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("2 of 2 model fits stopped at their iteration cap"), std::string::npos) << r.output;
  EXPECT_EQ(unconverged(dir / "q_capped"), 2);
  std::ifstream g(dir / "q_capped" / "generalisation.csv");
  std::string header, row;
  std::getline(g, header);
  std::getline(g, row);
  EXPECT_EQ(header.substr(header.size() - 29), "converged,start_mm,iterations") << header;
  EXPECT_EQ(row.substr(row.size() - 2), ",1") << row;  // one iteration
  r = run_cli(base + "--iterations 100 --training-starts --out " + q(dir / "q_converged"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("stopped at their iteration cap"), std::string::npos) << r.output;
  EXPECT_EQ(unconverged(dir / "q_converged"), 0);
  // The part-wise model (model/part_pca.h) in place of the global PCA: more components.
  r = run_cli(base + "--parts 2 --iterations 100 --out " + q(dir / "q_parts"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("part-wise model: 2 parts"), std::string::npos) << r.output;
  EXPECT_EQ(run_cli(base + "--parts -1 --out " + q(dir / "q_bad")).exit_code, 2);
}

// eval-model's fit options reach every fit: --iterations 0 returns each start (the projection),
// reported unconverged; the default iterations lower the error from it; a negative prior is
// refused before anything is written.
TEST(ModelCli, EvalModelPassesItsFitOptions) {
  const fs::path& model = built_model();
  const fs::path dir = folder().dir.path;
  const fs::path test = dir / "fit_options_test";
  fs::create_directories(test);
  write_mesh(test / "t0.ply", bent_cylinder(118, 1560, 0.18));
  write_mesh(test / "t1.ply", bent_cylinder(95, 1480, -0.05));
  auto rre_rows = [](const fs::path& csv) {
    std::ifstream in(csv);
    std::string line;
    std::vector<std::pair<double, std::string>> rows;  // mean_mm, converged
    std::getline(in, line);
    while (std::getline(in, line)) {
      std::vector<std::string> f;
      std::stringstream ss(line);
      for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
      if (f.size() >= 9 && f[1] == "rre") rows.emplace_back(std::stod(f[4]), f[8]);
    }
    return rows;
  };
  const std::string base = "eval-model " + q(model) + " --test " + q(test) + " --samples 0 --no-baseline --components 3";
  auto r = run_cli(base + " --iterations 0 --out " + q(dir / "it0"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("2 of 2 model fits stopped at their iteration cap"), std::string::npos) << r.output;
  r = run_cli(base + " --out " + q(dir / "it20"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto start = rre_rows(dir / "it0" / "generalisation.csv");
  const auto fitted = rre_rows(dir / "it20" / "generalisation.csv");
  ASSERT_EQ(start.size(), 2u);
  ASSERT_EQ(fitted.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(start[i].second, "0");
    EXPECT_LT(fitted[i].first, start[i].first);
  }
  r = run_cli(base + " --prior -1 --out " + q(dir / "bad_prior"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("bodymodel: error: --prior must be"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "bad_prior"));
}

// One person in many poses: the shape model is the full model, whose basis the file stores once
// (full_basis_is_shape_basis); it reads back as the same model.
TEST(ModelCli, PoseModelStoresItsBasisOnce) {
  const fs::path dir = folder().dir.path;
  const fs::path csv = dir / "one_person.csv";
  write_text_file(csv, "mesh,subject,pose\nc2_0,s2,p0\nc2_1,s2,p1\nc2_2,s2,p2\n");
  const fs::path out = dir / "pose_model.npz";
  auto r = run_cli("build " + q(folder().reg) + " --subjects " + q(csv) + " --standard-pose p0 --full-variance 1 --out " +
                   q(out));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const Npz z = Npz::load(out);
  EXPECT_TRUE(z.has("shape_basis"));
  EXPECT_FALSE(z.has("full_basis"));
  ASSERT_TRUE(z.has("full_basis_is_shape_basis"));
  EXPECT_EQ(z.scalar("full_basis_is_shape_basis"), 1.0);
  const BodyModel m = load_model(out);
  ASSERT_EQ(m.full.component_count(), 2);
  EXPECT_TRUE(m.full.pca.basis == m.shape.pca.basis);
}

// `build --parts` writes a part-wise model (model_file.h, parts_*) that reads back as the one
// built from the file's full model (float32 bases); `fit` fits it, from the mean body, to one of
// its training meshes and recovers it; eval-model evaluates the file's parts. Other verbs refuse
// the file with one line, and a bad part label array is refused naming its key.
TEST(ModelCli, PartWiseModelBuildFitAndRefusals) {
  const fs::path dir = folder().dir.path;
  const fs::path model = dir / "parts.npz";
  auto r = run_cli("build " + q(folder().reg) + " --subjects " + q(folder().csv) +
                   " --standard-pose p0 --full-variance 1 --no-measure --parts 2 --out " + q(model));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("part-wise model: 2 parts"), std::string::npos) << r.output;
  EXPECT_THROW(load_model(model), InputError);
  const BodyModel m = load_model(model, PartModelUse::read);
  ASSERT_EQ(m.parts.part_count(), 2);
  ASSERT_EQ(static_cast<int>(m.parts.triangle_part.size()), m.tmpl->triangle_count());
  const PartModel again = build_part_model(m.full.pca, *m.tmpl, 2);
  EXPECT_EQ(m.parts.triangle_part, again.triangle_part);
  EXPECT_EQ(m.parts.component_part, again.component_part);
  const int K = m.parts.pca.component_count();
  ASSERT_EQ(K, again.pca.component_count());
  EXPECT_GT(K, m.full.component_count());
  // Both bases are float32 in the file ("again" is built from the stored global one): agreement
  // to float32's precision.
  EXPECT_LT((m.parts.pca.basis - again.pca.basis).cwiseAbs().maxCoeff(), 1e-5);
  EXPECT_LT((m.parts.pca.eigenvalues - again.pca.eigenvalues).cwiseAbs().maxCoeff(), 1e-5 * again.pca.eigenvalues(0));
  EXPECT_LT((m.parts.pca.mean - m.full.pca.mean).cwiseAbs().maxCoeff(), 1e-12);

  // From the mean body to the training mesh c2_1 (in the model's span): recovered.
  const fs::path out = dir / "parts_fit.ply";
  r = run_cli("fit " + q(model) + " --in " + q(folder().reg / "c2_1.ply") + " --out " + q(out) +
              " --pose --start mean --iterations 100");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  nlohmann::json j = nlohmann::json::parse(std::ifstream(dir / "parts_fit.json"));
  EXPECT_EQ(j["sub_model"], "parts");
  EXPECT_EQ(j["components"].get<int>(), K);
  EXPECT_TRUE(j["converged"].get<bool>()) << j["stop_reason"];
  EXPECT_GT(j["start_mean_vertex_error_mm"].get<double>(), 5.0);
  EXPECT_LT(j["vertex_error_mm"]["max"].get<double>(), 0.05) << r.output;
  r = run_cli("fit " + q(model) + " --in " + q(folder().reg / "c2_1.ply") + " --out " + q(dir / "global_fit.ply") +
              " --pose --global --iterations 1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  j = nlohmann::json::parse(std::ifstream(dir / "global_fit.json"));
  EXPECT_EQ(j["sub_model"], "full");
  EXPECT_EQ(j["components"].get<int>(), m.full.component_count());

  const fs::path test = dir / "parts_test";
  fs::create_directories(test);
  write_mesh(test / "t0.ply", bent_cylinder(118, 1560, 0.18));
  const std::string eval = "eval-model " + q(model) + " --test " + q(test) + " --samples 0 --no-baseline --components " +
                           std::to_string(K) + " --iterations 2 ";
  r = run_cli(eval + "--out " + q(dir / "q_file_parts"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("part-wise model (the file's): 2 parts, " + std::to_string(K) + " components"),
            std::string::npos)
      << r.output;
  r = run_cli(eval + "--parts 3 --out " + q(dir / "q_other_parts"));
  EXPECT_EQ(r.exit_code, 2) << r.output;

  // A verb that cannot use it: one line naming the key.
  r = run_cli("generate " + q(model) + " --count 1 --out " + q(dir / "gen_parts"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("bodymodel: error: '" + model.string() + "' holds a part-wise pose model"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(dir / "gen_parts"));

  // Bad part labels: out of range, and a triangle moved to the other part (the parts' arrays
  // then no longer match): refused, naming 'parts_triangle_part'.
  for (int bad = 0; bad < 2; ++bad) {
    Npz z = Npz::load(model);
    Eigen::VectorXi label = z.int_vector("parts_triangle_part");
    label(7) = bad == 0 ? 2 : 1 - label(7);
    z.put("parts_triangle_part", label);
    const fs::path broken = dir / ("broken_parts" + std::to_string(bad) + ".npz");
    z.save(broken);
    r = run_cli("fit " + q(broken) + " --in " + q(folder().reg / "c2_1.ply") + " --out " + q(dir / "broken.ply") +
                " --pose");
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_NE(r.output.find("bodymodel: error: '" + broken.string() + "'"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(bad == 0 ? "'parts_triangle_part' element 7 is 2" : "in 'parts_triangle_part'"),
              std::string::npos)
        << r.output;
    EXPECT_FALSE(fs::exists(dir / "broken.ply"));
  }
}

// Bad input ends with one line "bodymodel: error: ..." naming the file and the problem, exit 2,
// and writes nothing.
TEST(ModelCli, FitBuildEvalBadInput) {
  const fs::path& model = built_model();
  const fs::path dir = folder().dir.path;
  // subjects.csv naming meshes the folder does not have.
  const fs::path bad_csv = dir / "bad_subjects.csv";
  write_text_file(bad_csv, "mesh,subject,pose\nc0_0,s0,p0\nghost_a,s9,p0\nghost_b,s9,p1\n");
  auto r = run_cli("build " + q(folder().reg) + " --subjects " + q(bad_csv) + " --out " + q(dir / "x.npz"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("bodymodel: error: '" + bad_csv.string() + "' names 2 mesh(es)"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("ghost_a, ghost_b"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "x.npz"));
  // A mesh of the wrong topology.
  const fs::path wrong = dir / "wrong.ply";
  write_mesh(wrong, fixtures::uv_sphere(100, 6, 8));
  r = run_cli("fit " + q(model) + " --in " + q(wrong) + " --out " + q(dir / "w.ply"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("bodymodel: error: '" + wrong.string() + "'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("registered to the model's template"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "w.ply"));
  const fs::path test = dir / "badtest";
  fs::create_directories(test);
  fs::copy_file(wrong, test / "wrong.ply");
  r = run_cli("eval-model " + q(model) + " --test " + q(test) + " --samples 0 --out " + q(dir / "qx"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("test mesh '" + (test / "wrong.ply").string() + "'"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "qx"));
  // K larger than the model.
  r = run_cli("fit " + q(model) + " --in " + q(folder().reg / "c1_1.ply") + " --out " + q(dir / "k.ply") +
              " --pose --components 999");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--components 999: the full model of"), std::string::npos) << r.output;
  r = run_cli("eval-model " + q(model) + " --test " + q(folder().reg) + " --components 5,999 --out " + q(dir / "qk"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--components 999"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace bodymodel
