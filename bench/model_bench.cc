// Statistical model benchmarks (issue 5):
//  * BM_GenerateBodies/<conditions>/<girths>: one body at a time as `generate` makes it
//    (generate_body + flipped-triangle check + OBJ); conditions = female, weight 65 kg, height
//    160..180 cm; girths 0 = `--no-girths`. Process CPU per body (cpu_ms_per_body), the same in
//    units of one decode timed in the same process (body_in_decodes), decodes per body, and the
//    final measurement and the OBJ apart. Model built in-process from 30 MakeHuman bodies.
//  * BM_GenerateFoldRepairCost: generation with and without the fold repair on the same seeds,
//    alternating in one process (CPU ratio), the repair alone, flips per body before and after.
//  * BM_GenerateCrowdParallel/<girths>/<threads>: batches of 16 bodies through write_crowd
//    (tools/pipeline/crowd_output.h: parallel bodies, OBJ files, labels.csv), wall and process CPU.
//  * BM_MeasureBanded, BM_WriteObj: measure_body cutting only each band's triangles vs every triangle, and the to_chars OBJ
//    writer vs the snprintf one it replaced, alternating in one process (speedup ratios).
//  * BM_Generalisation: reconstruction error of HELD-OUT subjects (all their scans, posed ones
//    included) vs the number of components, for the RRE model and for plain vertex-position
//    PCA of the same (rigidly aligned) meshes. Needs a synthetic database: BODYMODEL_BENCH_DB
//    (default /tmp/model_db, made by `bodymodel synth-db --subjects 40 --poses-per-subject 4`);
//    the last quarter of the subjects is held out. Prints a table to stderr.
//  * BM_ProjectionDiagnosis: why the RRE numbers above are what they are (training scans
//    reconstruct exactly, where the held-out residual sits, weighted projections).
//  * BM_PcaEigen/<N>/<K>: fit_pca with the full and the partial (Spectra) eigen-solver on the
//    same synthetic samples, interleaved; times, ratio and agreement (model/pca.h).
//  * BM_PoseMorph/<transfer neighbours>/<every bone>: pose morphing of the held-out subjects of
//    BODYMODEL_BENCH_MODEL (default /tmp/model30.npz: `bodymodel build REG30 --db DB --out
//    model30.npz` with REG30 = DB/truth meshes of the first 30 subjects) against DB/truth.
#include <benchmark/benchmark.h>

#include <chrono>
#include <ctime>
#include <unistd.h>
#include <cstdio>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <filesystem>
#include <numeric>
#include <random>

#include "core/geometry.h"
#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "core/io/pose_csv.h"
#include "core/makehuman.h"
#include "core/measure.h"
#include "model/database.h"
#include "model/model_file.h"
#include "model/morph.h"
#include "model/pca.h"
#include "model/pose_edit.h"
#include "tools/pipeline/crowd_output.h"

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

// Process CPU time (every thread of the process, the decoder's own TBB workers included), s.
double process_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

std::vector<LabelCondition> bench_conditions(bool constrained) {
  if (!constrained) return {};
  return {LabelCondition::exact("sex", 0), LabelCondition::exact("weight_kg", 65),
          LabelCondition::range("height_cm", 160, 180)};
}

// One body at a time, as `generate` makes each body: generate_body + flipped-triangle check +
// OBJ. The machine is shared, so the figures are PROCESS CPU time per body (cpu_ms_per_body;
// 10 bodies/s on 2 cores needs ≤ 200) and the same body's cost in units of one decode timed in
// the same process (body_in_decodes, load-independent). Parts: the final measurement
// (measure_ms, girths or not), the OBJ (write_ms), one decode (decode_ms).
void BM_GenerateBodies(benchmark::State& state) {
  auto model = bench_model();
  ShapeMorpher morpher(model);
  const std::vector<LabelCondition> cond = bench_conditions(state.range(0) != 0);
  auto out = std::filesystem::temp_directory_path() / ("bodymodel_bench_body_" + std::to_string(getpid()) + ".obj");
  GenerateOptions go;
  go.measure_girths = state.range(1) != 0;
  uint64_t seed = 1;
  double body_cpu = 0, write_cpu = 0, measure_cpu = 0, decode_cpu = 0, decodes = 0;
  for (auto _ : state) {
    const double t0 = process_cpu_seconds();
    GeneratedBody g = generate_body(morpher, cond, seed++, go);
    benchmark::DoNotOptimize(flipped_triangle_count(*model, g.V));
    const double t1 = process_cpu_seconds();
    write_mesh(out, g.V, model->tmpl->faces());
    const double t2 = process_cpu_seconds();
    state.PauseTiming();
    const double t3 = process_cpu_seconds();
    benchmark::DoNotOptimize(go.measure_girths ? morpher.measure(g.V, Sex::female)
                                               : measure_height_and_weight(g.V, model->tmpl->faces()));
    const double t4 = process_cpu_seconds();
    benchmark::DoNotOptimize(morpher.decode(g.encoding));
    const double t5 = process_cpu_seconds();
    state.ResumeTiming();
    body_cpu += t2 - t0;
    write_cpu += t2 - t1;
    measure_cpu += t4 - t3;
    decode_cpu += t5 - t4;
    decodes += g.summary.decodes;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["bodies_per_s"] = benchmark::Counter(n, benchmark::Counter::kIsRate);
  state.counters["cpu_ms_per_body"] = 1e3 * body_cpu / n;
  state.counters["decode_ms"] = 1e3 * decode_cpu / n;
  state.counters["body_in_decodes"] = body_cpu / decode_cpu;
  state.counters["measure_ms"] = 1e3 * measure_cpu / n;
  state.counters["write_ms"] = 1e3 * write_cpu / n;
  state.counters["decodes_per_body"] = decodes / n;
  std::filesystem::remove(out);
}
BENCHMARK(BM_GenerateBodies)->Args({0, 1})->Args({1, 1})->Args({1, 0})->Unit(benchmark::kMillisecond)->UseRealTime();

// The fold repair's cost (GenerateOptions::repair_folds, model/morph.h): the same seeds generated
// with and without it, alternating in one process (process CPU; ratio = with / without, the
// load-independent figure), and repair_body_folds alone on the unrepaired body; the flipped
// triangles per body before and after the repair (mean and worst over the iterations).
void BM_GenerateFoldRepairCost(benchmark::State& state) {
  auto model = bench_model();
  ShapeMorpher morpher(model);
  const std::vector<LabelCondition> cond = bench_conditions(true);
  GenerateOptions with, without;
  without.repair_folds = false;
  uint64_t seed = 1;
  double cpu_with = 0, cpu_without = 0, cpu_repair = 0, before = 0, after = 0, worst_before = 0, worst_after = 0;
  for (auto _ : state) {
    const double t0 = process_cpu_seconds();
    GeneratedBody a = generate_body(morpher, cond, seed, without);
    const double t1 = process_cpu_seconds();
    GeneratedBody b = generate_body(morpher, cond, seed, with);
    const double t2 = process_cpu_seconds();
    FoldRepairSummary r = repair_body_folds(*model, a.V);
    const double t3 = process_cpu_seconds();
    ++seed;
    cpu_without += t1 - t0;
    cpu_with += t2 - t1;
    cpu_repair += t3 - t2;
    before += r.flipped_before;
    const int left = flipped_triangle_count(*model, b.V);
    after += left;
    worst_before = std::max(worst_before, double(r.flipped_before));
    worst_after = std::max(worst_after, double(left));
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["cpu_ms_without"] = 1e3 * cpu_without / n;
  state.counters["cpu_ms_with"] = 1e3 * cpu_with / n;
  state.counters["ratio_with_to_without"] = cpu_with / cpu_without;
  state.counters["repair_ms"] = 1e3 * cpu_repair / n;
  state.counters["flipped_before_mean"] = before / n;
  state.counters["flipped_before_max"] = worst_before;
  state.counters["flipped_after_mean"] = after / n;
  state.counters["flipped_after_max"] = worst_after;
}
BENCHMARK(BM_GenerateFoldRepairCost)->Iterations(20)->Unit(benchmark::kMillisecond);

// The crowd as `bodymodel generate` makes it (write_crowd, tools/pipeline/crowd_output.h): bodies
// in parallel on `threads` TBB workers, each written to its own OBJ, labels.csv at the end.
// Wall and process CPU per body.
void BM_GenerateCrowdParallel(benchmark::State& state) {
  auto model = bench_model();
  const std::vector<LabelCondition> cond = bench_conditions(true);
  auto dir = std::filesystem::temp_directory_path() / ("bodymodel_bench_crowd_" + std::to_string(getpid()));
  CrowdOutputOptions co;
  co.crowd.generate.measure_girths = state.range(0) != 0;
  co.crowd.threads = static_cast<int>(state.range(1));
  const int batch = 16;
  uint64_t seed = 1;
  double cpu = 0;
  for (auto _ : state) {
    std::filesystem::remove_all(dir);
    co.crowd.seed = seed++;
    const double t0 = process_cpu_seconds();
    GenerateCrowdSummary s = write_crowd(model, cond, batch, dir, co);
    cpu += process_cpu_seconds() - t0;
    benchmark::DoNotOptimize(s.generated);
  }
  const double n = static_cast<double>(batch * state.iterations());
  state.counters["bodies_per_s"] = benchmark::Counter(n, benchmark::Counter::kIsRate);
  state.counters["cpu_ms_per_body"] = 1e3 * cpu / n;
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_GenerateCrowdParallel)->Args({1, 2})->Args({0, 2})->Args({1, 1})->Unit(benchmark::kMillisecond)->UseRealTime();

// measure_body (core/measure.h) cutting every triangle against cutting each band's triangles
// only (the default) on the same generated body, alternating in one process: ratio = speed-up.
void BM_MeasureBanded(benchmark::State& state) {
  auto model = bench_model();
  ShapeMorpher morpher(model);
  const Eigen::MatrixX3d V = generate_body(morpher, {}, 3).V;
  const Eigen::MatrixX3i& F = model->tmpl->faces();
  MeasureOptions every_triangle;
  every_triangle.cut_band_triangles_only = false;
  double full = 0, banded = 0;
  for (auto _ : state) {
    const double t0 = process_cpu_seconds();
    benchmark::DoNotOptimize(measure_body(V, F, Sex::female, every_triangle));
    const double t1 = process_cpu_seconds();
    benchmark::DoNotOptimize(measure_body(V, F, Sex::female));
    const double t2 = process_cpu_seconds();
    full += t1 - t0;
    banded += t2 - t1;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["measure_body_ms"] = 1e3 * full / n;
  state.counters["banded_ms"] = 1e3 * banded / n;
  state.counters["speedup"] = full / banded;
}
BENCHMARK(BM_MeasureBanded)->Unit(benchmark::kMillisecond);

// The OBJ writer (core/io/mesh_io.cc, std::to_chars) against the snprintf("%.9g") writer it
// replaced (same bytes), alternating in one process on a generated body.
void BM_WriteObj(benchmark::State& state) {
  auto model = bench_model();
  ShapeMorpher morpher(model);
  const Eigen::MatrixX3d V = generate_body(morpher, {}, 3).V;
  const Eigen::MatrixX3i& F = model->tmpl->faces();
  auto out = std::filesystem::temp_directory_path() / ("bodymodel_bench_write_" + std::to_string(getpid()) + ".obj");
  double fast = 0, baseline = 0;
  for (auto _ : state) {
    const double t0 = process_cpu_seconds();
    write_mesh(out, V, F);
    const double t1 = process_cpu_seconds();
    {
      std::string buf;
      buf.reserve(V.rows() * 40 + F.rows() * 24);
      char tmp[128];
      for (Eigen::Index i = 0; i < V.rows(); ++i)
        buf.append(tmp, std::snprintf(tmp, sizeof tmp, "v %.9g %.9g %.9g\n", V(i, 0), V(i, 1), V(i, 2)));
      for (Eigen::Index f = 0; f < F.rows(); ++f)
        buf.append(tmp, std::snprintf(tmp, sizeof tmp, "f %d %d %d\n", F(f, 0) + 1, F(f, 1) + 1, F(f, 2) + 1));
      write_text_file(out, buf);
    }
    const double t2 = process_cpu_seconds();
    fast += t1 - t0;
    baseline += t2 - t1;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["write_obj_ms"] = 1e3 * fast / n;
  state.counters["snprintf_ms"] = 1e3 * baseline / n;
  state.counters["speedup"] = baseline / fast;
  std::filesystem::remove(out);
}
BENCHMARK(BM_WriteObj)->Unit(benchmark::kMillisecond);

// Held-out split of the synthetic database with both PCAs fitted on the training scans.
struct GeneralisationData {
  ModelBuildInput in;
  std::vector<int> train, test;
  size_t n_train_subjects = 0, n_subjects = 0;
  Eigen::MatrixX3d rest;
  std::shared_ptr<EncodingTemplate> tmpl;
  std::shared_ptr<const EncodingMean> mean;
  Pca rre, vpca;
  std::vector<Eigen::VectorXd> test_enc;   // held-out encodings relative to `mean`
  std::vector<Eigen::VectorXd> train_enc;  // a few training encodings (diagnosis)
  Eigen::VectorXd flat(const Eigen::MatrixX3d& V) const {
    Eigen::MatrixX3d A = apply(fit_rigid_motion(V, rest), V);
    Eigen::VectorXd v(3 * A.rows());
    for (int r = 0; r < A.rows(); ++r) v.segment<3>(3 * r) = A.row(r).transpose();
    return v;
  }
};

const GeneralisationData* generalisation_data(benchmark::State& state) {
  namespace fs = std::filesystem;
  const char* env = std::getenv("BODYMODEL_BENCH_DB");
  fs::path db = env ? env : "/tmp/model_db";
  if (!fs::exists(db / "scans.csv")) {
    state.SkipWithError(("no database at " + db.string() + " (set BODYMODEL_BENCH_DB)").c_str());
    return nullptr;
  }
  static std::unique_ptr<GeneralisationData> data;
  if (data) return data.get();
  data = std::make_unique<GeneralisationData>();
  GeneralisationData& g = *data;
  g.in = read_registered_database(db / "truth", db);
  const ModelBuildInput& in = g.in;
  std::vector<std::string> subjects;
  for (auto& s : in.subject_ids)
    if (std::find(subjects.begin(), subjects.end(), s) == subjects.end()) subjects.push_back(s);
  g.n_subjects = subjects.size();
  g.n_train_subjects = subjects.size() - subjects.size() / 4;
  for (size_t i = 0; i < in.meshes.size(); ++i) {
    size_t si = std::find(subjects.begin(), subjects.end(), in.subject_ids[i]) - subjects.begin();
    (si < g.n_train_subjects ? g.train : g.test).push_back(static_cast<int>(i));
  }
  // RRE: template = mean of the training standard-pose meshes; encodings relative to their mean.
  const Eigen::MatrixX3d& ref = in.meshes[g.train[0]];
  g.rest = Eigen::MatrixX3d::Zero(ref.rows(), 3);
  int ns = 0;
  for (int i : g.train)
    if (in.is_standard_pose[i]) {
      g.rest += apply(fit_rigid_motion(in.meshes[i], ref), in.meshes[i]);
      ++ns;
    }
  g.rest /= ns;
  g.tmpl = std::make_shared<EncodingTemplate>(g.rest, in.F);
  const int D = g.tmpl->encoding_size();
  Eigen::MatrixXd X(D, g.train.size());
  for (size_t k = 0; k < g.train.size(); ++k) X.col(k) = encode_absolute(*g.tmpl, in.meshes[g.train[k]]);
  g.mean = EncodingMean::from_values(X.rowwise().mean());
  for (size_t k = 0; k < g.train.size(); ++k) {
    Eigen::VectorXd a = X.col(k);
    X.col(k) = relative_to(g.mean, a).values;
  }
  for (int k : {0, 1, 2}) g.train_enc.push_back(X.col(k));
  g.rre = fit_pca(X, {1.0, -1});
  X.resize(0, 0);
  for (int i : g.test) g.test_enc.push_back(relative_to(g.mean, encode_absolute(*g.tmpl, in.meshes[i])).values);
  // Vertex PCA of rigidly aligned meshes (aligned to the template rest shape).
  Eigen::MatrixXd P(3 * g.rest.rows(), g.train.size());
  for (size_t k = 0; k < g.train.size(); ++k) P.col(k) = g.flat(in.meshes[g.train[k]]);
  g.vpca = fit_pca(P, {1.0, -1});
  return data.get();
}

void BM_Generalisation(benchmark::State& state) {
  const GeneralisationData* gp = generalisation_data(state);
  if (!gp) return;
  const GeneralisationData& g = *gp;
  const ModelBuildInput& in = g.in;
  for (auto _ : state) {
    RelativeRotationDecoder decoder(g.tmpl);
    std::fprintf(stderr, "\nheld-out reconstruction: %zu training scans (%zu subjects), %zu held-out scans (%zu subjects)\n",
                 g.train.size(), g.n_train_subjects, g.test.size(), g.n_subjects - g.n_train_subjects);
    std::fprintf(stderr, "%6s  %16s %16s  %16s %16s\n", "K", "RRE all (mm)", "RRE posed (mm)", "vertex all (mm)",
                 "vertex posed (mm)");
    for (int K : {1, 2, 5, 10, 20, 40, 80, 120}) {
      if (K > g.rre.component_count() || K > g.vpca.component_count()) break;
      double er_all = 0, er_posed = 0, ev_all = 0, ev_posed = 0;
      int n_posed = 0;
      for (size_t t = 0; t < g.test.size(); ++t) {
        const Eigen::MatrixX3d& truth = in.meshes[g.test[t]];
        Eigen::VectorXd c = g.rre.basis.leftCols(K).transpose() * (g.test_enc[t] - g.rre.mean);
        Eigen::VectorXd x = g.rre.mean + g.rre.basis.leftCols(K) * c;
        Eigen::MatrixX3d Vr = decoder.decode(Encoding{x, g.mean});
        double e1 = mean_vertex_error_after_rigid_fit(Vr, truth);
        Eigen::VectorXd f = g.flat(truth);
        Eigen::VectorXd cv = g.vpca.basis.leftCols(K).transpose() * (f - g.vpca.mean);
        Eigen::VectorXd fr = g.vpca.mean + g.vpca.basis.leftCols(K) * cv;
        Eigen::MatrixX3d Vv(truth.rows(), 3);
        for (int r = 0; r < Vv.rows(); ++r) Vv.row(r) = fr.segment<3>(3 * r).transpose();
        double e2 = mean_vertex_error_after_rigid_fit(Vv, truth);
        er_all += e1;
        ev_all += e2;
        if (!in.is_standard_pose[g.test[t]]) {
          er_posed += e1;
          ev_posed += e2;
          ++n_posed;
        }
      }
      const double nt = static_cast<double>(g.test.size());
      std::fprintf(stderr, "%6d  %16.2f %16.2f  %16.2f %16.2f\n", K, er_all / nt, er_posed / std::max(1, n_posed),
                   ev_all / nt, ev_posed / std::max(1, n_posed));
      state.counters["rre_posed_mm_K" + std::to_string(K)] = er_posed / std::max(1, n_posed);
      state.counters["vertex_posed_mm_K" + std::to_string(K)] = ev_posed / std::max(1, n_posed);
    }
  }
}
BENCHMARK(BM_Generalisation)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

// Diagnosis of the RRE projection: (a) a TRAINING scan projected with all components must
// decode to ~0 error, (b) a held-out scan's own encoding must decode to ~0 (decoder round
// trip), (c) held-out projection with all components; plus which part of the encoding
// residual (rotations or stretches) makes the vertex error.
void BM_ProjectionDiagnosis(benchmark::State& state) {
  const GeneralisationData* gp = generalisation_data(state);
  if (!gp) return;
  const GeneralisationData& g = *gp;
  for (auto _ : state) {
    RelativeRotationDecoder decoder(g.tmpl);
    const int K = g.rre.component_count();
    auto proj = [&](const Eigen::VectorXd& x, int k) {
      Eigen::VectorXd c = g.rre.basis.leftCols(k).transpose() * (x - g.rre.mean);
      return Eigen::VectorXd(g.rre.mean + g.rre.basis.leftCols(k) * c);
    };
    auto err = [&](const Eigen::VectorXd& x, const Eigen::MatrixX3d& truth) {
      return mean_vertex_error_after_rigid_fit(decoder.decode(Encoding{x, g.mean}), truth);
    };
    const int D = static_cast<int>(g.rre.mean.size());
    Eigen::VectorXd rot_mask(D), str_mask(D);
    for (int i = 0; i < D; ++i) {
      rot_mask(i) = (i % 15) < 9 ? 1 : 0;
      str_mask(i) = 1 - rot_mask(i);
    }
    for (int k = 0; k < 3; ++k) {
      const Eigen::MatrixX3d& truth = g.in.meshes[g.train[k]];
      std::fprintf(stderr, "train %d: own encoding %.3f mm, projected (K=%d) %.3f mm, encoding residual %.2e\n", k,
                   err(g.train_enc[k], truth), K, err(proj(g.train_enc[k], K), truth),
                   (proj(g.train_enc[k], K) - g.train_enc[k]).norm() / g.train_enc[k].norm());
    }
    // Projections in a weighted metric: rotation slots weighted by alpha (alpha = 1 is the
    // orthogonal projection).
    for (double alpha : {1.0, 10.0, 100.0}) {
      for (int k : {20, K}) {
        Eigen::VectorXd w = str_mask + alpha * alpha * rot_mask;
        Eigen::MatrixXd B = g.rre.basis.leftCols(k);
        Eigen::MatrixXd BtW = (B.array().colwise() * w.array()).matrix().transpose();
        Eigen::MatrixXd N = BtW * B;
        Eigen::LDLT<Eigen::MatrixXd> ldlt(N);
        double e_posed = 0;
        int n = 0;
        for (size_t t = 0; t < g.test.size(); t += 3) {
          if (g.in.is_standard_pose[g.test[t]]) continue;
          Eigen::VectorXd c = ldlt.solve(BtW * (g.test_enc[t] - g.rre.mean));
          e_posed += err(g.rre.mean + B * c, g.in.meshes[g.test[t]]);
          ++n;
        }
        std::fprintf(stderr, "rotation weight %g, K=%d: held-out posed mean error %.2f mm (%d scans)\n", alpha, k,
                     e_posed / n, n);
      }
    }
    for (size_t t = 0; t < g.test.size(); t += 7) {
      const Eigen::MatrixX3d& truth = g.in.meshes[g.test[t]];
      const Eigen::VectorXd& x = g.test_enc[t];
      Eigen::VectorXd p = proj(x, K);
      Eigen::VectorXd r = x - p;
      Eigen::VectorXd rot_only = x - r.cwiseProduct(rot_mask);  // residual only in rotations
      Eigen::VectorXd str_only = x - r.cwiseProduct(str_mask);  // residual only in stretches
      std::fprintf(stderr,
                   "held-out %s (%s): own %.3f mm, projected %.2f mm; residual rot %.3f / %.3f, stretch %.3f / %.3f "
                   "(norms of residual / of x); error from rot residual only %.2f mm, stretch only %.2f mm\n",
                   g.in.scan_ids[g.test[t]].c_str(), g.in.is_standard_pose[g.test[t]] ? "standard" : "posed",
                   err(x, truth), err(p, truth), r.cwiseProduct(rot_mask).norm(), x.cwiseProduct(rot_mask).norm(),
                   r.cwiseProduct(str_mask).norm(), x.cwiseProduct(str_mask).norm(), err(rot_only, truth),
                   err(str_only, truth));
      // Slots whose absolute relative-rotation angle is large (creases where LBS folds or
      // inverts triangles): their share of the residual and the error without their residual.
      Eigen::VectorXd abs_x = absolute_values(Encoding{x, g.mean});
      Eigen::VectorXd big_mask = Eigen::VectorXd::Zero(D);
      int n_big = 0, n_inverted = 0;
      for (int f = 0; f < D / 15; ++f) {
        for (int k = 0; k < 3; ++k)
          if (abs_x.segment<3>(15 * f + 3 * k).norm() > 0.5) {
            big_mask.segment<15>(15 * f).setOnes();
            ++n_big;
          }
        Eigen::Matrix3d S;
        const double* s6 = abs_x.data() + 15 * f + 9;
        S << s6[0], s6[1], s6[2], s6[1], s6[3], s6[4], s6[2], s6[4], s6[5];
        if (S.determinant() <= 0) ++n_inverted;
      }
      Eigen::VectorXd no_big = p + r.cwiseProduct(big_mask);
      std::fprintf(stderr, "    slots with |rotation| > 0.5 rad: %d, triangles with det S <= 0: %d, residual norm there %.3f, "
                   "error with those triangles exact %.2f mm\n",
                   n_big, n_inverted, r.cwiseProduct(big_mask).norm(), err(no_big, truth));
    }
  }
}
BENCHMARK(BM_ProjectionDiagnosis)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

// Pose morphing (§5.4) of held-out subjects: each held-out subject's standard-pose truth mesh
// is morphed into the joint angles of each of its posed scans and compared with that scan's
// truth mesh (mean vertex error after a rigid fit). Model: BODYMODEL_BENCH_MODEL (default
// /tmp/model30.npz, built by `bodymodel build` from the first 30 subjects of the database);
// subjects of the database that are not in the model are held out.
void BM_PoseMorph(benchmark::State& state) {
  namespace fs = std::filesystem;
  const char* env_db = std::getenv("BODYMODEL_BENCH_DB");
  const char* env_model = std::getenv("BODYMODEL_BENCH_MODEL");
  fs::path db = env_db ? env_db : "/tmp/model_db";
  fs::path model_path = env_model ? env_model : "/tmp/model30.npz";
  if (!fs::exists(db / "scans.csv") || !fs::exists(model_path)) {
    state.SkipWithError(("need " + (db / "scans.csv").string() + " and " + model_path.string()).c_str());
    return;
  }
  const BodyModel model = load_model(model_path);
  auto scans = read_scan_table(db / "scans.csv");
  const auto& known = model.shape.sample_ids;
  std::vector<std::pair<std::string, std::string>> cases;  // standard scan, posed scan
  for (auto& r : scans) {
    if (std::find(known.begin(), known.end(), r.subject_id) != known.end() || r.pose == "standard") continue;
    for (auto& q : scans)
      if (q.subject_id == r.subject_id && q.pose == "standard") cases.emplace_back(q.scan_id, r.scan_id);
  }
  const int neighbours = static_cast<int>(state.range(0));
  for (auto _ : state) {
    RelativeRotationDecoder decoder(model.tmpl);
    PoseMorphOptions o;
    o.transfer_neighbours = neighbours;
    o.constrain_every_bone = state.range(1) != 0;
    std::vector<double> errors;
    for (auto& [st, posed] : cases) {
      Mesh body = read_mesh(db / "truth" / (st + ".ply"));
      Mesh truth = read_mesh(db / "truth" / (posed + ".ply"));
      Pose pose = read_pose_csv(db / "truth" / (posed + ".pose.csv"), model.rig.bone_names).pose;
      Eigen::MatrixX3d out = pose_morph(model, decoder, body.V, pose, o);
      errors.push_back(mean_vertex_error_after_rigid_fit(out, truth.V));
      // Reference: the body skinned with the model's rig (what the positional constraints use).
      const Eigen::MatrixX3d Vc = body.V * canonical_rotation(model.rig, body.V).transpose();
      Eigen::MatrixX3d lbs = linear_blend_skinning(Vc, model.rig.weights,
                                                   forward_kinematics(model.rig.skeleton_for(Vc), pose));
      std::fprintf(stderr, "%s -> %s: %.2f mm (skinned with the model's rig: %.2f mm)\n", st.c_str(), posed.c_str(),
                   errors.back(), mean_vertex_error_after_rigid_fit(lbs, truth.V));
    }
    double mean = std::accumulate(errors.begin(), errors.end(), 0.0) / std::max<size_t>(1, errors.size());
    std::fprintf(stderr, "pose morph, %d transfer neighbours, every bone constrained %d: %zu held-out posed scans, mean vertex error %.2f mm, worst %.2f mm\n",
                 neighbours, static_cast<int>(state.range(1)), errors.size(), mean, errors.empty() ? 0.0 : *std::max_element(errors.begin(), errors.end()));
    state.counters["mean_error_mm"] = mean;
    state.counters["scans"] = static_cast<double>(errors.size());
  }
}
BENCHMARK(BM_PoseMorph)->Args({0, 0})->Args({8, 0})->Args({8, 1})->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

// The PCA's eigen-solvers on the same data (fit_pca, model/pca.h): the full dense solver of the
// N×N Gram matrix against Spectra's partial Lanczos solver for the K = range(1) leading
// components, at N = range(0) samples, interleaved in one loop (alternating order). The data
// is synthetic, of D = N + 1000 values per sample with a decaying spectrum (σ_k ∝ 1/k, as
// shape data has) plus noise; D only sizes the Gram product, which both paths share, so the
// difference of the two times is the eigen-solve. Process CPU (both paths are serial, so it is
// their time on an idle machine, and steadier than wall time on a loaded one), and how far
// apart the results are: eigenvalues (relative) and basis vectors (max |Δ|, up to sign).
void BM_PcaEigen(benchmark::State& state) {
  const int N = static_cast<int>(state.range(0)), K = static_cast<int>(state.range(1)), D = N + 1000;
  std::mt19937 rng(11);
  std::normal_distribution<double> z;
  Eigen::MatrixXd A(D, N), Z(N, N);
  for (Eigen::Index i = 0; i < A.size(); ++i) A.data()[i] = z(rng);
  for (Eigen::Index i = 0; i < Z.size(); ++i) Z.data()[i] = z(rng);
  for (int k = 0; k < N; ++k) A.col(k) *= 100.0 / (k + 1);
  Eigen::MatrixXd X = A * Z;
  for (Eigen::Index i = 0; i < X.size(); ++i) X.data()[i] += 0.01 * z(rng);
  PcaOptions full{1.0, K, PcaEigenSolver::full}, partial{1.0, K, PcaEigenSolver::partial};
  double t_full = 0, t_partial = 0;
  Pca a, b;
  int round = 0;
  for (auto _ : state) {
    for (int step = 0; step < 2; ++step) {
      const bool use_partial = (round + step) % 2 == 1;
      const double t0 = process_cpu_seconds();
      (use_partial ? b : a) = fit_pca(X, use_partial ? partial : full);
      (use_partial ? t_partial : t_full) += process_cpu_seconds() - t0;
    }
    ++round;
  }
  const double n = static_cast<double>(state.iterations());
  double eig = 0, basis = 0;
  for (int k = 0; k < std::min(a.component_count(), b.component_count()); ++k) {
    eig = std::max(eig, std::abs(a.eigenvalues(k) - b.eigenvalues(k)) / a.eigenvalues(0));
    const double sign = a.basis.col(k).dot(b.basis.col(k)) < 0 ? -1 : 1;
    basis = std::max(basis, (a.basis.col(k) - sign * b.basis.col(k)).cwiseAbs().maxCoeff());
  }
  state.counters["full_ms"] = 1e3 * t_full / n;
  state.counters["partial_ms"] = 1e3 * t_partial / n;
  state.counters["full_over_partial"] = t_full / t_partial;
  state.counters["eigenvalue_rel_diff"] = eig;
  state.counters["basis_max_diff"] = basis;
  state.counters["components"] = b.component_count();
  std::fprintf(stderr, "PCA N=%d D=%d K=%d: full %.1f ms, partial (Spectra) %.1f ms, full/partial %.2f; "
               "eigenvalues agree to %.1e (relative to the largest), basis to %.1e\n",
               N, D, K, 1e3 * t_full / n, 1e3 * t_partial / n, t_full / t_partial, eig, basis);
}
BENCHMARK(BM_PcaEigen)->Args({200, 20})->Args({1000, 20})->Args({1000, 50})->Args({2000, 20})->Args({2000, 50})
    ->Iterations(3)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace bodymodel

BENCHMARK_MAIN();
