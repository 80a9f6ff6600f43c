// fit-measurements on ANSUR II soldiers with the full modifier set (population/ansur_fit.h, as
// `bodymodel fit-measurements --people ansur2_male.csv` runs it: macro sliders, the 20 measure
// modifiers and every body-shape modifier, 86 parameters for a man), against a baseline in the
// same process on the same soldiers:
//  * BM_FitAnsurFullModifierSet/<jobs>: the first 12 soldiers of the shared men's file (a fixed
//    set, the prior learned from the rest), fitted to the 18 columns of the accuracy bar with the
//    default options; then the same soldiers with the baseline's options: a forward-difference
//    Jacobian at every Levenberg–Marquardt step (ProportionFitOptions::refresh_every = 1) instead
//    of one every 5 steps with Broyden updates between. Run in the order default, baseline,
//    baseline, default (a change of load hits both alike), times summed. Counters:
//    people_per_s (wall) and people_per_cpu_s of both, speedup_wall / speedup_cpu (default over baseline), and how many
//    soldiers each meets within the tolerance on every given column and with no flipped triangle
//    (the speed is not bought with accuracy).
// Needs $BODYMODEL_DATA/anthropometry/ansur2/ansur2_male.csv; skipped (error) without it.
#include <benchmark/benchmark.h>
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <numeric>

#include "core/data_path.h"
#include "core/makehuman.h"
#include "population/ansur.h"
#include "population/ansur_fit.h"

namespace {

using namespace bodymodel;

double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

struct Timed {
  double wall = 0, cpu = 0;
  int met = 0;  // soldiers within tolerance on every given column, with no flipped triangle
};

Timed run(const ProportionFitter& fitter, const MeasurementSet& set, const AnsurTable& table, const AnsurFitOptions& o) {
  const double c0 = cpu_seconds();
  const auto t0 = std::chrono::steady_clock::now();
  const AnsurFitRun r = fit_ansur_rows(fitter, set, table, table, o, false);
  Timed t;
  t.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  t.cpu = cpu_seconds() - c0;
  for (const auto& p : r.people) {
    bool ok = p.fit.flipped_triangles == 0;
    for (size_t k = 0; k < p.fit.names.size(); ++k)
      if (p.fit.given[k] && !(std::abs(p.fit.measured(k) - p.fit.target(k)) <= ansur_tolerance(p.fit.names[k])))
        ok = false;
    t.met += ok;
  }
  return t;
}

void BM_FitAnsurFullModifierSet(benchmark::State& state) {
  const std::filesystem::path file = data_file("anthropometry") / "ansur2" / "ansur2_male.csv";
  if (!std::filesystem::exists(file)) {
    state.SkipWithError(("no " + file.string()).c_str());
    return;
  }
  static const MakeHuman mh = MakeHuman::load();
  static const MeasurementSet set = ansur_measurement_set(mh);
  static const ProportionFitter fitter(mh, set);
  ProportionFitOptions baseline_options;
  baseline_options.refresh_every = 1;
  static const ProportionFitter baseline(mh, set, baseline_options);
  static const AnsurTable table = read_ansur(file, default_ansur_columns());
  AnsurFitOptions o;
  o.given = default_ansur_columns();
  o.rows.resize(12);
  std::iota(o.rows.begin(), o.rows.end(), 0);
  o.jobs = static_cast<int>(state.range(0));
  const double people = static_cast<double>(o.rows.size());
  Timed fast, base;
  for (auto _ : state) {
    const Timed f1 = run(fitter, set, table, o), b1 = run(baseline, set, table, o);
    const Timed b2 = run(baseline, set, table, o), f2 = run(fitter, set, table, o);
    fast = {f1.wall + f2.wall, f1.cpu + f2.cpu, f1.met};
    base = {b1.wall + b2.wall, b1.cpu + b2.cpu, b1.met};
    state.SetIterationTime(fast.wall);
  }
  const double fitted = 2 * people;
  state.counters["people_per_s"] = fitted / fast.wall;
  state.counters["people_per_cpu_s"] = fitted / fast.cpu;
  state.counters["baseline_people_per_s"] = fitted / base.wall;
  state.counters["baseline_people_per_cpu_s"] = fitted / base.cpu;
  state.counters["speedup_wall"] = base.wall / fast.wall;
  state.counters["speedup_cpu"] = base.cpu / fast.cpu;
  state.counters["met"] = fast.met;
  state.counters["baseline_met"] = base.met;
}
BENCHMARK(BM_FitAnsurFullModifierSet)->Arg(1)->Arg(2)->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);

}  // namespace

BENCHMARK_MAIN();
