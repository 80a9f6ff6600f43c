// Registration speed and accuracy: seconds per scan for the fast and the paper non-rigid
// schedules on the 13 380-vertex MakeHuman template and a 60 000-point synthetic scan (a
// different body, posed, 1 mm noise, with 23 landmarks), pose fit included, I/O excluded.
// One scan at a time, and two scans registered concurrently on 2 threads (as `register
// --jobs 2`). Time = wall clock, CPU = process CPU (all threads); the machine is shared, so
// compare schedules by their ratio in the same run. Counters:
//   s_per_scan      wall seconds per scan (wall / scans)
//   cpu_s_per_scan  process CPU seconds per scan
//   corr_mm         mean correspondence error vs the true vertices
//   surf_mm         mean distance from the registered vertices to the true surface
//   steps, factorizations, cg_iterations, pose_s, nonrigid_s  (last scan)
//
//   registration_bench --benchmark_filter=Fast        (minutes)
//   registration_bench                                (the paper schedule: 1500 solves a scan)
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <chrono>
#include <ctime>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "core/geometry.h"
#include "core/landmarks.h"
#include "core/makehuman.h"
#include "registration/metrics.h"
#include "registration/register_scan.h"

namespace bodymodel {
namespace {

struct Case {
  RegistrationTemplate tpl;
  Mesh truth;
  PointCloud scan;
  std::vector<Landmark> landmarks;
};

const Case& the_case() {
  static const Case c = [] {
    Case c;
    MakeHuman mh = MakeHuman::load();
    MakeHuman::Body t = mh.body(MacroSettings{});
    c.tpl = {t.mesh, t.skeleton, t.weights, {}, {}};
    MacroSettings s;
    s.gender = 0.8;
    s.weight = 0.7;
    s.height = 0.65;
    MakeHuman::Body b = mh.body(s);
    Pose pose = Pose::rest(b.skeleton.bone_count());
    auto rot = [](double deg, Eigen::Vector3d axis) {
      return Eigen::AngleAxisd(deg * M_PI / 180, axis.normalized()).toRotationMatrix();
    };
    pose.rotations[b.skeleton.index("upperarm01.L")] = rot(-30, {0, 0, 1});
    pose.rotations[b.skeleton.index("lowerarm01.R")] = rot(40, {0, 1, 0.3});
    pose.rotations[b.skeleton.index("upperleg01.R")] = rot(-20, {1, 0, 0});
    pose.rotations[b.skeleton.index("lowerleg01.R")] = rot(25, {1, 0, 0});
    pose.rotations[0] = rot(10, {0, 1, 0});
    c.truth.F = b.mesh.F;
    c.truth.V = linear_blend_skinning(b.mesh.V, b.weights, forward_kinematics(b.skeleton, pose));
    SurfaceSamples ss = sample_surface(c.truth.V, c.truth.F, 60000, 5);
    const Eigen::MatrixX3d FN = face_normals(c.truth.V, c.truth.F);
    c.scan.P = ss.P;
    c.scan.N.resize(ss.P.rows(), 3);
    unsigned state = 12345;
    for (Eigen::Index i = 0; i < ss.P.rows(); ++i) {
      c.scan.N.row(i) = FN.row(ss.face(i));
      state = state * 1664525u + 1013904223u;
      const double u1 = (state >> 8) / double(1 << 24) + 1e-9;
      state = state * 1664525u + 1013904223u;
      const double u2 = (state >> 8) / double(1 << 24);
      c.scan.P.row(i) += std::sqrt(-2 * std::log(u1)) * std::cos(2 * M_PI * u2) * c.scan.N.row(i);
    }
    for (const auto& [name, v] : body_landmarks())
      c.landmarks.push_back({v, c.truth.V.row(v).transpose(), name});
    return c;
  }();
  return c;
}

// Registers `scans` copies of the scan on `scans` threads (1 or 2).
void run(benchmark::State& state, NonrigidSchedule schedule, int scans) {
  const Case& c = the_case();
  RegistrationOptions o;
  o.nonrigid.schedule = schedule;
  std::vector<RegistrationResult> r(scans);
  std::vector<RegistrationSummary> s(scans);
  double wall = 0, cpu = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::clock_t c0 = std::clock();
    tbb::task_arena arena(scans);
    arena.execute([&] {
      tbb::parallel_for(0, scans, 1, [&](int k) {
        PointCloud scan = c.scan;
        r[k] = register_scan(c.tpl, scan, c.landmarks, o, "bench", &s[k]);
      });
    });
    cpu += double(std::clock() - c0) / CLOCKS_PER_SEC;
    wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  const double n = double(state.iterations()) * scans;
  const RegistrationErrors e = registration_errors(r[0].V, c.truth.V, c.truth.F, c.scan.P);
  state.counters["s_per_scan"] = wall / n;
  state.counters["cpu_s_per_scan"] = cpu / n;
  state.counters["corr_mm"] = e.correspondence_mean;
  state.counters["surf_mm"] = e.surface_mean;
  state.counters["flipped"] = e.flipped_triangles;
  state.counters["pose_s"] = s[0].pose.seconds;
  state.counters["nonrigid_s"] = s[0].nonrigid.seconds;
  state.counters["steps"] = s[0].nonrigid.iterations;
  state.counters["factorizations"] = s[0].nonrigid.factorizations;
  state.counters["cg_iterations"] = s[0].nonrigid.reuse_iterations;
}

void BM_RegisterFast(benchmark::State& state) { run(state, NonrigidSchedule::fast, 1); }
void BM_RegisterFastJobs2(benchmark::State& state) { run(state, NonrigidSchedule::fast, 2); }
void BM_RegisterPaper(benchmark::State& state) { run(state, NonrigidSchedule::paper, 1); }
void BM_RegisterPaperJobs2(benchmark::State& state) { run(state, NonrigidSchedule::paper, 2); }
BENCHMARK(BM_RegisterFast)->Unit(benchmark::kSecond)->Iterations(1)
    ->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(BM_RegisterFastJobs2)->Unit(benchmark::kSecond)->Iterations(1)
    ->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(BM_RegisterPaper)->Unit(benchmark::kSecond)->Iterations(1)
    ->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(BM_RegisterPaperJobs2)->Unit(benchmark::kSecond)->Iterations(1)
    ->MeasureProcessCPUTime()->UseRealTime();

}  // namespace
}  // namespace bodymodel

BENCHMARK_MAIN();
