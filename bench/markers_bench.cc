// `markers clean` speed (issue 38: 350 markers × 1 000 frames in ≤ 10 s on 2 cores): a capture
// simulated from the Vlasic "jumping" meshes (markers/simulate.h defaults, 350 markers, the 30
// mesh frames at 10 fps interpolated to 345 Hz: 1 001 frames), then cleaned (merge, fill, smooth;
// markers/clean.h defaults). Wall time on the threads TBB is given (2 on the project's machine), and
// the CPU seconds of all threads (on a shared machine, CPU / cores is the idle-machine wall).
//   ./build/bench/markers_bench --benchmark_repetitions=3
#include <benchmark/benchmark.h>

#include <algorithm>
#include <ctime>
#include <filesystem>

#include "core/data_path.h"
#include "core/io/mesh_io.h"
#include "markers/clean.h"
#include "markers/simulate.h"

namespace bodymodel {
namespace {

const SimulatedCapture& capture() {
  static const SimulatedCapture s = [] {
    std::vector<std::filesystem::path> files;
    for (const auto& e : std::filesystem::directory_iterator(data_root() / "animations" / "vlasic-jumping"))
      if (e.path().extension() == ".obj") files.push_back(e.path());
    std::sort(files.begin(), files.end());
    std::vector<Eigen::MatrixX3d> frames;
    Eigen::MatrixX3i F;
    for (const auto& f : files) {
      const Mesh m = read_mesh(f);
      frames.push_back(m.V);
      F = m.F;
    }
    SimulateOptions o;
    o.rate = 345;
    return simulate_capture(frames, F, o);
  }();
  return s;
}

void BM_MarkersClean(benchmark::State& state) {
  const SimulatedCapture& s = capture();
  CleanResult r;
  double cpu = 0;
  for (auto _ : state) {
    const std::clock_t c0 = std::clock();  // CPU seconds of every thread of the process
    r = clean_markers(s.capture);
    cpu = double(std::clock() - c0) / CLOCKS_PER_SEC;
  }
  state.counters["cpu_s_all_threads"] = cpu;
  const CleanEvaluation e = evaluate_cleaning(s.capture, r, s.truth);
  state.counters["frames"] = s.truth.frame_count();
  state.counters["markers"] = s.truth.marker_count();
  state.counters["pieces"] = r.report.pieces;
  state.counters["merged"] = r.report.merged;
  state.counters["wrong_merges"] = e.wrong_merges;
  state.counters["median_fill_mm"] = e.median_fill_mm;
}
BENCHMARK(BM_MarkersClean)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace
}  // namespace bodymodel

BENCHMARK_MAIN();
