// Skinning speed.
//  * Runtime: throughput (vertices per second) of the float32 SoA evaluator for LBS, Animation Space
//    and MWE with 4 influences, 24 bones, on 1 and 2 threads, at two sizes: 13 380 vertices (the
//    MakeHuman body: one character's rig stays in cache) and 200 000 (memory-bound). One thread is
//    timed in CPU time (robust on a shared machine), two threads in wall time. MWE/LBS = ratio of
//    the two throughputs of the same size and threads.
//  * Fit: MWE of the horse gallop (8 431 vertices, 10 evenly spaced poses; the MWE solve only,
//    after bone recovery and the SSD base), and SSD + MWE with automatic influence sets for
//    300 000 vertices × 50 poses: points spread over the MakeHuman body's triangles (a
//    subdivided body, each point a fixed barycentric combination of its triangle's corners),
//    posed by the 163-bone default skeleton through 50 frames of CMU clip 02_02.
//  * Every method (issue 26): posing rigs fitted to the horse gallop (8 431 vertices, 24 recovered
//    bones, 8 influences, 10 training poses, settings as fitted without cross-validation) with the
//    double-precision reference evaluators (evaluate_rig: ssd, dqs, as, mwe; evaluate_pose_space:
//    psd, eigenskin, quadratic), one thread, CPU time. BM_EveryMethodRatios times all seven in turn
//    in the same process (median of 7 rounds) and reports each as a ratio to SSD's reference time;
//    the float32 SIMD runtime of ssd/as/mwe (above) is a separate, faster path.
//   ./build/skinning_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <filesystem>
#include <chrono>
#include <sys/resource.h>
#include <random>

#include "core/data_path.h"
#include "core/io/bvh.h"
#include "core/io/mesh_io.h"
#include "core/makehuman.h"
#include "core/retarget.h"
#include "skinning/fit_lbs.h"
#include "skinning/fit_mwe.h"
#include "skinning/runtime_skinning.h"
#include "skinning/sequence_evaluation.h"
#include "skinning/skinning_model.h"

#include <tbb/global_control.h>

namespace bodymodel {
namespace {

constexpr int kBones = 24, kInfluences = 4;

// process_cpu_seconds() (skinning/sequence_evaluation.h): CPU seconds of the whole process (all
// threads): on a machine shared with other jobs the wall time of a multithreaded fit mostly
// measures the others; CPU seconds / cores is the idle-machine wall.

SkinningRig random_rig(SkinningMethod method, int vertices) {
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> bone(0, kBones - 1);
  std::uniform_real_distribution<double> u(0, 1);
  SkinningRig rig;
  rig.method = method;
  rig.bone_count = kBones;
  rig.rest = Eigen::MatrixX3d::Random(vertices, 3);
  rig.influences.resize(vertices, kInfluences);
  const int c = coefficients_per_influence(method);
  rig.coefficients.resize(vertices, kInfluences * c);
  for (int i = 0; i < vertices; ++i)
    for (int k = 0; k < kInfluences; ++k) {
      rig.influences(i, k) = bone(rng);
      for (int q = 0; q < c; ++q) rig.coefficients(i, k * c + q) = u(rng) / kInfluences;
    }
  return rig;
}

BoneTransforms random_pose() {
  BoneTransforms M(kBones, Eigen::Affine3d::Identity());
  for (int b = 0; b < kBones; ++b) {
    M[b].linear() = Eigen::AngleAxisd(0.1 * b, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    M[b].translation() = Eigen::Vector3d(0.01 * b, 0, 0);
  }
  return M;
}

// Args: method, threads, vertices.
void BM_RuntimePose(benchmark::State& state) {
  const auto method = static_cast<SkinningMethod>(state.range(0));
  const int threads = static_cast<int>(state.range(1));
  const int n = static_cast<int>(state.range(2));
  const RuntimeSkinner skinner(random_rig(method, n));
  const BoneTransforms M = random_pose();
  std::vector<float> x(n), y(n), z(n);
  for (auto _ : state) {
    skinner.pose(M, x.data(), y.data(), z.data(), threads);
    benchmark::DoNotOptimize(x.data());
    benchmark::ClobberMemory();
  }
  state.SetLabel(skinning_method_name(method) + ", " + std::to_string(threads) + " thread(s), " + std::to_string(n) +
                 " vertices, 4 influences, " + (threads == 1 ? "CPU time" : "see the suffix: real_time = wall, process_time = CPU of both threads"));
  state.counters["Mvertices_per_s"] =
      benchmark::Counter(double(n) * state.iterations() / 1e6, benchmark::Counter::kIsRate);
}
constexpr int kLbs = int(SkinningMethod::lbs), kAs = int(SkinningMethod::animation_space),
              kMwe = int(SkinningMethod::mwe);
BENCHMARK(BM_RuntimePose)
    ->ArgsProduct({{kLbs, kAs, kMwe}, {1}, {13380, 200000}})
    ->Unit(benchmark::kMicrosecond);
// Two threads: wall time (the speed-up, meaningful only on an idle machine) and CPU time summed
// over both threads (the per-core throughput, robust when other jobs share the cores).
BENCHMARK(BM_RuntimePose)
    ->ArgsProduct({{kLbs, kAs, kMwe}, {2}, {13380, 200000}})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RuntimePose)
    ->ArgsProduct({{kLbs, kAs, kMwe}, {2}, {13380, 200000}})
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMicrosecond);

struct HorseData {
  std::vector<Eigen::MatrixX3d> frames;
  Eigen::MatrixX3i F;
};
const HorseData& horse() {
  static const HorseData h = [] {
    HorseData d;
    const auto dir = data_file("animations/horse-gallop");
    std::vector<std::filesystem::path> files;
    for (const auto& e : std::filesystem::directory_iterator(dir))
      if (e.path().extension() == ".obj") files.push_back(e.path());
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      Mesh m = read_mesh(f);
      d.F = m.F;
      d.frames.push_back(m.V);
    }
    return d;
  }();
  return h;
}

void BM_MweFitHorse(benchmark::State& state) {
  const HorseData& h = horse();
  SequenceEvaluationOptions opt;
  opt.max_influences = 4;
  const PreparedSequence prep =
      prepare_skinning_sequence(h.frames, h.F, evenly_spaced_frames(static_cast<int>(h.frames.size()), 10), opt);
  double cpu = 0;
  for (auto _ : state) {
    const double c0 = process_cpu_seconds();
    SkinningRig rig = fit_mwe(prep.examples, &prep.lbs);
    cpu += process_cpu_seconds() - c0;
    benchmark::DoNotOptimize(rig.coefficients.data());
  }
  state.counters["cpu_s_all_threads"] = cpu / state.iterations();
  state.SetLabel("horse 8431 vertices, 10 poses, 24 recovered bones, 4 influences, MWE solve only, " +
                 std::to_string(state.range(0)) + " thread(s) (TBB default)");
}
BENCHMARK(BM_MweFitHorse)->Arg(2)->UseRealTime()->Unit(benchmark::kMillisecond)->Iterations(3);

// Every method fitted once to the horse (see the header), and the pose of an unseen frame.
struct EveryMethod {
  std::vector<FittedModel> models;   // all_skinning_models() order
  BoneTransforms pose;
};
const EveryMethod& every_method() {
  static const EveryMethod e = [] {
    const HorseData& h = horse();
    SequenceEvaluationOptions opt;
    const PreparedSequence prep =
        prepare_skinning_sequence(h.frames, h.F, evenly_spaced_frames(static_cast<int>(h.frames.size()), 10), opt);
    EveryMethod out;
    for (SkinningModel m : all_skinning_models()) out.models.push_back(fit_model(m, prep.examples, prep.lbs, opt.fit));
    out.pose = prep.transforms[1];   // frame 02: not a training frame
    return out;
  }();
  return e;
}

void BM_EveryMethodPose(benchmark::State& state) {
  const EveryMethod& e = every_method();
  const FittedModel& m = e.models[static_cast<size_t>(state.range(0))];
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  for (auto _ : state) {
    Eigen::MatrixX3d X = m.pose(e.pose);
    benchmark::DoNotOptimize(X.data());
  }
  const double n = double(m.is_pose_space() ? m.pose_space.vertex_count() : m.rig.vertex_count());
  state.counters["Mvertices_per_s"] = benchmark::Counter(n * state.iterations() / 1e6, benchmark::Counter::kIsRate);
  state.SetLabel(skinning_model_name(m.model) + ", reference (double) evaluator, horse 8431 vertices, 24 bones, 8 "
                 "influences, 10 training poses, 1 thread, CPU time");
}
BENCHMARK(BM_EveryMethodPose)->DenseRange(0, 6)->Unit(benchmark::kMicrosecond);

// All seven timed in turn, 7 rounds, median CPU time per pose; ratio of SSD's time to each (so
// 0.5 = half SSD's throughput).
void BM_EveryMethodRatios(benchmark::State& state) {
  const EveryMethod& e = every_method();
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  const size_t M = e.models.size();
  std::vector<std::vector<double>> t(M);
  for (auto _ : state) {
    for (int round = 0; round < 7; ++round)
      for (size_t m = 0; m < M; ++m) {
        const int reps = 20;
        const double c0 = process_cpu_seconds();
        for (int r = 0; r < reps; ++r) {
          Eigen::MatrixX3d X = e.models[m].pose(e.pose);
          benchmark::DoNotOptimize(X.data());
        }
        t[m].push_back((process_cpu_seconds() - c0) / reps);
      }
  }
  std::vector<double> med(M);
  for (size_t m = 0; m < M; ++m) {
    std::sort(t[m].begin(), t[m].end());
    med[m] = t[m][t[m].size() / 2];
  }
  for (size_t m = 0; m < M; ++m) {
    const std::string name = skinning_model_name(e.models[m].model);
    state.counters[name + "_Mvert_per_cpu_s"] = 8431e-6 / med[m];
    state.counters[name + "_throughput_vs_ssd"] = med[0] / med[m];
  }
  state.SetLabel("reference evaluators, horse rigs, 1 thread, median of 7 rounds of 20 poses (CPU time)");
}
BENCHMARK(BM_EveryMethodRatios)->Iterations(1)->Unit(benchmark::kSecond);

struct LargeFitData {
  SkinningExamples ex;
};

// 300 000 points on the MakeHuman body × 50 poses (see the header comment). Built once.
const LargeFitData& large_fit_data() {
  static const LargeFitData data = [] {
    constexpr int kPoints = 300000, kPoses = 50;
    const MakeHuman mh = MakeHuman::load();
    const MakeHuman::Body body = mh.body(MacroSettings{});
    const BvhMotion clip = read_bvh(data_file("makehuman/motion/cmu/02_02.bvh"));
    const std::vector<Pose> poses = poses_from_bvh(clip, body.skeleton, data_file("makehuman"));
    std::mt19937 rng(7);
    std::uniform_int_distribution<int> tri(0, static_cast<int>(body.mesh.F.rows()) - 1);
    std::uniform_real_distribution<double> u(0, 1);
    // Each point: a fixed barycentric combination (a, b, c) of one triangle's corners.
    std::vector<Eigen::Triplet<double>> trip;
    for (int i = 0; i < kPoints; ++i) {
      double r1 = u(rng), r2 = u(rng);
      if (r1 + r2 > 1) r1 = 1 - r1, r2 = 1 - r2;
      const int f = tri(rng);
      trip.emplace_back(i, body.mesh.F(f, 0), 1 - r1 - r2);
      trip.emplace_back(i, body.mesh.F(f, 1), r1);
      trip.emplace_back(i, body.mesh.F(f, 2), r2);
    }
    Eigen::SparseMatrix<double, Eigen::RowMajor> S(kPoints, body.mesh.V.rows());
    S.setFromTriplets(trip.begin(), trip.end());
    LargeFitData d;
    d.ex.rest = S * body.mesh.V;
    for (int p = 0; p < kPoses; ++p) {
      const int frame = p * (static_cast<int>(poses.size()) - 1) / (kPoses - 1);
      const BoneTransforms M = forward_kinematics(body.skeleton, poses[static_cast<size_t>(frame)]);
      d.ex.transforms.push_back(M);
      d.ex.poses.push_back(S * linear_blend_skinning(body.mesh.V, body.weights, M));
    }
    return d;
  }();
  return data;
}

void BM_FitLarge(benchmark::State& state) {
  const LargeFitData& d = large_fit_data();
  double ssd_s = 0, mwe_s = 0, ssd_cpu = 0, mwe_cpu = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = process_cpu_seconds();
    const SkinningRig lbs = fit_lbs(d.ex);
    const auto t1 = std::chrono::steady_clock::now();
    const double c1 = process_cpu_seconds();
    const SkinningRig mwe = fit_mwe(d.ex, &lbs);
    const auto t2 = std::chrono::steady_clock::now();
    const double c2 = process_cpu_seconds();
    ssd_s = std::chrono::duration<double>(t1 - t0).count();
    mwe_s = std::chrono::duration<double>(t2 - t1).count();
    ssd_cpu = c1 - c0;
    mwe_cpu = c2 - c1;
    benchmark::DoNotOptimize(mwe.coefficients.data());
  }
  state.counters["ssd_wall_s"] = ssd_s;
  state.counters["mwe_wall_s"] = mwe_s;
  state.counters["ssd_cpu_s"] = ssd_cpu;   // all threads
  state.counters["mwe_cpu_s"] = mwe_cpu;
  state.SetLabel("300000 points on the MakeHuman body, 50 poses (CMU 02_02), 163 bones, automatic 4-influence "
                 "sets; SSD fit then MWE fit, TBB default threads (2 cores)");
}
BENCHMARK(BM_FitLarge)->UseRealTime()->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace
}  // namespace bodymodel

BENCHMARK_MAIN();
