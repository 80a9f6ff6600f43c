#include "skinning/sequence_evaluation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
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

PreparedSequence prepare_skinning_sequence(const std::vector<Eigen::MatrixX3d>& frames,
                                           const Eigen::MatrixX3i& F, const std::vector<int>& train_in,
                                           const SequenceEvaluationOptions& options,
                                           const std::vector<BoneTransforms>& given,
                                           const ProgressCallback& progress) {
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
  PreparedSequence out;
  SkinningExamples& ex = out.examples;
  ex.rest = rest;
  for (int t : train) ex.poses.push_back(frames[static_cast<size_t>(t)]);
  if (given.empty()) {
    ProgressCallback sub = progress ? ProgressCallback([&](double f, std::string_view w) {
      return progress(0.5 * f, w);
    }) : ProgressCallback();
    out.recovered = recover_bones(rest, F, ex.poses, options.recovery, &out.recovery, sub);
    ex.transforms = out.recovered.transforms;
  } else {
    for (int t : train) ex.transforms.push_back(given[static_cast<size_t>(t)]);
  }
  report_progress(progress, 0.5, "SSD weights");
  LbsFitOptions lo = options.lbs;
  lo.max_influences = options.max_influences;
  lo.require_rigid = given.empty() ? true : lo.require_rigid;
  out.lbs = fit_lbs(ex, {}, lo, &out.lbs_summary);
  if (given.empty()) {
    for (int a = 0; a < options.alternations; ++a) {
      tbb::parallel_for(0, static_cast<int>(train.size()), [&](int p) {
        ex.transforms[static_cast<size_t>(p)] = fit_transforms_with_fixed_weights(
            out.lbs, ex.poses[static_cast<size_t>(p)], ex.transforms[static_cast<size_t>(p)],
            options.transform_iterations);
      });
      out.lbs = fit_lbs(ex, {}, lo, &out.lbs_summary);
    }
  }
  // Transforms of every frame: training frames keep theirs; unseen frames are fitted with the SSD
  // weights held fixed (or taken from `given`).
  out.transforms.assign(static_cast<size_t>(nf), {});
  out.is_train.assign(static_cast<size_t>(nf), false);
  for (size_t p = 0; p < train.size(); ++p) {
    out.transforms[static_cast<size_t>(train[p])] = ex.transforms[p];
    out.is_train[static_cast<size_t>(train[p])] = true;
  }
  report_progress(progress, 0.8, "unseen-frame transforms");
  tbb::parallel_for(0, nf, [&](int f) {
    if (out.is_train[static_cast<size_t>(f)]) return;
    if (!given.empty()) {
      out.transforms[static_cast<size_t>(f)] = given[static_cast<size_t>(f)];
      return;
    }
    const BoneTransforms init = fit_section_transforms(rest, out.recovered.vertex_bone, ex.bone_count(),
                                                       frames[static_cast<size_t>(f)]);
    out.transforms[static_cast<size_t>(f)] = fit_transforms_with_fixed_weights(
        out.lbs, frames[static_cast<size_t>(f)], init, options.transform_iterations);
  });
  report_progress(progress, 1.0, "prepared");
  return out;
}

RigFrameStats evaluate_rig_on_frames(const SkinningRig& rig, const PreparedSequence& prep,
                                     const std::vector<Eigen::MatrixX3d>& frames, const Eigen::MatrixX3i& F,
                                     const std::vector<const ReferenceSurface*>& surfaces) {
  const int nf = static_cast<int>(frames.size());
  if (prep.transforms.size() != frames.size())
    throw InputError("evaluate_rig_on_frames: prepared for " + std::to_string(prep.transforms.size()) +
                     " frames, given " + std::to_string(nf));
  RigFrameStats out;
  out.frame_mean_geometric.assign(static_cast<size_t>(nf), 0.0);
  out.mean_unseen_geometric = Eigen::VectorXd::Zero(frames[0].rows());
  for (int f = 0; f < nf; ++f) {
    std::unique_ptr<ReferenceSurface> own;
    const ReferenceSurface* s = surfaces.empty() ? nullptr : surfaces[static_cast<size_t>(f)];
    if (!s) {
      own = std::make_unique<ReferenceSurface>(frames[static_cast<size_t>(f)], F);
      s = own.get();
    }
    const Eigen::MatrixX3d X = evaluate_rig(rig, prep.transforms[static_cast<size_t>(f)]);
    const MeshDeviation d = mesh_deviation(X, frames[static_cast<size_t>(f)], F, s);
    out.frame_mean_geometric[static_cast<size_t>(f)] = d.geometric.mean();
    if (prep.is_train[static_cast<size_t>(f)]) {
      out.train.add(d);
    } else {
      out.unseen.add(d);
      out.mean_unseen_geometric += d.geometric;
    }
  }
  if (out.unseen.frames) out.mean_unseen_geometric /= double(out.unseen.frames);
  return out;
}

SequenceEvaluation evaluate_skinning_sequence(const std::vector<Eigen::MatrixX3d>& frames,
                                              const Eigen::MatrixX3i& F, const std::vector<int>& train,
                                              const SequenceEvaluationOptions& options,
                                              const std::vector<BoneTransforms>& given,
                                              const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  ProgressCallback sub = progress ? ProgressCallback([&](double f, std::string_view w) {
    return progress(0.5 * f, w);
  }) : ProgressCallback();
  const PreparedSequence prep = prepare_skinning_sequence(frames, F, train, options, given, sub);
  SequenceEvaluation out;
  out.train_frames.clear();
  for (size_t f = 0; f < frames.size(); ++f)
    if (prep.is_train[f]) out.train_frames.push_back(static_cast<int>(f));
  out.diagonal = bounding_box_diagonal(frames[0]);
  out.recovery = prep.recovery;
  out.lbs_summary = prep.lbs_summary;
  std::vector<std::unique_ptr<ReferenceSurface>> trees;
  std::vector<const ReferenceSurface*> surfaces;
  for (const auto& fr : frames) {
    trees.push_back(std::make_unique<ReferenceSurface>(fr, F));
    surfaces.push_back(trees.back().get());
  }
  for (size_t m = 0; m < options.methods.size(); ++m) {
    const SkinningMethod method = options.methods[m];
    report_progress(progress, 0.5 + 0.5 * m / options.methods.size(), "fitting and evaluating " +
                    skinning_method_name(method));
    SkinningRig rig;
    switch (method) {
      case SkinningMethod::lbs: rig = prep.lbs; break;
      case SkinningMethod::animation_space:
        rig = fit_animation_space(prep.examples, &prep.lbs, options.animation_space, &out.as_summary);
        break;
      case SkinningMethod::mwe:
        rig = fit_mwe(prep.examples, &prep.lbs, options.mwe, &out.mwe_summary);
        break;
    }
    const RigFrameStats st = evaluate_rig_on_frames(rig, prep, frames, F, surfaces);
    out.rows.push_back({method, "train", st.train});
    if (st.unseen.frames) out.rows.push_back({method, "unseen", st.unseen});
    out.mean_unseen_geometric.push_back(st.mean_unseen_geometric);
    out.frame_mean_geometric.push_back(st.frame_mean_geometric);
  }
  report_progress(progress, 1.0, "done");
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace bodymodel
