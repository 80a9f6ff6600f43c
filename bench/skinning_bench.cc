// Skinning speed: runtime evaluation throughput (vertices per second, float32 SoA evaluator) of
// LBS, Animation Space and MWE with 4 influences on 1 and 2 threads, and the MWE fit of the horse
// gallop (8 431 vertices, 10 evenly spaced poses; the MWE solve only, after bone recovery and the
// SSD base). Positions only, no I/O. Report MWE/LBS as the ratio of the two throughputs.
//   ./build/skinning_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <filesystem>
#include <random>

#include "core/data_path.h"
#include "core/io/mesh_io.h"
#include "skinning/fit_mwe.h"
#include "skinning/runtime_skinning.h"
#include "skinning/sequence_evaluation.h"

namespace bodymodel {
namespace {

constexpr int kVertices = 200000, kBones = 24, kInfluences = 4;

SkinningRig random_rig(SkinningMethod method) {
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> bone(0, kBones - 1);
  std::uniform_real_distribution<double> u(0, 1);
  SkinningRig rig;
  rig.method = method;
  rig.bone_count = kBones;
  rig.rest = Eigen::MatrixX3d::Random(kVertices, 3);
  rig.influences.resize(kVertices, kInfluences);
  const int c = coefficients_per_influence(method);
  rig.coefficients.resize(kVertices, kInfluences * c);
  for (int i = 0; i < kVertices; ++i)
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

void BM_RuntimePose(benchmark::State& state) {
  const auto method = static_cast<SkinningMethod>(state.range(0));
  const int threads = static_cast<int>(state.range(1));
  const RuntimeSkinner skinner(random_rig(method));
  const BoneTransforms M = random_pose();
  std::vector<float> x(kVertices), y(kVertices), z(kVertices);
  for (auto _ : state) {
    skinner.pose(M, x.data(), y.data(), z.data(), threads);
    benchmark::DoNotOptimize(x.data());
    benchmark::ClobberMemory();
  }
  state.SetLabel(skinning_method_name(method) + ", " + std::to_string(threads) + " thread(s), " +
                 std::to_string(kVertices) + " vertices, 4 influences");
  state.counters["vertices_per_s"] =
      benchmark::Counter(double(kVertices) * state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_RuntimePose)
    ->ArgsProduct({{int(SkinningMethod::lbs), int(SkinningMethod::animation_space), int(SkinningMethod::mwe)}, {1, 2}})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);

void BM_MweFitHorse(benchmark::State& state) {
  const auto dir = data_file("animations/horse-gallop");
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().extension() == ".obj") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  std::vector<Eigen::MatrixX3d> frames;
  Eigen::MatrixX3i F;
  for (const auto& f : files) {
    Mesh m = read_mesh(f);
    F = m.F;
    frames.push_back(m.V);
  }
  SequenceEvaluationOptions opt;
  const PreparedSequence prep =
      prepare_skinning_sequence(frames, F, evenly_spaced_frames(static_cast<int>(frames.size()), 10), opt);
  for (auto _ : state) {
    SkinningRig rig = fit_mwe(prep.examples, &prep.lbs);
    benchmark::DoNotOptimize(rig.coefficients.data());
  }
  state.SetLabel("horse 8431 vertices, 10 poses, 24 recovered bones, 4 influences, MWE solve only, " +
                 std::to_string(state.range(0)) + " thread(s) (TBB default)");
}
BENCHMARK(BM_MweFitHorse)->Arg(2)->UseRealTime()->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace
}  // namespace bodymodel

BENCHMARK_MAIN();
