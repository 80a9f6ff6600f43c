// Encoding speed on the 13 380-vertex / 26 756-triangle MakeHuman body (issue 4 targets:
// decode ≤ 60 ms median, encode ≤ 30 ms, after the one-time set-up).
//
//   encoding_bench [--benchmark_filter=...]
//
// Benchmarks (Google Benchmark's wall time is inflated on a shared machine: the summary at
// the end gives medians in process CPU time summed over threads, the fairer figure):
//   Encode                 posed body → encoding relative to the set mean
//   Setup                  decoder construction (once per template)
//   Decode/0 encoded       an encoded mesh (realisable: exact tree integration, no linear solve)
//   Decode/1 pose-blend    default body, halfway between fight01 and run01
//   Decode/2 body-blend    0.5·(default body in fight01 + heavy male in run01)
//   Decode/3 sample        set mean + a 2σ random combination of the 6 set encodings
//   Decode/4 cholesky      the body blend with RotationSolver::kCholeskyRefactor (CHOLMOD's
//                          scalar refactorisation instead of the default 3×3-block Cholesky)
//   Decode/5 baseline      the body blend, both systems analysed and factorised on every call
//   DecodeTwoThreads       one decoder, two threads decoding a sample and a blend concurrently
//   RotationFactor         the body blend's rotation system (3·26 755 unknowns, triangle 0
//                          fixed), numeric factorisation and solve, interleaved in one loop:
//                          the hand-written block supernodal Cholesky (encoding/block_cholesky.h,
//                          the decoder's path), CHOLMOD simplicial and CHOLMOD supernodal; the
//                          summary prints factorise + solve per decode in wall and process CPU,
//                          their ratio, and which BLAS the process mapped
// Each decode is also run in its two stages (split/...: rotation = encoding → matrices,
// rotation solve, orthonormalisation; Poisson = right-hand side and back-substitution).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>
#include <thread>
#include <random>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

#include "core/io/bvh.h"
#include "core/makehuman.h"
#include "core/skeleton.h"
#include <Eigen/CholmodSupport>
#include <Eigen/Sparse>

#include "encoding/block_cholesky.h"
#include "encoding/relative_rotation_decoder.h"
#include "encoding/relative_rotation_encoding.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct Fixture {
  std::shared_ptr<const EncodingTemplate> tmpl;
  Eigen::MatrixX3d posed_a, posed_b;
  EncodedSet set;        // 3 bodies × 2 poses; encodings[0] = default body in fight01
  Encoding pose_blend;   // default body: halfway between fight01 and run01
  Encoding body_blend;   // 0.5·(body A in fight01 + body B in run01)
  Encoding sample;       // mean + a 2σ random combination of the set's deviations
};

const Fixture& fixture() {
  static const Fixture f = [] {
    Fixture x;
    const MakeHuman mh = MakeHuman::load();
    MacroSettings heavy, slim;
    heavy.gender = 1, heavy.weight = 0.85, heavy.muscle = 0.7, heavy.height = 0.7;
    slim.gender = 0, slim.weight = 0.2, slim.height = 0.3, slim.age = 0.8;
    const MakeHuman::Body body = mh.body(MacroSettings{});
    x.tmpl = std::make_shared<const EncodingTemplate>(body.mesh.V, body.mesh.F);
    std::vector<Eigen::MatrixX3d> meshes;
    for (const MacroSettings& s : {MacroSettings{}, heavy, slim}) {
      const MakeHuman::Body b = mh.body(s);
      for (const char* name : {"fight01", "run01"}) {
        const Pose p = bvh_frame_to_pose(read_bvh(mh.pose_file(name)), 0, b.skeleton);
        meshes.push_back(linear_blend_skinning(b.mesh.V, b.weights, forward_kinematics(b.skeleton, p)));
      }
    }
    x.posed_a = meshes[0];
    x.posed_b = meshes[1];
    x.set = encode_set(*x.tmpl, meshes);
    const auto& e = x.set.encodings;
    x.pose_blend = interpolate(e[0], e[1], 0.5);
    x.body_blend = interpolate(e[0], e[3], 0.5);
    // Deviations from the mean are the encodings themselves (relative storage); a unit-variance
    // combination along random directions is Σ z_i e_i / sqrt(n): scale it to 2σ.
    std::mt19937 rng(4);
    std::normal_distribution<double> z;
    x.sample = 0.0 * e[0];
    for (const Encoding& ei : e) x.sample = x.sample + (2.0 * z(rng) / std::sqrt(double(e.size()))) * ei;
    return x;
  }();
  return f;
}

std::map<std::string, std::vector<double>>& samples() {
  static std::map<std::string, std::vector<double>> s;
  return s;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

void BM_Encode(benchmark::State& state) {
  const Fixture& f = fixture();
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::clock_t c0 = std::clock();
    Encoding e = encode(*f.tmpl, f.posed_a, f.set.mean);
    benchmark::DoNotOptimize(e.values.data());
    samples()["encode (process CPU)"].push_back(1000.0 * (std::clock() - c0) / CLOCKS_PER_SEC);
    samples()["encode"].push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
}
BENCHMARK(BM_Encode)->Unit(benchmark::kMillisecond)->Iterations(20);

void BM_Setup(benchmark::State& state) {
  const Fixture& f = fixture();
  for (auto _ : state) {
    RelativeRotationDecoder d(f.tmpl);
    benchmark::DoNotOptimize(&d);
  }
}
BENCHMARK(BM_Setup)->Unit(benchmark::kMillisecond)->Iterations(3);

// Cases: 0 encoded mesh (realisable), 1 pose blend, 2 body blend, 3 model sample (defaults
// options), 4 body blend with the Cholesky path forced, 5 baseline: body blend, everything
// analysed and factorised from scratch on every call.
constexpr const char* kCaseNames[] = {"encoded", "pose-blend", "body-blend", "sample",
                                      "cholesky", "baseline"};

double cpu_ms_since(std::clock_t c0) { return 1000.0 * (std::clock() - c0) / CLOCKS_PER_SEC; }

void BM_Decode(benchmark::State& state) {
  const Fixture& f = fixture();
  const int mode = static_cast<int>(state.range(0));
  const std::string name = kCaseNames[mode];
  DecoderOptions o;
  if (mode >= 4) o.rotation_solver = RotationSolver::kCholeskyRefactor;
  if (mode == 5) o.reuse_factorisations = false;
  RelativeRotationDecoder decoder(f.tmpl, o);
  const Encoding& e = mode == 0 ? f.set.encodings[0]
                      : mode == 1 ? f.pose_blend
                      : mode == 3 ? f.sample
                                  : f.body_blend;
  decoder.decode(e);  // warm-up (the first Cholesky decode analyses the pattern)
  DecodeTiming sum;
  for (auto _ : state) {
    std::clock_t c0 = std::clock();
    Eigen::MatrixX3d X = decoder.decode(e, {}, nullptr);
    benchmark::DoNotOptimize(X.data());
    samples()["decode/" + name + " (process CPU)"].push_back(cpu_ms_since(c0));
    const DecodeTiming t = decoder.last_timing();
    sum.assemble_ms += t.assemble_ms;
    sum.rotation_solve_ms += t.rotation_solve_ms;
    sum.orthonormalise_ms += t.orthonormalise_ms;
    sum.poisson_ms += t.poisson_ms;
    sum.cg_iterations = t.cg_iterations;
    sum.rotation_path = t.rotation_path;
    samples()["decode/" + name].push_back(t.total_ms);
    // The same decode in its two stages, each timed in process CPU: rotation = encoding →
    // matrices + rotation solve + orthonormalisation; Poisson = right-hand side + solve.
    state.PauseTiming();
    c0 = std::clock();
    std::vector<Eigen::Matrix3d> slots, S;
    encoding_matrices(e, slots, S);
    const std::vector<Eigen::Matrix3d> R = decoder.solve_rotations(slots);
    samples()["split/" + name + " rotation (process CPU)"].push_back(cpu_ms_since(c0));
    c0 = std::clock();
    const Eigen::MatrixX3d P = decoder.solve_positions(R, S);
    benchmark::DoNotOptimize(P.data());
    samples()["split/" + name + " Poisson (process CPU)"].push_back(cpu_ms_since(c0));
    state.ResumeTiming();
  }
  const double n = static_cast<double>(state.iterations());
  state.SetLabel(name);
  state.counters["assemble_ms"] = sum.assemble_ms / n;
  state.counters["rotation_solve_ms"] = sum.rotation_solve_ms / n;
  state.counters["orthonormalise_ms"] = sum.orthonormalise_ms / n;
  state.counters["poisson_ms"] = sum.poisson_ms / n;
  state.counters["cg_iterations"] = sum.cg_iterations;
  state.counters["rotation_path"] = sum.rotation_path;
}
BENCHMARK(BM_Decode)->DenseRange(0, 5)->Unit(benchmark::kMillisecond)->Iterations(10);

// Two threads decoding different encodings on ONE decoder (issue 5 generates bodies this way):
// wall time per body, to compare with the sequential decode/... figures.
void BM_DecodeTwoThreads(benchmark::State& state) {
  const Fixture& f = fixture();
  const RelativeRotationDecoder decoder(f.tmpl);
  const Encoding* work[] = {&f.sample, &f.body_blend};
  decoder.decode(f.sample);
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    std::thread other([&] { benchmark::DoNotOptimize(decoder.decode(*work[1]).data()); });
    benchmark::DoNotOptimize(decoder.decode(*work[0]).data());
    other.join();
    samples()["two threads: wall per body"].push_back(
        0.5 * std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
}
BENCHMARK(BM_DecodeTwoThreads)->Unit(benchmark::kMillisecond)->Iterations(6)->UseRealTime();

// The rotation system of the body blend on its own: block values and scalar matrix.
struct RotationSystem {
  int n = 0;                                    // unknown blocks (triangle 0 fixed)
  std::vector<std::pair<int, int>> lower;       // block pattern, (r, c) with r > c
  std::vector<Eigen::Matrix3d> diag, off;       // values for BlockCholesky3
  Eigen::SparseMatrix<double> N;                // the same 3n by 3n matrix, lower triangle
  Eigen::MatrixXd b;                            // 3n by 3 right-hand side
  std::unique_ptr<BlockCholesky3> supernodal;
};

const RotationSystem& rotation_system() {
  static const RotationSystem sys = [] {
    const Fixture& f = fixture();
    RotationSystem r;
    std::vector<Eigen::Matrix3d> slots, S;
    encoding_matrices(f.body_blend, slots, S);
    const Eigen::MatrixX3i& TT = f.tmpl->adjacency();
    const int nf = f.tmpl->triangle_count();
    r.n = nf - 1;
    auto reverse = [&](int f0, int k) {
      const int g = TT(f0, k);
      for (int kk = 0; kk < 3; ++kk)
        if (TT(g, kk) == f0) return 3 * g + kk;
      return 3 * f0 + k;
    };
    std::vector<Eigen::Triplet<double>> t;
    r.diag.assign(r.n, Eigen::Matrix3d::Zero());
    r.b = Eigen::MatrixXd::Zero(3 * r.n, 3);
    for (int f0 = 0; f0 < nf; ++f0)
      for (int k = 0; k < 3; ++k) {
        const int g = TT(f0, k);
        if (g < 0) continue;
        const Eigen::Matrix3d M = slots[3 * f0 + k] + slots[reverse(f0, k)].transpose();
        if (f0 >= 1) r.diag[f0 - 1] += 2 * Eigen::Matrix3d::Identity();
        if (f0 >= 1 && g == 0) r.b.middleRows<3>(3 * (f0 - 1)) += M;
        if (f0 > g && g >= 1) {
          r.lower.emplace_back(f0 - 1, g - 1);
          r.off.push_back(-M);
        }
      }
    for (int p = 0; p < r.n; ++p)
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) t.emplace_back(3 * p + a, 3 * p + c, r.diag[p](a, c));
    for (size_t e = 0; e < r.lower.size(); ++e)
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c)
          t.emplace_back(3 * r.lower[e].first + a, 3 * r.lower[e].second + c, r.off[e](a, c));
    r.N.resize(3 * r.n, 3 * r.n);
    r.N.setFromTriplets(t.begin(), t.end());
    r.supernodal = std::make_unique<BlockCholesky3>(r.n, r.lower);
    return r;
  }();
  return sys;
}

// The three factorisations of the same matrix, interleaved in one loop (each iteration runs
// all three, in a rotating order, so load from other processes hits them alike): numeric
// factorisation and solve for the 3 right-hand sides, as the decoder does per decode (its
// symbolic analysis is done once, outside the loop). Wall and process CPU per method.
constexpr const char* kFactorNames[] = {"block", "CHOLMOD simplicial", "CHOLMOD supernodal"};

double wall_ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void BM_RotationFactor(benchmark::State& state) {
  const RotationSystem& r = rotation_system();
  Eigen::CholmodSimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower> simplicial;
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> supernodal;
  simplicial.analyzePattern(r.N);
  supernodal.analyzePattern(r.N);
  BlockCholesky3::Factor factor;
  Eigen::MatrixXd x[3];
  int round = 0;
  for (auto _ : state) {
    for (int step = 0; step < 3; ++step) {
      const int method = (round + step) % 3;
      const std::string name = std::string("rotation system: ") + kFactorNames[method];
      x[method] = r.b;
      std::clock_t c0 = std::clock();
      auto w0 = std::chrono::steady_clock::now();
      if (method == 0) {
        if (!r.supernodal->factorize(r.diag, r.off, factor)) state.SkipWithError("not positive definite");
      } else if (method == 1) {
        simplicial.factorize(r.N);
      } else {
        supernodal.factorize(r.N);
      }
      samples()[name + " factorise (process CPU)"].push_back(cpu_ms_since(c0));
      samples()[name + " factorise (wall)"].push_back(wall_ms_since(w0));
      c0 = std::clock();
      w0 = std::chrono::steady_clock::now();
      if (method == 0) r.supernodal->solve(factor, x[0]);
      else if (method == 1) x[1] = simplicial.solve(r.b);
      else x[2] = supernodal.solve(r.b);
      samples()[name + " solve (process CPU)"].push_back(cpu_ms_since(c0));
      samples()[name + " solve (wall)"].push_back(wall_ms_since(w0));
    }
    ++round;
  }
  for (int method = 0; method < 3; ++method) {
    const Eigen::MatrixXd full = r.N.selfadjointView<Eigen::Lower>() * x[method];
    state.counters[std::string("residual_") + std::to_string(method)] = (full - r.b).norm() / r.b.norm();
  }
  state.counters["max_diff_block_vs_cholmod_supernodal"] = (x[0] - x[2]).cwiseAbs().maxCoeff();
  state.counters["supernodes"] = r.supernodal->supernode_count();
  state.counters["factor_blocks"] = static_cast<double>(r.supernodal->factor_blocks());
  state.counters["MFlop"] = r.supernodal->factor_flops() / 1e6;
}
BENCHMARK(BM_RotationFactor)->Unit(benchmark::kMillisecond)->Iterations(15);

// The BLAS and LAPACK libraries the process mapped (CHOLMOD's supernodal path calls them). The
// link line and Debian's alternatives decide together: Ceres's package links ATLAS's libf77blas
// directly, and CHOLMOD's level-3 calls bind to it (docs/dependencies.md).
std::string mapped_blas() {
  std::ifstream maps("/proc/self/maps");
  std::string line, out;
  std::set<std::string> seen;
  while (std::getline(maps, line)) {
    const size_t slash = line.find('/');
    if (slash == std::string::npos) continue;
    const std::string path = line.substr(slash);
    if ((path.find("blas") != std::string::npos || path.find("lapack") != std::string::npos ||
         path.find("atlas") != std::string::npos) && seen.insert(path).second) {
      std::error_code ec;
      const fs::path real = fs::canonical(path, ec);
      out += "  " + (ec ? path : real.string()) + "\n";
    }
  }
  return out.empty() ? "  (none)\n" : out;
}

}  // namespace
}  // namespace bodymodel

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  using bodymodel::median;
  auto& s = bodymodel::samples();
  std::printf("\nMedians over the timed calls (ms), 13380-vertex / 26756-triangle body:\n");
  for (const auto& [name, v] : s) std::printf("  %-36s %8.1f\n", name.c_str(), median(v));
  auto ratio = [&](const std::string& a, const std::string& b) {
    const double x = median(s[a]), y = median(s[b]);
    return y > 0 ? x / y : 0.0;
  };
  const std::string base = "decode/baseline (process CPU)";
  if (s.count(base)) {
    std::printf("baseline (refactorise everything per call) / reuse, process CPU:");
    for (const char* c : {"encoded", "pose-blend", "body-blend", "sample", "cholesky"})
      if (s.count(std::string("decode/") + c + " (process CPU)"))
        std::printf("  %s %.1fx", c, ratio(base, std::string("decode/") + c + " (process CPU)"));
    std::printf("\n");
  }
  // Factorise + solve per decode (the decoder refactorises on every decode that reaches the
  // Cholesky path), in wall time (the supernodal codes use both cores: TBB, BLAS threads) and
  // process CPU.
  auto per_decode = [&](const std::string& method, const char* clock) {
    const std::string p = "rotation system: " + method;
    return median(s[p + " factorise (" + clock + ")"]) + median(s[p + " solve (" + clock + ")"]);
  };
  if (s.count("rotation system: block factorise (wall)")) {
    std::printf("rotation system, factorise + solve per decode (medians, ms):\n");
    for (const char* clock : {"wall", "process CPU"})
      std::printf("  %-11s block supernodal %7.1f  CHOLMOD simplicial %7.1f  CHOLMOD supernodal %7.1f"
                  "  -> CHOLMOD supernodal / block = %.2f\n",
                  clock, per_decode("block", clock), per_decode("CHOLMOD simplicial", clock),
                  per_decode("CHOLMOD supernodal", clock),
                  per_decode("CHOLMOD supernodal", clock) / per_decode("block", clock));
    std::printf("BLAS/LAPACK mapped at run time:\n%s", bodymodel::mapped_blas().c_str());
  }
  return 0;
}
