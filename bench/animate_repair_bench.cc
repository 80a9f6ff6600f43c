// Cost of `bodymodel animate`'s fold repair (core/fold_repair.h, repair_folds_against_normals;
// tools/pipeline/animate_job.h) against the skinning of the same frames, same process.
//   * BM_AnimateSkinning: the runtime evaluator (1 thread) on the MakeHuman body (13 380
//     vertices, MakeHuman's weights, 4 influences) through every 12th frame of CMU 02_02 (25), retargeted
//     as `animate` does (RetargetOptions::for_animation).
//   * BM_AnimateSkinningAndRepair: the same plus the flip references (each triangle's rest normal
//     turned by its dominant bone, the check of tools/pipeline/deformation_check.h) and the
//     repair of every frame with the animation defaults (16 passes, edges kept <= 3x rest).
//     Counters: flips before and after (worst frame).
// Both timed in CPU time (time per iteration = all 25 frames); (repair time - skinning time) /
// skinning time is the repair's cost as a multiple of skinning. Measured (load ~9, CPU column):
// skinning 2.4 ms, skinning + repair 296 ms for the 25 frames: ~12 ms per frame, ~120x the
// single-threaded float evaluator; worst frame 42 flipped before, 0 after. The template weights fold more than a character's smoothed SSD
// (25-35 vs 7-20 triangles in the worst frame), so this is an upper side of the cost.
//   ./build/animate_repair_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <map>

#include "core/fold_repair.h"
#include "core/geometry.h"
#include "core/io/bvh.h"
#include "core/makehuman.h"
#include "core/retarget.h"
#include "skinning/runtime_skinning.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {
namespace {

struct Scene {
  Eigen::MatrixX3d rest;
  Eigen::MatrixX3i F;
  Eigen::MatrixX3d rest_normals;
  Eigen::VectorXi face_bone;  // #F dominant bone (largest summed corner weight)
  SkinningRig rig;
  std::vector<BoneTransforms> frames;
};

const Scene& scene() {
  static Scene s = [] {
    Scene out;
    const MakeHuman mh = MakeHuman::load();
    const MakeHuman::Body b = mh.body(MacroSettings{});
    out.rest = b.mesh.V;
    out.F = b.mesh.F;
    out.rest_normals = face_normals(out.rest, out.F);
    out.rig = lbs_rig_from_weights(out.rest, Eigen::MatrixXd(b.weights), 4);
    out.face_bone.resize(out.F.rows());
    for (Eigen::Index f = 0; f < out.F.rows(); ++f) {
      std::map<int, double> w;
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < out.rig.max_influences(); ++k)
          if (out.rig.influences(out.F(f, c), k) >= 0)
            w[out.rig.influences(out.F(f, c), k)] += out.rig.coefficients(out.F(f, c), k);
      int best = 0;
      double bw = -1;
      for (auto [bone, x] : w)
        if (x > bw) bw = x, best = bone;
      out.face_bone(f) = best;
    }
    const BvhMotion m = read_bvh(mh.directory() / "motion" / "cmu" / "02_02.bvh");
    const Retargeter r(m, b.skeleton, RetargetMap::for_clip(m, mh.directory()), RetargetOptions::for_animation());
    for (int f = 0; f < m.frame_count(); f += 12) out.frames.push_back(forward_kinematics(b.skeleton, r.pose(f)));
    return out;
  }();
  return s;
}

void run(benchmark::State& state, bool repair) {
  const Scene& s = scene();
  const RuntimeSkinner skinner(s.rig);
  FoldRepairOptions ro;
  ro.passes = 16;
  ro.max_edge_ratio = 3;
  int before = 0, after = 0;
  for (auto _ : state) {
    for (const BoneTransforms& M : s.frames) {
      Eigen::MatrixX3d X = skinner.pose(M, 1).cast<double>();
      if (repair) {
        Eigen::MatrixX3d N(s.F.rows(), 3);
        for (Eigen::Index f = 0; f < s.F.rows(); ++f)
          N.row(f) = (M[s.face_bone(f)].linear() * s.rest_normals.row(f).transpose()).transpose();
        const FoldRepairSummary r = repair_folds_against_normals(X, s.rest, N, s.F, ro);
        before = std::max(before, r.flipped_before);
        after = std::max(after, r.flipped_after);
      }
      benchmark::DoNotOptimize(X.data());
    }
  }
  state.counters["frames"] = double(s.frames.size());
  if (repair) {
    state.counters["worst_flipped_before"] = before;
    state.counters["worst_flipped_after"] = after;
  }
}

void BM_AnimateSkinning(benchmark::State& state) { run(state, false); }
void BM_AnimateSkinningAndRepair(benchmark::State& state) { run(state, true); }

BENCHMARK(BM_AnimateSkinning)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_AnimateSkinningAndRepair)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();

}  // namespace
}  // namespace bodymodel
BENCHMARK_MAIN();
