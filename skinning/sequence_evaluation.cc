#include "skinning/sequence_evaluation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>

#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/geometry.h"

namespace bodymodel {

std::vector<int> evenly_spaced_frames(int frame_count, int count) {
  if (frame_count < 1 || count < 1) throw InputError("evenly spaced frames: counts must be positive");
  count = std::min(count, frame_count);
  std::vector<int> out;
  for (int i = 0; i < count; ++i)
    out.push_back(count == 1 ? 0 : static_cast<int>(std::lround(double(i) * (frame_count - 1) / (count - 1))));
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

SequenceEvaluation evaluate_skinning_sequence(const std::vector<Eigen::MatrixX3d>& frames,
                                              const Eigen::MatrixX3i& F, const std::vector<int>& train_in,
                                              const SequenceEvaluationOptions& options,
                                              const std::vector<BoneTransforms>& given,
                                              const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  const int nf = static_cast<int>(frames.size());
  if (nf < 1) throw InputError("skinning evaluation: no frames");
  std::set<int> train_set(train_in.begin(), train_in.end());
  if (train_set.empty()) throw InputError("skinning evaluation: no training frames");
  for (int t : train_set)
    if (t < 0 || t >= nf)
      throw InputError("skinning evaluation: training frame " + std::to_string(t) + " outside 0.." +
                       std::to_string(nf - 1));
  if (options.rest_frame < 0 || options.rest_frame >= nf)
    throw InputError("skinning evaluation: rest frame " + std::to_string(options.rest_frame) + " outside 0.." +
                     std::to_string(nf - 1));
  for (int f = 0; f < nf; ++f)
    if (frames[static_cast<size_t>(f)].rows() != frames[0].rows())
      throw InputError("skinning evaluation: frame " + std::to_string(f) + " has " +
                       std::to_string(frames[static_cast<size_t>(f)].rows()) + " vertices, frame 0 has " +
                       std::to_string(frames[0].rows()));
  if (!given.empty() && static_cast<int>(given.size()) != nf)
    throw InputError("skinning evaluation: " + std::to_string(given.size()) + " transform sets for " +
                     std::to_string(nf) + " frames");
  const std::vector<int> train(train_set.begin(), train_set.end());
  const Eigen::MatrixX3d& rest = frames[static_cast<size_t>(options.rest_frame)];
  SequenceEvaluation out;
  out.train_frames = train;
  out.diagonal = bounding_box_diagonal(frames[0]);

  SkinningExamples ex;
  ex.rest = rest;
  for (int t : train) ex.poses.push_back(frames[static_cast<size_t>(t)]);
  RecoveredBones rec;
  if (given.empty()) {
    ProgressCallback sub = progress ? ProgressCallback([&](double f, std::string_view w) {
      return progress(0.3 * f, w);
    }) : ProgressCallback();
    rec = recover_bones(rest, F, ex.poses, options.recovery, &out.recovery, sub);
    ex.transforms = rec.transforms;
  } else {
    for (int t : train) ex.transforms.push_back(given[static_cast<size_t>(t)]);
  }
  report_progress(progress, 0.3, "SSD weights");
  LbsFitOptions lo = options.lbs;
  lo.max_influences = options.max_influences;
  lo.require_rigid = given.empty() ? true : lo.require_rigid;
  SkinningRig lbs = fit_lbs(ex, {}, lo, &out.lbs_summary);
  if (given.empty()) {
    for (int a = 0; a < options.alternations; ++a) {
      tbb::parallel_for(0, static_cast<int>(train.size()), [&](int p) {
        ex.transforms[static_cast<size_t>(p)] = fit_transforms_with_fixed_weights(
            lbs, ex.poses[static_cast<size_t>(p)], ex.transforms[static_cast<size_t>(p)],
            options.transform_iterations);
      });
      lbs = fit_lbs(ex, {}, lo, &out.lbs_summary);
    }
  }
  // Transforms of every frame: training frames keep theirs; unseen frames are fitted with the SSD
  // weights held fixed (or taken from `given`).
  std::vector<BoneTransforms> T(static_cast<size_t>(nf));
  for (size_t p = 0; p < train.size(); ++p) T[static_cast<size_t>(train[p])] = ex.transforms[p];
  report_progress(progress, 0.45, "unseen-frame transforms");
  tbb::parallel_for(0, nf, [&](int f) {
    if (train_set.count(f)) return;
    if (!given.empty()) {
      T[static_cast<size_t>(f)] = given[static_cast<size_t>(f)];
      return;
    }
    const BoneTransforms init = fit_section_transforms(rest, rec.vertex_bone, ex.bone_count(),
                                                       frames[static_cast<size_t>(f)]);
    T[static_cast<size_t>(f)] = fit_transforms_with_fixed_weights(lbs, frames[static_cast<size_t>(f)], init,
                                                                  options.transform_iterations);
  });
  // Rigs.
  std::vector<SkinningRig> rigs;
  for (SkinningMethod m : options.methods) {
    report_progress(progress, 0.55, "fitting " + skinning_method_name(m));
    switch (m) {
      case SkinningMethod::lbs: rigs.push_back(lbs); break;
      case SkinningMethod::animation_space:
        rigs.push_back(fit_animation_space(ex, &lbs, options.animation_space, &out.as_summary));
        break;
      case SkinningMethod::mwe:
        rigs.push_back(fit_mwe(ex, &lbs, options.mwe, &out.mwe_summary));
        break;
    }
  }
  // Evaluation.
  const size_t nm = rigs.size();
  std::vector<DeviationStats> train_stats(nm), unseen_stats(nm);
  out.mean_unseen_geometric.assign(nm, Eigen::VectorXd::Zero(rest.rows()));
  out.frame_mean_geometric.assign(nm, std::vector<double>(static_cast<size_t>(nf), 0.0));
  int unseen_count = 0;
  for (int f = 0; f < nf; ++f) {
    report_progress(progress, 0.65 + 0.35 * f / nf, "evaluating frames");
    const ReferenceSurface surface(frames[static_cast<size_t>(f)], F);
    const bool is_train = train_set.count(f) > 0;
    if (!is_train) ++unseen_count;
    for (size_t m = 0; m < nm; ++m) {
      const Eigen::MatrixX3d X = evaluate_rig(rigs[m], T[static_cast<size_t>(f)]);
      const MeshDeviation d = mesh_deviation(X, frames[static_cast<size_t>(f)], F, &surface);
      (is_train ? train_stats[m] : unseen_stats[m]).add(d);
      out.frame_mean_geometric[m][static_cast<size_t>(f)] = d.geometric.mean();
      if (!is_train) out.mean_unseen_geometric[m] += d.geometric;
    }
  }
  for (size_t m = 0; m < nm; ++m) {
    if (unseen_count) out.mean_unseen_geometric[m] /= unseen_count;
    out.rows.push_back({options.methods[m], "train", train_stats[m]});
    if (unseen_count) out.rows.push_back({options.methods[m], "unseen", unseen_stats[m]});
  }
  report_progress(progress, 1.0, "done");
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace bodymodel
