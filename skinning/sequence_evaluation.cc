#include "skinning/sequence_evaluation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <functional>
#include <limits>
#include <set>

#include <sys/resource.h>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/geometry.h"

namespace bodymodel {

double process_cpu_seconds() {
  rusage u;
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

std::vector<int> evenly_spaced_frames(int frame_count, int count) {
  if (frame_count < 1 || count < 1) throw InputError("evenly spaced frames: counts must be positive");
  count = std::min(count, frame_count);
  std::vector<int> out;
  for (int i = 0; i < count; ++i)
    out.push_back(count == 1 ? 0 : static_cast<int>(std::lround(double(i) * (frame_count - 1) / (count - 1))));
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

namespace {
BoneTransforms fit_frame_transforms(const SkinningRig& lbs, const Eigen::MatrixX3d& Q, const BoneTransforms& initial,
                                    int iterations, const FixedWeightMoments& moments,
                                    const SequenceEvaluationOptions& options) {
  return options.baseline_fit ? fit_transforms_with_fixed_weights_per_vertex(lbs, Q, initial, iterations)
                                          : fit_transforms_with_fixed_weights(lbs, Q, initial, iterations, &moments);
}

// Bones (recovered from the training frames when `given` is empty), SSD and its alternation on the
// training frames, then every other frame's bone maps. `rest` is the rig's rest shape and Frest its
// faces (bone recovery); it need not be one of the frames (full nesting's folds, where the rest
// frame may be held out). Inputs are checked by the callers.
PreparedSequence prepare_core(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3i& Frest,
                              const std::vector<Eigen::MatrixX3d>& frames, const std::vector<int>& train,
                              const SequenceEvaluationOptions& options, const std::vector<BoneTransforms>& given,
                              const ProgressCallback& progress) {
  const int nf = static_cast<int>(frames.size());
  const auto t0 = std::chrono::steady_clock::now();
  const double c0 = process_cpu_seconds();
  PreparedSequence out;
  SkinningExamples& ex = out.examples;
  ex.rest = rest;
  for (int t : train) ex.poses.push_back(frames[static_cast<size_t>(t)]);
  if (given.empty()) {
    ProgressCallback sub = progress ? ProgressCallback([&](double f, std::string_view w) {
      return progress(0.5 * f, w);
    }) : ProgressCallback();
    out.recovered = recover_bones(rest, Frest, ex.poses, options.recovery, &out.recovery, sub);
    ex.transforms = out.recovered.transforms;
    out.recovery_cpu_seconds = process_cpu_seconds() - c0;
  } else {
    for (int t : train) ex.transforms.push_back(given[static_cast<size_t>(t)]);
  }
  report_progress(progress, 0.5, "SSD weights");
  LbsFitOptions lo = options.lbs;
  lo.max_influences = options.max_influences;
  lo.require_rigid = given.empty() ? true : lo.require_rigid;
  out.lbs = fit_lbs(ex, {}, lo, &out.lbs_summary);
  out.alternation_rms.push_back(out.lbs_summary.rms_residual);
  if (given.empty()) {
    for (int a = 0; a < options.alternations; ++a) {
      const FixedWeightMoments moments = fixed_weight_moments(out.lbs);   // shared by every frame of the round
      tbb::parallel_for(0, static_cast<int>(train.size()), [&](int p) {
        ex.transforms[static_cast<size_t>(p)] = fit_frame_transforms(
            out.lbs, ex.poses[static_cast<size_t>(p)], ex.transforms[static_cast<size_t>(p)],
            options.alternation_transform_iterations > 0 ? options.alternation_transform_iterations
                                                         : options.transform_iterations, moments, options);
      });
      // Influence sets are chosen afresh every round: keeping the first round's costs 20 % of
      // unseen E_RMS on the horse (bones that take over vertices late must be able to).
      out.lbs = fit_lbs(ex, {}, lo, &out.lbs_summary);
      const double before = out.alternation_rms.back(), after = out.lbs_summary.rms_residual;
      out.alternation_rms.push_back(after);
      if (before - after < options.alternation_tolerance * before) break;
    }
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.cpu_seconds = process_cpu_seconds() - c0;
  const auto t1 = std::chrono::steady_clock::now();
  // Transforms of every frame: training frames keep theirs; unseen frames are fitted with the SSD
  // weights held fixed (or taken from `given`).
  out.transforms.assign(static_cast<size_t>(nf), {});
  out.is_train.assign(static_cast<size_t>(nf), false);
  for (size_t p = 0; p < train.size(); ++p) {
    out.transforms[static_cast<size_t>(train[p])] = ex.transforms[p];
    out.is_train[static_cast<size_t>(train[p])] = true;
  }
  report_progress(progress, 0.8, "unseen-frame transforms");
  const FixedWeightMoments moments = given.empty() ? fixed_weight_moments(out.lbs) : FixedWeightMoments{};
  tbb::parallel_for(0, nf, [&](int f) {
    if (out.is_train[static_cast<size_t>(f)]) return;
    if (!given.empty()) {
      out.transforms[static_cast<size_t>(f)] = given[static_cast<size_t>(f)];
      return;
    }
    const Eigen::MatrixX3d& Q = frames[static_cast<size_t>(f)];
    // Two starts, the better fit kept: the recovered sections' own rigid maps, and the bone maps of
    // the nearest training frame (smallest Σ‖q_i − q'_i‖², the frames' vertices correspond).
    const BoneTransforms a = fit_frame_transforms(
        out.lbs, Q, fit_section_transforms(rest, out.recovered.vertex_bone, ex.bone_count(), Q),
        options.transform_iterations, moments, options);
    size_t nearest = 0;
    double best = std::numeric_limits<double>::infinity();
    for (size_t p = 0; p < train.size(); ++p) {
      const double d = (ex.poses[p] - Q).squaredNorm();
      if (d < best) best = d, nearest = p;
    }
    const BoneTransforms b =
        fit_frame_transforms(out.lbs, Q, ex.transforms[nearest], options.transform_iterations, moments, options);
    const double ea = (evaluate_rig(out.lbs, a) - Q).squaredNorm(), eb = (evaluate_rig(out.lbs, b) - Q).squaredNorm();
    out.transforms[static_cast<size_t>(f)] = ea <= eb ? a : b;
  });
  out.unseen_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  out.unseen_cpu_seconds = process_cpu_seconds() - c0 - out.cpu_seconds;
  report_progress(progress, 1.0, "prepared");
  return out;
}

}  // namespace

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
  if (!options.frame_faces.empty()) {
    if (static_cast<int>(options.frame_faces.size()) != nf)
      throw InputError("skinning evaluation: " + std::to_string(options.frame_faces.size()) + " face lists for " +
                       std::to_string(nf) + " frames");
    for (int f = 0; f < nf; ++f) {
      const Eigen::MatrixX3i& Ff = options.frame_faces[static_cast<size_t>(f)];
      if (Ff.rows() == 0 || Ff.minCoeff() < 0 || Ff.maxCoeff() >= frames[0].rows())
        throw InputError("skinning evaluation: frame " + std::to_string(f) + " has no faces or a face index outside 0.." +
                         std::to_string(frames[0].rows() - 1));
    }
  }
  if (!given.empty() && static_cast<int>(given.size()) != nf)
    throw InputError("skinning evaluation: " + std::to_string(given.size()) + " transform sets for " +
                     std::to_string(nf) + " frames");
  if (given.empty() && !train_set.count(options.rest_frame))
    throw InputError("skinning evaluation: the rest frame (" + std::to_string(options.rest_frame) +
                     ") must be a training frame: its geometry becomes the rig's rest shape");
  const std::vector<int> train(train_set.begin(), train_set.end());
  const Eigen::MatrixX3i& Frest =
      options.frame_faces.empty() ? F : options.frame_faces[static_cast<size_t>(options.rest_frame)];
  return prepare_core(frames[static_cast<size_t>(options.rest_frame)], Frest, frames, train, options, given, progress);
}

FoldBones fit_fold_bones(const SkinningExamples& ex, const Eigen::MatrixX3i& Frest, const std::vector<int>& train,
                         const std::vector<int>& held_out, const SequenceEvaluationOptions& options) {
  std::vector<int> all(train);
  all.insert(all.end(), held_out.begin(), held_out.end());
  std::sort(all.begin(), all.end());
  if (train.empty() || std::adjacent_find(all.begin(), all.end()) != all.end() || all.front() < 0 ||
      all.back() >= ex.pose_count())
    throw InputError("fold bones: the training and held-out examples must be disjoint, non-empty on the training side "
                     "and within 0.." + std::to_string(ex.pose_count() - 1));
  // Only the fold's examples: the held-out poses reach the fit only as frames to fit bone maps to
  // after the weights are fixed.
  std::vector<Eigen::MatrixX3d> frames;
  for (int p : train) frames.push_back(ex.poses[static_cast<size_t>(p)]);
  for (int p : held_out) frames.push_back(ex.poses[static_cast<size_t>(p)]);
  std::vector<int> fold_train(train.size());
  for (size_t k = 0; k < train.size(); ++k) fold_train[k] = static_cast<int>(k);
  PreparedSequence prep = prepare_core(ex.rest, Frest, frames, fold_train, options, {}, {});
  FoldBones out;
  out.train = std::move(prep.examples);
  out.lbs = std::move(prep.lbs);
  for (size_t k = 0; k < held_out.size(); ++k) out.held_out.push_back(prep.transforms[train.size() + k]);
  return out;
}

namespace {
RigFrameStats evaluate_on_frames(const std::function<Eigen::MatrixX3d(const BoneTransforms&)>& pose,
                                 const PreparedSequence& prep, const std::vector<Eigen::MatrixX3d>& frames,
                                 const Eigen::MatrixX3i& F, const std::vector<const ReferenceSurface*>& surfaces,
                                 const std::vector<Eigen::MatrixX3i>& frame_faces,
                                 const std::function<void(int, const Eigen::MatrixX3d&)>& on_posed = {}) {
  const int nf = static_cast<int>(frames.size());
  if (prep.transforms.size() != frames.size())
    throw InputError("evaluate_rig_on_frames: prepared for " + std::to_string(prep.transforms.size()) +
                     " frames, given " + std::to_string(nf));
  RigFrameStats out;
  out.frame_mean_geometric.assign(static_cast<size_t>(nf), 0.0);
  out.mean_unseen_geometric = Eigen::VectorXd::Zero(frames[0].rows());
  for (int f = 0; f < nf; ++f) {
    std::unique_ptr<ReferenceSurface> own;
    const Eigen::MatrixX3i& Ff = frame_faces.empty() ? F : frame_faces[static_cast<size_t>(f)];
    const ReferenceSurface* s = surfaces.empty() ? nullptr : surfaces[static_cast<size_t>(f)];
    if (!s) {
      own = std::make_unique<ReferenceSurface>(frames[static_cast<size_t>(f)], Ff);
      s = own.get();
    }
    const Eigen::MatrixX3d X = pose(prep.transforms[static_cast<size_t>(f)]);
    if (on_posed) on_posed(f, X);
    const MeshDeviation d = mesh_deviation(X, frames[static_cast<size_t>(f)], Ff, s);
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
}  // namespace

RigFrameStats evaluate_rig_on_frames(const SkinningRig& rig, const PreparedSequence& prep,
                                     const std::vector<Eigen::MatrixX3d>& frames, const Eigen::MatrixX3i& F,
                                     const std::vector<const ReferenceSurface*>& surfaces,
                                     const std::vector<Eigen::MatrixX3i>& frame_faces) {
  return evaluate_on_frames([&](const BoneTransforms& M) { return evaluate_rig(rig, M); }, prep, frames, F, surfaces,
                            frame_faces);
}

RigFrameStats evaluate_model_on_frames(const FittedModel& model, const PreparedSequence& prep,
                                       const std::vector<Eigen::MatrixX3d>& frames, const Eigen::MatrixX3i& F,
                                       const std::vector<const ReferenceSurface*>& surfaces,
                                       const std::vector<Eigen::MatrixX3i>& frame_faces,
                                       const std::function<void(int, const Eigen::MatrixX3d&)>& on_posed) {
  return evaluate_on_frames([&](const BoneTransforms& M) { return model.pose(M); }, prep, frames, F, surfaces,
                            frame_faces, on_posed);
}

FittedModel fit_sequence_method(SkinningModel method, const PreparedSequence& prep,
                                const SequenceEvaluationOptions& options, const CrossValidator* validator,
                                MethodFit* fit, const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  const double c0 = process_cpu_seconds();
  MethodFit local;
  MethodFit& mf = fit ? *fit : local;
  mf.method = method;
  ModelFitOptions o = options.fit;
  if (validator && options.cv.scheme != CvScheme::none) {
    ProgressCallback sub = progress ? ProgressCallback([&](double f, std::string_view w) {
      return progress(0.8 * f, w);
    }) : ProgressCallback();
    mf.cv = validator->select(method, o, sub);
    o = mf.cv.chosen;
  }
  const FittedModel m = fit_model(method, prep.examples, prep.lbs, o, &mf.brief);
  mf.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  mf.cpu_seconds = process_cpu_seconds() - c0;
  return m;
}

void check_evaluation_request(int nf, const std::vector<int>& train_in, const SequenceEvaluationOptions& options,
                              bool bones_recovered) {
  if (options.methods.empty()) throw InputError("skinning evaluation: no method given");
  const std::set<int> train(train_in.begin(), train_in.end());
  if (train.empty()) throw InputError("skinning evaluation: no training frames");
  for (int t : train)
    if (t < 0 || t >= nf)
      throw InputError("skinning evaluation: training frame " + std::to_string(t) + " outside 0.." + std::to_string(nf - 1));
  if (bones_recovered && !train.count(options.rest_frame))
    throw InputError("skinning evaluation: the rest frame (" + std::to_string(options.rest_frame) +
                     ") must be a training frame: its geometry becomes the rig's rest shape");
  const int count = static_cast<int>(train.size());
  const std::vector<std::vector<int>> folds = cv_folds(count >= 2 ? count : 2, options.cv);
  for (SkinningModel m : options.methods) {
    if (count < minimum_examples(m))
      throw InputError("skinning evaluation: " + skinning_model_name(m) + " needs at least " +
                       std::to_string(minimum_examples(m)) + " training frames, " + std::to_string(count) + " given");
    if (m == SkinningModel::ssd || m == SkinningModel::dqs) continue;
    for (const auto& held : folds)
      if (count - static_cast<int>(held.size()) < minimum_examples(m))
        throw InputError("cross-validation of " + skinning_model_name(m) + ": a fold leaves " +
                         std::to_string(count - static_cast<int>(held.size())) + " training example(s), the method needs " +
                         std::to_string(minimum_examples(m)) + " (use fewer folds or more training frames)");
  }
}

SequenceEvaluation evaluate_skinning_sequence(const std::vector<Eigen::MatrixX3d>& frames,
                                              const Eigen::MatrixX3i& F, const std::vector<int>& train,
                                              const SequenceEvaluationOptions& options,
                                              const std::vector<BoneTransforms>& given,
                                              const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  check_evaluation_request(static_cast<int>(frames.size()), train, options, given.empty());
  ProgressCallback sub = progress ? ProgressCallback([&](double f, std::string_view w) {
    return progress(0.3 * f, w);
  }) : ProgressCallback();
  const PreparedSequence prep = prepare_skinning_sequence(frames, F, train, options, given, sub);
  for (SkinningModel m : options.methods)
    if (prep.examples.pose_count() < minimum_examples(m))
      throw InputError("skinning evaluation: " + skinning_model_name(m) + " needs at least " +
                       std::to_string(minimum_examples(m)) + " training frames, " +
                       std::to_string(prep.examples.pose_count()) + " given");
  SequenceEvaluation out;
  out.train_frames.clear();
  for (size_t f = 0; f < frames.size(); ++f)
    if (prep.is_train[f]) out.train_frames.push_back(static_cast<int>(f));
  out.diagonal = bounding_box_diagonal(frames[0]);
  out.recovery = prep.recovery;
  out.lbs_summary = prep.lbs_summary;
  out.alternation_rms = prep.alternation_rms;
  out.prepare_seconds = prep.seconds;
  out.prepare_cpu_seconds = prep.cpu_seconds;
  out.recovery_cpu_seconds = prep.recovery_cpu_seconds;
  out.unseen_cpu_seconds = prep.unseen_cpu_seconds;
  std::vector<std::unique_ptr<ReferenceSurface>> trees;
  std::vector<const ReferenceSurface*> surfaces, train_surfaces;
  for (size_t f = 0; f < frames.size(); ++f) {
    trees.push_back(std::make_unique<ReferenceSurface>(frames[f], options.frame_faces.empty() ? F : options.frame_faces[f]));
    surfaces.push_back(trees.back().get());
    if (prep.is_train[f]) train_surfaces.push_back(trees.back().get());
  }
  std::unique_ptr<CrossValidator> validator;
  if (options.cv.scheme != CvScheme::none) {
    const double c0 = process_cpu_seconds();
    SkinCrossValidationOptions cv = options.cv;
    // Given bone maps are not fitted to anything: there is nothing to refit per fold.
    if (!given.empty()) cv.nesting = CvNesting::weights;
    const Eigen::MatrixX3i& Frest =
        options.frame_faces.empty() ? F : options.frame_faces[static_cast<size_t>(options.rest_frame)];
    FoldBoneFitter fold_bones;
    if (cv.nesting == CvNesting::full)
      fold_bones = [&](const std::vector<int>& t, const std::vector<int>& h) {
        return fit_fold_bones(prep.examples, Frest, t, h, options);
      };
    ProgressCallback csub = progress ? ProgressCallback([&](double f, std::string_view w) {
      return progress(0.3 + 0.1 * f, w);
    }) : ProgressCallback();
    validator = std::make_unique<CrossValidator>(prep.examples, [&] {
      LbsFitOptions lo = options.lbs;
      lo.max_influences = options.max_influences;
      lo.require_rigid = false;
      return lo;
    }(), cv, train_surfaces, fold_bones, csub);
    out.cv_setup_cpu_seconds = process_cpu_seconds() - c0;
  }
  SequenceEvaluationOptions opt = options;
  // MWE over an Animation Space base uses the AS ridge chosen for AS, EigenSkin and the quadratic
  // method PSD's pose space (kernel width, RBF ridge): fit AS and PSD first, or cross-validate
  // them for the others when they are not evaluated themselves.
  std::vector<SkinningModel> order = options.methods;
  auto rank = [](SkinningModel m) { return m == SkinningModel::as || m == SkinningModel::psd ? 0 : 1; };
  std::stable_sort(order.begin(), order.end(), [&](SkinningModel a, SkinningModel b) { return rank(a) < rank(b); });
  auto has = [&](SkinningModel m) { return std::count(order.begin(), order.end(), m) > 0; };
  if (validator && has(SkinningModel::mwe) && !has(SkinningModel::as) &&
      std::count(options.cv.mwe_bases.begin(), options.cv.mwe_bases.end(), MweBase::animation_space))
    opt.fit.mwe.base_as_ridge = validator->select(SkinningModel::as, opt.fit).chosen.animation_space.ridge;
  if (validator && (has(SkinningModel::eigenskin) || has(SkinningModel::quadratic)) && !has(SkinningModel::psd)) {
    const PoseSpaceOptions chosen = validator->select(SkinningModel::psd, opt.fit).chosen.pose_space;
    opt.fit.pose_space.kernel_width = chosen.kernel_width;
    opt.fit.pose_space.rbf_ridge = chosen.rbf_ridge;
  }
  std::vector<MethodFit> fits(options.methods.size());
  std::vector<RigFrameStats> stats(options.methods.size());
  for (size_t k = 0; k < order.size(); ++k) {
    const SkinningModel method = order[k];
    const size_t m = static_cast<size_t>(std::find(options.methods.begin(), options.methods.end(), method) -
                                         options.methods.begin());
    ProgressCallback msub = progress ? ProgressCallback([&](double f, std::string_view w) {
      return progress(0.4 + 0.6 * (k + f) / order.size(), w);
    }) : ProgressCallback();
    const FittedModel model = fit_sequence_method(method, prep, opt, validator.get(), &fits[m], msub);
    if (method == SkinningModel::as && validator) opt.fit.mwe.base_as_ridge = fits[m].cv.chosen.animation_space.ridge;
    if (method == SkinningModel::psd && validator) {
      opt.fit.pose_space.kernel_width = fits[m].cv.chosen.pose_space.kernel_width;
      opt.fit.pose_space.rbf_ridge = fits[m].cv.chosen.pose_space.rbf_ridge;
    }
    report_progress(msub, 0.9, "evaluating " + skinning_model_name(method));
    std::function<void(int, const Eigen::MatrixX3d&)> sink;
    if (options.on_posed) sink = [&](int f, const Eigen::MatrixX3d& X) { options.on_posed(method, f, X); };
    stats[m] = evaluate_model_on_frames(model, prep, frames, F, surfaces, options.frame_faces, sink);
  }
  for (size_t m = 0; m < options.methods.size(); ++m) {
    out.rows.push_back({options.methods[m], "train", stats[m].train});
    if (stats[m].unseen.frames) out.rows.push_back({options.methods[m], "unseen", stats[m].unseen});
    out.mean_unseen_geometric.push_back(stats[m].mean_unseen_geometric);
    out.frame_mean_geometric.push_back(stats[m].frame_mean_geometric);
  }
  out.fits = std::move(fits);
  report_progress(progress, 1.0, "done");
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace bodymodel
