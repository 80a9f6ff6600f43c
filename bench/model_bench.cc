// Statistical model benchmarks (issue 5):
//  * BM_GenerateBodies: bodies per second of `generate`, including writing the OBJ, without and
//    with label conditions (weight = 65 kg, height 160..180 cm, female), on a model built from
//    30 MakeHuman bodies.
//  * BM_Generalisation: reconstruction error of HELD-OUT subjects (all their scans, posed ones
//    included) vs the number of components, for the RRE model and for plain vertex-position
//    PCA of the same (rigidly aligned) meshes. Needs a synthetic database: BODYMODEL_BENCH_DB
//    (default /tmp/model_db, made by `bodymodel synth-db --subjects 40 --poses-per-subject 4`);
//    the last quarter of the subjects is held out. Prints a table to stderr.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <filesystem>
#include <random>

#include "core/geometry.h"
#include "core/io/mesh_io.h"
#include "core/makehuman.h"
#include "core/measure.h"
#include "model/database.h"
#include "model/morph.h"
#include "model/pca.h"
#include "model/pose_edit.h"

namespace bodymodel {
namespace {

std::shared_ptr<const BodyModel> bench_model() {
  static std::shared_ptr<const BodyModel> model = [] {
    MakeHuman mh = MakeHuman::load();
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(0, 1);
    ModelBuildInput in;
    in.F = mh.body_faces();
    in.subject_labels = {{"sex", ""}, {"height_cm", "cm"}, {"weight_kg", "kg"}};
    const int n = 30;
    in.subject_label_values.resize(n, 3);
    in.pose_label_values.resize(n, 0);
    for (int i = 0; i < n; ++i) {
      MacroSettings s;
      bool male = i % 2;
      s.gender = male ? 0.85 + 0.15 * u(rng) : 0.15 * u(rng);
      s.age = 0.45 + 0.4 * u(rng);
      s.muscle = 0.15 + 0.7 * u(rng);
      s.weight = 0.15 + 0.7 * u(rng);
      s.height = 0.15 + 0.7 * u(rng);
      Eigen::MatrixX3d V = mh.body(s).mesh.V;
      BodyMeasurements m = measure_body(V, in.F);
      in.meshes.push_back(V);
      in.scan_ids.push_back("b" + std::to_string(i));
      in.subject_ids.push_back("b" + std::to_string(i));
      in.is_standard_pose.push_back(1);
      in.subject_label_values.row(i) << (male ? 1.0 : 0.0), m.height_cm, m.weight_kg;
    }
    return std::make_shared<const BodyModel>(build_body_model(in));
  }();
  return model;
}

void BM_GenerateBodies(benchmark::State& state) {
  auto model = bench_model();
  ShapeMorpher morpher(model);
  std::vector<LabelCondition> cond;
  if (state.range(0))
    cond = {LabelCondition::exact("sex", 0), LabelCondition::exact("weight_kg", 65),
            LabelCondition::range("height_cm", 160, 180)};
  auto out = std::filesystem::temp_directory_path() / "bodymodel_bench_body.obj";
  uint64_t seed = 1;
  for (auto _ : state) {
    GeneratedBody g = generate_body(morpher, cond, seed++);
    write_mesh(out, g.V, model->tmpl->faces());
  }
  state.counters["bodies_per_s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
  std::filesystem::remove(out);
}
BENCHMARK(BM_GenerateBodies)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Generalisation(benchmark::State& state) {
  namespace fs = std::filesystem;
  const char* env = std::getenv("BODYMODEL_BENCH_DB");
  fs::path db = env ? env : "/tmp/model_db";
  if (!fs::exists(db / "scans.csv")) {
    state.SkipWithError(("no database at " + db.string() + " (set BODYMODEL_BENCH_DB)").c_str());
    return;
  }
  for (auto _ : state) {
    ModelBuildInput in = read_registered_database(db / "truth", db);
    std::vector<std::string> subjects;
    for (auto& s : in.subject_ids)
      if (std::find(subjects.begin(), subjects.end(), s) == subjects.end()) subjects.push_back(s);
    const size_t n_train = subjects.size() - subjects.size() / 4;
    std::vector<int> train, test;
    for (size_t i = 0; i < in.meshes.size(); ++i) {
      size_t si = std::find(subjects.begin(), subjects.end(), in.subject_ids[i]) - subjects.begin();
      (si < n_train ? train : test).push_back(static_cast<int>(i));
    }
    // RRE: template = mean of the training standard-pose meshes; encodings relative to their mean.
    const Eigen::MatrixX3d& ref = in.meshes[train[0]];
    Eigen::MatrixX3d rest = Eigen::MatrixX3d::Zero(ref.rows(), 3);
    int ns = 0;
    for (int i : train)
      if (in.is_standard_pose[i]) {
        rest += apply(fit_rigid_motion(in.meshes[i], ref), in.meshes[i]);
        ++ns;
      }
    rest /= ns;
    auto tmpl = std::make_shared<EncodingTemplate>(rest, in.F);
    const int D = tmpl->encoding_size();
    Eigen::MatrixXd X(D, train.size());
    for (size_t k = 0; k < train.size(); ++k) X.col(k) = encode_absolute(*tmpl, in.meshes[train[k]]);
    auto mean = EncodingMean::from_values(X.rowwise().mean());
    for (size_t k = 0; k < train.size(); ++k) {
      Eigen::VectorXd a = X.col(k);
      X.col(k) = relative_to(mean, a).values;
    }
    Pca rre = fit_pca(X, {1.0, -1});
    X.resize(0, 0);
    std::vector<Eigen::VectorXd> test_enc;
    for (int i : test) test_enc.push_back(relative_to(mean, encode_absolute(*tmpl, in.meshes[i])).values);
    // Vertex PCA of rigidly aligned meshes (aligned to the template rest shape).
    Eigen::MatrixXd P(3 * rest.rows(), train.size());
    auto flat = [&](const Eigen::MatrixX3d& V) {
      Eigen::MatrixX3d A = apply(fit_rigid_motion(V, rest), V);
      Eigen::VectorXd v(3 * A.rows());
      for (int r = 0; r < A.rows(); ++r) v.segment<3>(3 * r) = A.row(r).transpose();
      return v;
    };
    for (size_t k = 0; k < train.size(); ++k) P.col(k) = flat(in.meshes[train[k]]);
    Pca vpca = fit_pca(P, {1.0, -1});
    P.resize(0, 0);
    RelativeRotationDecoder decoder(tmpl);
    std::fprintf(stderr, "\nheld-out reconstruction: %zu training scans (%zu subjects), %zu held-out scans (%zu subjects)\n",
                 train.size(), n_train, test.size(), subjects.size() - n_train);
    std::fprintf(stderr, "%6s  %16s %16s  %16s %16s\n", "K", "RRE all (mm)", "RRE posed (mm)", "vertex all (mm)",
                 "vertex posed (mm)");
    for (int K : {1, 2, 5, 10, 20, 40, 80, 120}) {
      if (K > rre.component_count() || K > vpca.component_count()) break;
      double er_all = 0, er_posed = 0, ev_all = 0, ev_posed = 0;
      int n_posed = 0;
      for (size_t t = 0; t < test.size(); ++t) {
        const Eigen::MatrixX3d& truth = in.meshes[test[t]];
        Eigen::VectorXd c = rre.basis.leftCols(K).transpose() * (test_enc[t] - rre.mean);
        Eigen::VectorXd x = rre.mean + rre.basis.leftCols(K) * c;
        Eigen::MatrixX3d Vr = decoder.decode(Encoding{x, mean});
        double e1 = mean_vertex_error_after_rigid_fit(Vr, truth);
        Eigen::VectorXd f = flat(truth);
        Eigen::VectorXd cv = vpca.basis.leftCols(K).transpose() * (f - vpca.mean);
        Eigen::VectorXd fr = vpca.mean + vpca.basis.leftCols(K) * cv;
        Eigen::MatrixX3d Vv(truth.rows(), 3);
        for (int r = 0; r < Vv.rows(); ++r) Vv.row(r) = fr.segment<3>(3 * r).transpose();
        double e2 = mean_vertex_error_after_rigid_fit(Vv, truth);
        er_all += e1;
        ev_all += e2;
        if (!in.is_standard_pose[test[t]]) {
          er_posed += e1;
          ev_posed += e2;
          ++n_posed;
        }
      }
      const double nt = static_cast<double>(test.size());
      std::fprintf(stderr, "%6d  %16.2f %16.2f  %16.2f %16.2f\n", K, er_all / nt, er_posed / std::max(1, n_posed),
                   ev_all / nt, ev_posed / std::max(1, n_posed));
      state.counters["rre_posed_mm_K" + std::to_string(K)] = er_posed / std::max(1, n_posed);
      state.counters["vertex_posed_mm_K" + std::to_string(K)] = ev_posed / std::max(1, n_posed);
    }
  }
}
BENCHMARK(BM_Generalisation)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace
}  // namespace bodymodel

BENCHMARK_MAIN();
