// Pose morphing (Hasler et al. 2009 §5.4) diagnosis on a database's held-out subjects: for each
// held-out subject's standard-pose truth mesh morphed into the joint angles of each of its posed
// scans, the body's volume after each stage (encode/decode round trip, joint-angle labels only,
// labels + positional constraints) relative to the rest body, the torso's rigid offset from the
// body skinned with the model's rig (after the whole-body rigid placement the character
// pipeline uses), and the mean vertex error against the scan's truth mesh.
//
// Model: BODYMODEL_BENCH_MODEL (default /tmp/model30.npz, `bodymodel build` of the first 30
// subjects of the database), database BODYMODEL_BENCH_DB (default /tmp/model_db); subjects of
// the database that are not in the model are held out.
//   build-x/bench/pose_morph_bench --benchmark_filter=PoseMorphStages
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numeric>

#include "core/geometry.h"
#include "core/io/mesh_io.h"
#include "core/io/pose_csv.h"
#include "model/database.h"
#include "model/model_file.h"
#include "model/pose_edit.h"

namespace bodymodel {
namespace {

struct Stats {
  std::vector<double> v;
  void add(double x) { v.push_back(x); }
  double mean() const { return v.empty() ? 0 : std::accumulate(v.begin(), v.end(), 0.0) / v.size(); }
  double min() const { return v.empty() ? 0 : *std::min_element(v.begin(), v.end()); }
  double max() const { return v.empty() ? 0 : *std::max_element(v.begin(), v.end()); }
};

void BM_PoseMorphStages(benchmark::State& state) {
  namespace fs = std::filesystem;
  const char* env_db = std::getenv("BODYMODEL_BENCH_DB");
  const char* env_model = std::getenv("BODYMODEL_BENCH_MODEL");
  const fs::path db = env_db ? env_db : "/tmp/model_db";
  const fs::path model_path = env_model ? env_model : "/tmp/model30.npz";
  if (!fs::exists(db / "scans.csv") || !fs::exists(model_path)) {
    state.SkipWithError(("need " + (db / "scans.csv").string() + " and " + model_path.string()).c_str());
    return;
  }
  const BodyModel model = load_model(model_path);
  const auto scans = read_scan_table(db / "scans.csv");
  const auto& known = model.shape.sample_ids;
  std::vector<std::pair<std::string, std::string>> cases;
  for (auto& r : scans) {
    if (std::find(known.begin(), known.end(), r.subject_id) != known.end() || r.pose == "standard") continue;
    for (auto& q : scans)
      if (q.subject_id == r.subject_id && q.pose == "standard") cases.emplace_back(q.scan_id, r.scan_id);
  }
  const Eigen::MatrixX3i& F = model.tmpl->faces();
  const Eigen::VectorXd torso_w = torso_weight(model.rig);
  for (auto _ : state) {
    RelativeRotationDecoder decoder(model.tmpl);
    Stats round, labels, tips, truthv, lbsv, err, err_lbs, torso_t, torso_deg, torso_before, torso_after;
    for (auto& [st, posed] : cases) {
      const Mesh body = read_mesh(db / "truth" / (st + ".ply"));
      const Mesh truth = read_mesh(db / "truth" / (posed + ".ply"));
      const Pose pose = read_pose_csv(db / "truth" / (posed + ".pose.csv"), model.rig.bone_names).pose;
      const double v0 = signed_volume(body.V, F);
      const Eigen::MatrixX3d rt = decoder.decode(model.encode(body.V));
      PoseMorphOptions o;
      o.anchor_torso = state.range(0) != 0;
      o.preserve_volume = false;
      o.torso_anchor_weight = std::pow(10.0, static_cast<double>(state.range(2)));
      o.use_tip_constraints = false;
      const Eigen::MatrixX3d lab = pose_morph(model, decoder, body.V, pose, o);
      o.use_tip_constraints = true;
      o.preserve_volume = state.range(1) != 0;
      const Eigen::MatrixX3d out = pose_morph(model, decoder, body.V, pose, o);
      const Eigen::Matrix3d G = canonical_rotation(model.rig, body.V);
      const Eigen::MatrixX3d Vc = body.V * G.transpose();
      const Eigen::MatrixX3d lbs =
          linear_blend_skinning(Vc, model.rig.weights, forward_kinematics(model.rig.skeleton_for(Vc), pose)) * G;
      const double vr = signed_volume(rt, F) / v0, vl = signed_volume(lab, F) / v0, vt = signed_volume(out, F) / v0;
      round.add(vr);
      labels.add(vl);
      tips.add(vt);
      truthv.add(signed_volume(truth.V, F) / v0);
      lbsv.add(signed_volume(lbs, F) / v0);
      err.add(mean_vertex_error_after_rigid_fit(out, truth.V));
      err_lbs.add(mean_vertex_error_after_rigid_fit(lbs, truth.V));
      const TorsoOffset to = torso_offset(out, lbs, torso_w);
      torso_t.add(to.translation_mm);
      torso_deg.add(to.rotation_deg);
      torso_before.add(to.mean_distance_mm);
      torso_after.add(to.mean_distance_after_mm);
      std::fprintf(stderr,
                   "%s -> %s: volume round trip %.4f labels %.4f +tips %.4f truth %.4f lbs %.4f | error %.2f mm "
                   "(lbs %.2f) | torso vs lbs %.1f mm %.2f deg, mean %.1f -> %.1f mm\n",
                   st.c_str(), posed.c_str(), vr, vl, vt, truthv.v.back(), lbsv.v.back(), err.v.back(),
                   err_lbs.v.back(), to.translation_mm, to.rotation_deg, to.mean_distance_mm,
                   to.mean_distance_after_mm);
    }
    auto line = [](const char* name, const Stats& s) {
      std::fprintf(stderr, "%-28s mean %.4f min %.4f max %.4f\n", name, s.mean(), s.min(), s.max());
    };
    std::fprintf(stderr, "%zu held-out posed scans; torso anchors %d, volume restored %d, anchor weight 1e%d\n",
                 cases.size(), static_cast<int>(state.range(0)), static_cast<int>(state.range(1)),
                 static_cast<int>(state.range(2)));
    line("volume ratio round trip", round);
    line("volume ratio labels only", labels);
    line("volume ratio labels + tips", tips);
    line("volume ratio truth", truthv);
    line("volume ratio lbs", lbsv);
    line("error vs truth (mm)", err);
    line("lbs error vs truth (mm)", err_lbs);
    line("torso offset (mm)", torso_t);
    line("torso turn (deg)", torso_deg);
    line("torso distance before (mm)", torso_before);
    line("torso distance after (mm)", torso_after);
    state.counters["mean_error_mm"] = err.mean();
    state.counters["worst_volume_change"] = std::max(std::abs(1 - tips.min()), std::abs(tips.max() - 1));
    state.counters["torso_offset_mm"] = torso_t.mean();
  }
}
// Args: torso anchors on/off, volume kept on/off, log10 of the torso anchors' weight (measured
// with the volume restored exactly: 1e2 and 1e3 9.0 mm mean error, 1e4 8.8).
BENCHMARK(BM_PoseMorphStages)->Args({0, 0, 4})->Args({1, 0, 4})->Args({1, 1, 4})->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace
}  // namespace bodymodel
BENCHMARK_MAIN();
