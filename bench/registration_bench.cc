// Registration speed and accuracy: seconds per scan for the fast and the paper non-rigid
// schedules on the 13 380-vertex MakeHuman template and a ≥ 50 000-point synthetic scan (a
// different body, posed, 1 mm noise, with 20 landmarks), pose fit included, I/O excluded.
// Counters: corr_mm = mean correspondence error vs the true vertices, surf_mm = mean distance
// to the true surface (same scan for both schedules, so the ratio of times is the comparison).
//
//   registration_bench --benchmark_filter=Fast      (the paper schedule takes minutes)
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>

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
    c.tpl = {t.mesh, t.skeleton, t.weights};
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

void run(benchmark::State& state, NonrigidSchedule schedule) {
  const Case& c = the_case();
  RegistrationOptions o;
  o.nonrigid.schedule = schedule;
  RegistrationResult r;
  RegistrationSummary s;
  for (auto _ : state) {
    PointCloud scan = c.scan;
    r = register_scan(c.tpl, scan, c.landmarks, o, "bench", &s);
  }
  const RegistrationErrors e = registration_errors(r.V, c.truth.V, c.truth.F, c.scan.P);
  state.counters["corr_mm"] = e.correspondence_mean;
  state.counters["surf_mm"] = e.surface_mean;
  state.counters["pose_s"] = s.pose.seconds;
  state.counters["nonrigid_s"] = s.nonrigid.seconds;
  state.counters["steps"] = s.nonrigid.iterations;
}

void BM_RegisterFast(benchmark::State& state) { run(state, NonrigidSchedule::fast); }
void BM_RegisterPaper(benchmark::State& state) { run(state, NonrigidSchedule::paper); }
BENCHMARK(BM_RegisterFast)->Unit(benchmark::kSecond)->Iterations(1)->Repetitions(3);
BENCHMARK(BM_RegisterPaper)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace
}  // namespace bodymodel

BENCHMARK_MAIN();
