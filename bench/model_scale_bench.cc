// Model-building scale (issue 25, part 4): `bodymodel build` on a database of N registered
// meshes, run as a child process as a user runs it, reporting its wall time, its peak resident
// memory (the child's ru_maxrss from wait4) and the model file's size.
//
//  * BM_BuildScale/<N>: N ∈ {200, 500, 2000} random MakeHuman bodies in the standard pose (the
//    kind of database a population sample is: one registered mesh per person; sliders drawn as
//    synth-db draws its subjects, ethnic mix random), written once as binary PLY to
//    $BODYMODEL_BENCH_SCALE_DIR (default /tmp/bodymodel_scale) with subjects_<N>.csv, then
//    `bodymodel build DIR --subjects subjects_<N>.csv --components 300 --no-rig --out model_<N>.npz`.
//    The bodymodel executable: $BODYMODEL_EXE, else ../bodymodel beside this benchmark.
//    Counters: wall_s, peak_rss_gb, file_mb, components.
//  * BM_FitFaust/<mesh>: `fit` (model/fit.h) of FAUST registration tr_reg_<mesh> (a person the
//    model never saw: subject 6) with every component of a full model built in this process
//    from subjects 0–5 (60 meshes, --full-variance 1). Baseline in the same process: the
//    projection of the mesh's encoding (the fit's start). Counters: fit wall and process-CPU
//    seconds, mean vertex error of fit and projection (mm), iterations, wall ratio fit /
//    projection; and the same fit through ModelFitOptions::reference_solver (CHOLMOD, the
//    solver before the block one): wall and CPU ratios fit / reference and its error.
//    Needs $BODYMODEL_DATA/faust-registrations.
#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>

#include <ctime>

#include "core/data_path.h"
#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "core/makehuman.h"
#include "model/database.h"
#include "model/fit.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

fs::path scale_dir() {
  const char* env = std::getenv("BODYMODEL_BENCH_SCALE_DIR");
  return env ? fs::path(env) : fs::path("/tmp/bodymodel_scale");
}

fs::path bodymodel_exe() {
  if (const char* env = std::getenv("BODYMODEL_EXE")) return env;
  return fs::canonical("/proc/self/exe").parent_path().parent_path() / "bodymodel";
}

// Bodies 0..n−1 (each depends only on its index), written if missing.
void ensure_bodies(int n) {
  const fs::path dir = scale_dir();
  fs::create_directories(dir);
  const MakeHuman* mh = nullptr;
  std::unique_ptr<MakeHuman> owned;
  for (int i = 0; i < n; ++i) {
    const fs::path p = dir / fmt::format("body_{:05d}.ply", i);
    if (fs::exists(p)) continue;
    if (!mh) {
      owned = std::make_unique<MakeHuman>(MakeHuman::load());
      mh = owned.get();
    }
    std::mt19937_64 rng(1000003ULL * static_cast<uint64_t>(i) + 17);
    std::uniform_real_distribution<double> u(0, 1);
    auto in = [&](double a, double b) { return a + (b - a) * u(rng); };
    MacroSettings s;
    const bool male = i % 2 == 1;
    s.gender = male ? in(0.85, 1.0) : in(0.0, 0.15);
    s.age = in(0.45, 0.9);
    s.muscle = in(0.1, 0.9);
    s.weight = in(0.1, 0.9);
    s.height = in(0.1, 0.9);
    s.proportions = in(0.2, 0.8);
    s.cup = in(0.2, 0.8);
    s.set_ethnic("african", in(0, 1));
    s.set_ethnic("asian", in(0, 1 - s.african));
    write_mesh(p, mh->body(s).mesh.V, mh->body_faces());
  }
  std::string csv = "mesh,subject,pose,sex\n";
  for (int i = 0; i < n; ++i) csv += fmt::format("body_{:05d},p{:05d},standard,{}\n", i, i, i % 2 ? "male" : "female");
  write_text_file(dir / fmt::format("subjects_{}.csv", n), csv);
}

void BM_BuildScale(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  ensure_bodies(n);
  const fs::path dir = scale_dir();
  const fs::path out = dir / fmt::format("model_{}.npz", n);
  const std::string exe = bodymodel_exe().string();
  const std::vector<std::string> args = {exe, "build", dir.string(), "--subjects",
                                         (dir / fmt::format("subjects_{}.csv", n)).string(),
                                         "--components", "300", "--no-rig", "--out", out.string()};
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const pid_t pid = fork();
    if (pid == 0) {
      std::vector<char*> argv;
      for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      const int devnull = open("/dev/null", O_WRONLY);
      if (devnull >= 0) dup2(devnull, STDERR_FILENO);
      execv(exe.c_str(), argv.data());
      _exit(127);
    }
    int status = 0;
    rusage ru{};
    wait4(pid, &status, 0, &ru);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
      state.SkipWithError(fmt::format("{} build failed (status {})", exe, status).c_str());
      return;
    }
    state.counters["wall_s"] = wall;
    state.counters["cpu_s"] = static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
                              1e-6 * static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
    state.counters["peak_rss_gb"] = static_cast<double>(ru.ru_maxrss) / (1024.0 * 1024.0);  // ru_maxrss in KiB
    state.counters["file_mb"] = static_cast<double>(fs::file_size(out)) / 1e6;
    state.counters["meshes"] = n;
  }
}
BENCHMARK(BM_BuildScale)->Arg(200)->Arg(500)->Arg(2000)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

double process_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// The FAUST model of subjects 0–5 (built once).
const BodyModel* faust_model(benchmark::State& state) {
  static std::unique_ptr<BodyModel> model;
  if (model) return model.get();
  fs::path reg;
  try {
    reg = data_file("faust-registrations");
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return nullptr;
  }
  const fs::path csv = scale_dir() / "faust_train6.csv";
  fs::create_directories(scale_dir());
  std::string rows = "mesh,subject,pose\n";
  for (int i = 0; i < 60; ++i) rows += fmt::format("tr_reg_{:03d},s{},p{}\n", i, i / 10, i % 10);
  write_text_file(csv, rows);
  RegisteredFolderOptions ro;
  ro.mm_per_unit = 1000;
  ro.standard_pose = "p0";
  ModelBuildOptions bo;
  bo.full_pca = {1.0, -1};
  model = std::make_unique<BodyModel>(build_body_model(read_registered_folder(reg, csv, ro), bo));
  return model.get();
}

void BM_FitFaust(benchmark::State& state) {
  const BodyModel* model = faust_model(state);
  if (!model) return;
  const Eigen::MatrixX3d Y =
      read_mesh(data_file("faust-registrations") / fmt::format("tr_reg_{:03d}.off", state.range(0))).V * 1000.0;
  ModelFitter fitter(model->tmpl, model->mean, model->full.pca);
  const int K = model->full.component_count();
  for (auto _ : state) {
    // Baseline: the projection of the encoding, decoded and rigidly placed.
    auto t0 = std::chrono::steady_clock::now();
    const Eigen::MatrixX3d P = fitter.evaluate(fitter.project(Y, K));
    const Eigen::MatrixX3d Pp = apply(fit_rigid_motion(P, Y), P);
    const double projection_wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double projection_mm = (Pp - Y).rowwise().norm().mean();
    const double c0 = process_cpu_seconds();
    t0 = std::chrono::steady_clock::now();
    const ModelFit f = fitter.fit(Y);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    state.counters["fit_wall_s"] = wall;
    state.counters["fit_cpu_s"] = process_cpu_seconds() - c0;
    state.counters["fit_mean_mm"] = f.summary.mean_mm;
    state.counters["projection_mean_mm"] = projection_mm;
    state.counters["iterations"] = f.summary.iterations;
    state.counters["decode_s"] = f.summary.decode_seconds;      // where the time goes
    state.counters["jacobian_s"] = f.summary.jacobian_seconds;
    state.counters["components"] = K;
    state.counters["wall_ratio_fit_over_projection"] = wall / std::max(projection_wall, 1e-9);
    // The same fit through the CHOLMOD reference path (the solver before the block one):
    // ratios < 1 = the block solver's gain; the errors should agree to rounding.
    ModelFitOptions ro;
    ro.reference_solver = true;
    const double rc0 = process_cpu_seconds();
    t0 = std::chrono::steady_clock::now();
    const ModelFit r = fitter.fit(Y, ro);
    const double reference_wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    state.counters["reference_fit_mean_mm"] = r.summary.mean_mm;
    state.counters["wall_ratio_fit_over_reference"] = wall / std::max(reference_wall, 1e-9);
    state.counters["cpu_ratio_fit_over_reference"] =
        state.counters["fit_cpu_s"] / std::max(process_cpu_seconds() - rc0, 1e-9);
  }
}
BENCHMARK(BM_FitFaust)->Arg(60)->Arg(63)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace
}  // namespace bodymodel

BENCHMARK_MAIN();
