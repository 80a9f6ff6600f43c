// ANSUR II measurements (core/ansur_measure.h), the cost a least-squares fit pays per body:
//  * BM_AnsurMeasure/<body>: one AnsurMeasurer::measure call (all 23 measurements) on a
//    MakeHuman body (0 default, 1 male, 2 female, 3 heavy male, 4 light female, 5 tall heavy
//    muscular male, 6 short heavy old woman), skeleton given;
//    counter fallbacks = sections that left their triangle tube (cut on the whole mesh).
//  * BM_AnsurMeasureOneFallback: the same on the default woman with a measurer whose waist tube
//    misses her waist (built on a body with the navel pulled 250 mm up): one section per call
//    cut on the whole mesh, the cost of a body far from the reference.
//  * BM_AnsurSkeletonFromBody: MakeHuman::skeleton_from_body, which a caller adds per body.
//  * BM_MeasureBodySurvey: measure_body (NHANES survey measures, no band girths) for scale.
#include <benchmark/benchmark.h>

#include "core/ansur_measure.h"
#include "core/landmarks.h"
#include "core/makehuman.h"
#include "core/measure.h"

namespace {

using namespace bodymodel;

const MakeHuman& mh() {
  static const MakeHuman m = MakeHuman::load();
  return m;
}

const AnsurMeasurer& measurer() {
  static const AnsurMeasurer m = [] {
    const MakeHuman::Body ref = mh().body(MacroSettings{});
    return AnsurMeasurer(mh().body_faces(), mh().body_weights(), ref.mesh.V, ref.skeleton);
  }();
  return m;
}

MakeHuman::Body body_of(int which) {
  MacroSettings s;
  const double gender[] = {0.5, 1, 0, 1, 0, 1, 0}, weight[] = {0.5, 0.5, 0.5, 1, 0, 1, 1};
  const double muscle[] = {0.5, 0.5, 0.5, 0.5, 0.5, 1, 0.5}, height[] = {0.5, 0.5, 0.5, 0.5, 0.5, 1, 0};
  s.gender = gender[which];
  s.weight = weight[which];
  s.muscle = muscle[which];
  s.height = height[which];
  s.age = which == 6 ? 1.0 : 0.5;
  return mh().body(s);
}

void BM_AnsurMeasure(benchmark::State& state) {
  const MakeHuman::Body b = body_of(static_cast<int>(state.range(0)));
  const Skeleton s = mh().skeleton_from_body(b.mesh.V);
  const long before = measurer().fallback_count();
  for (auto _ : state) benchmark::DoNotOptimize(measurer().measure(b.mesh.V, s));
  state.counters["fallbacks"] = static_cast<double>(measurer().fallback_count() - before);
}
BENCHMARK(BM_AnsurMeasure)->DenseRange(0, 6)->Unit(benchmark::kMillisecond);

void BM_AnsurMeasureOneFallback(benchmark::State& state) {
  const MakeHuman::Body b = body_of(2);
  Eigen::MatrixX3d pulled = b.mesh.V;
  pulled(ansur_landmarks().omphalion, 1) += 250;
  const AnsurMeasurer off(mh().body_faces(), mh().body_weights(), pulled, b.skeleton);
  const Skeleton s = mh().skeleton_from_body(b.mesh.V);
  for (auto _ : state) benchmark::DoNotOptimize(off.measure(b.mesh.V, s));
  state.counters["fallbacks_per_call"] = static_cast<double>(off.fallback_count()) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_AnsurMeasureOneFallback)->Unit(benchmark::kMillisecond);

void BM_AnsurSkeletonFromBody(benchmark::State& state) {
  const MakeHuman::Body b = body_of(1);
  mh().skeleton_from_body(b.mesh.V);  // the regressor is fitted on first use
  for (auto _ : state) benchmark::DoNotOptimize(mh().skeleton_from_body(b.mesh.V));
}
BENCHMARK(BM_AnsurSkeletonFromBody)->Unit(benchmark::kMillisecond);

void BM_MeasureBodySurvey(benchmark::State& state) {
  const MakeHuman::Body b = body_of(1);
  MeasureOptions o;
  o.band_girths = false;
  for (auto _ : state) benchmark::DoNotOptimize(measure_body(b.mesh.V, b.mesh.F, Sex::male, o));
}
BENCHMARK(BM_MeasureBodySurvey)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
