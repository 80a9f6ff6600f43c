// Regression study speed and figures (issue 6): the full 10-fold evaluation of every regressor on
// 100 subjects, features = vertex-position PCA coefficients of random MakeHuman bodies (see
// tests/regression/makehuman_features.h), labels measured with measure_body. Feature generation is
// outside the timing. Two feature sets: clean bodies, and bodies with 3 mm vertex noise (a
// stand-in for scan/registration noise, which is what makes filtering matter in the paper).
// Prints the Table-1-style RMSE matrix beside Hasler et al.'s figures, and the Table-2 angles.
// Run: build/bench/regression_bench   (one iteration each; BODYMODEL_BENCH_JOBS=2 by default). The
// table on the model itself: `bodymodel eval-regressors --synthetic 100 --folds 10 --out report`.
#define FMT_HEADER_ONLY  // the bench targets do not link libfmt
#include <fmt/format.h>
#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include <ctime>
#include <cstdlib>
#include <map>

#include "regression/regression_study.h"
#include "regression/regressor.h"
#include "tests/regression/makehuman_features.h"

namespace bodymodel {
namespace {

const MakeHumanFeatures& features(double noise_mm) {
  static std::map<double, MakeHumanFeatures> cache;
  static const MakeHuman mh = MakeHuman::load();
  auto it = cache.find(noise_mm);
  if (it == cache.end()) it = cache.emplace(noise_mm, make_makehuman_features(mh, 100, 1, noise_mm)).first;
  return it->second;
}

void print_study(const RegressionStudy& s, const MakeHumanFeatures& f, double noise_mm) {
  fmt::print(stderr, "\n10-fold RMSE, 100 MakeHuman subjects, {} PCA components, vertex noise {} mm ({:.1f} s)\n",
             f.coefficients.cols(), noise_mm, s.seconds);
  fmt::print(stderr, "{:<18}", "");
  for (size_t l = 0; l < f.label_names.size(); ++l)
    fmt::print(stderr, " {:>18}", f.label_names[l] + " (" + f.label_units[l] + ")");
  fmt::print(stderr, "\n");
  const std::map<std::string, std::vector<double>> paper = {
      {"paper simple", {3.68, 3.03, 3.38, 5.63, 2.78}},
      {"paper filtered", {1.43, 1.33, 2.02, 2.41, 0.945}},
      {"paper non-linear", {1.15, 1.17, 1.66, 2.38, 0.858}}};
  for (const auto& r : regressor_names()) {
    fmt::print(stderr, "{:<18}", r);
    for (const auto& l : f.label_names) fmt::print(stderr, " {:>18.3f}", s.result(r, l).rmse);
    fmt::print(stderr, "\n");
  }
  for (const auto& [name, v] : paper) {
    fmt::print(stderr, "{:<18}", name);
    for (double x : v) fmt::print(stderr, " {:>18.3f}", x);
    fmt::print(stderr, "\n");
  }
  fmt::print(stderr, "morph-direction angles to the mean, degrees (mean ± std):\n");
  for (const auto& d : s.directions)
    if (d.regressor == "svr" || d.regressor == "gaussian_process")
      fmt::print(stderr, "  {:<18} {:<14} {:.2f} ± {:.2f}\n", d.regressor, d.label, d.spread.mean_deg, d.spread.std_deg);
  for (const auto& r : regressor_names()) {
    fmt::print(stderr, "  {} chosen in fold 1:", r);
    for (const auto& l : f.label_names) fmt::print(stderr, " [{}: {}]", l, s.result(r, l).fold_descriptions[0]);
    fmt::print(stderr, "\n");
  }
}

void BM_RegressionStudy(benchmark::State& state) {
  const double noise_mm = static_cast<double>(state.range(0));
  const MakeHumanFeatures& f = features(noise_mm);
  RegressionStudyOptions o;  // all regressors, 10 folds, directions and the filtered curve
  const char* jobs = std::getenv("BODYMODEL_BENCH_JOBS");
  o.jobs = jobs ? std::atoi(jobs) : 2;
  RegressionStudy last;
  const std::clock_t cpu0 = std::clock();
  for (auto _ : state) last = run_regression_study(f.coefficients, f.labels, f.label_names, {}, o);
  // Process CPU time over all worker threads: the wall time depends on what else the shared
  // machine runs, this does not.
  state.counters["process_cpu_s"] = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC;
  state.counters["jobs"] = o.jobs;
  state.counters["components"] = static_cast<double>(f.coefficients.cols());
  print_study(last, f, noise_mm);
}
BENCHMARK(BM_RegressionStudy)->Arg(0)->Arg(3)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

// The cost of stacking the filtered model's nested fits against keeping one count (both from the
// same leave-one-out residuals): 10-fold cross-validation of each on the 5 labels of the 3 mm
// feature set, one thread. Arg 0 = one count (filtered_linear_select), 1 = stacked (the default).
// Compare the two process_cpu_s counters (same process, same data).
void BM_FilteredLinearSelection(benchmark::State& state) {
  const MakeHumanFeatures& f = features(3);
  const auto prototype = make_regressor(state.range(0) ? "filtered_linear" : "filtered_linear_select");
  double sum_rmse = 0;
  const std::clock_t cpu0 = std::clock();
  for (auto _ : state) {
    sum_rmse = 0;
    for (Eigen::Index l = 0; l < f.labels.cols(); ++l)
      sum_rmse += cross_validate(*prototype, f.coefficients, f.labels.col(l), {}, {}, f.label_names[l]).rmse;
  }
  state.counters["process_cpu_s"] = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC / state.iterations();
  state.counters["sum_rmse"] = sum_rmse;
}
BENCHMARK(BM_FilteredLinearSelection)->Arg(0)->Arg(1)->Iterations(3)->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace
}  // namespace bodymodel

BENCHMARK_MAIN();
