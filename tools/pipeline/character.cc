#include "tools/pipeline/character.h"

#include <fmt/format.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <random>

#include "core/error.h"
#include "core/geometry.h"
#include "core/io/bvh.h"
#include "core/retarget.h"
#include "encoding/relative_rotation_decoder.h"
#include "tools/pipeline/deformation_check.h"

namespace bodymodel {

namespace fs = std::filesystem;

namespace {

Pose slerp_pose(const Pose& a, const Pose& b, double t) {
  Pose p = a;
  for (size_t i = 0; i < a.rotations.size(); ++i) {
    Eigen::Quaterniond qa(a.rotations[i]), qb(b.rotations[i]);
    p.rotations[i] = qa.slerp(t, qb).toRotationMatrix();
  }
  p.root_translation = (1 - t) * a.root_translation + t * b.root_translation;
  return p;
}

}  // namespace

std::vector<char> driven_bones(const BodyModel& model, const Skeleton& skeleton) {
  std::vector<char> d(skeleton.bone_count(), 0);
  for (int b = 0; b < skeleton.bone_count(); ++b)
    if (skeleton.parents[b] < 0) d[b] = 1;
  for (const auto& l : model.full.regression.labels) {
    if (l.name.rfind("pose:", 0) != 0) continue;
    const auto colon = l.name.rfind(':');
    const int b = skeleton.find(l.name.substr(5, colon - 5));
    if (b >= 0) d[b] = 1;
  }
  return d;
}

Pose restrict_pose(const Pose& pose, const std::vector<char>& driven) {
  Pose p = pose;
  for (size_t b = 0; b < p.rotations.size() && b < driven.size(); ++b)
    if (!driven[b]) p.rotations[b].setIdentity();
  return p;
}

Eigen::MatrixXd merge_undriven_weights(const Eigen::MatrixXd& W, const Skeleton& skeleton,
                                       const std::vector<char>& driven) {
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(W.rows(), W.cols());
  for (int b = 0; b < skeleton.bone_count(); ++b) {
    int a = b;
    while (a >= 0 && !driven[a]) a = skeleton.parents[a];
    if (a < 0) a = b;
    out.col(a) += W.col(b);
  }
  return out;
}

BoneTransforms relative_to_root(const BoneTransforms& M, const Skeleton& skeleton, Eigen::Affine3d* root) {
  int r = 0;
  for (int b = 0; b < skeleton.bone_count(); ++b)
    if (skeleton.parents[b] < 0) {
      r = b;
      break;
    }
  const Eigen::Affine3d G = M[r];
  const Eigen::Affine3d Gi = G.inverse(Eigen::Isometry);
  BoneTransforms out(M.size());
  for (size_t b = 0; b < M.size(); ++b) out[b] = Gi * M[b];
  if (root) *root = G;
  return out;
}

std::vector<RangeOfMotionPose> range_of_motion(const Skeleton& skeleton, const fs::path& makehuman_dir,
                                               const RangeOfMotionOptions& o) {
  std::vector<RangeOfMotionPose> out;
  out.push_back({"rest", Pose::rest(skeleton.bone_count())});
  // MakeHuman's static poses (the skeleton's own bone names).
  const fs::path poses_dir = makehuman_dir / "motion" / "poses";
  std::vector<fs::path> files;
  std::error_code ec;
  if (fs::is_directory(poses_dir, ec))
    for (auto& e : fs::directory_iterator(poses_dir))
      if (e.path().extension() == ".bvh") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (auto& f : files) {
    const std::string stem = f.stem().string();
    if (std::find(o.excluded_static.begin(), o.excluded_static.end(), stem) != o.excluded_static.end()) continue;
    BvhMotion m = read_bvh(f);
    out.push_back({stem, bvh_frame_to_pose(m, 0, skeleton)});
  }
  // CMU clips, retargeted: the database's frames for training, frames between them held out.
  const fs::path cmu_dir = makehuman_dir / "motion" / "cmu";
  std::vector<fs::path> clips;
  if (fs::is_directory(cmu_dir, ec))
    for (auto& e : fs::directory_iterator(cmu_dir))
      if (e.path().extension() == ".bvh") clips.push_back(e.path());
  std::sort(clips.begin(), clips.end());
  for (auto& c : clips) {
    BvhMotion m = read_bvh(c);
    // The database's retarget (default options), not for_animation: the model has seen these poses.
    Retargeter r(m, skeleton, RetargetMap::for_clip(m, makehuman_dir));
    const int n = m.frame_count();
    std::vector<int> train;
    for (int k = 0; k < o.training_frames_per_clip; ++k) {
      int f = static_cast<int>((k + 0.5) * n / o.training_frames_per_clip);
      train.push_back(f);
      Pose p = r.pose(f);
      p.root_translation.setZero();
      out.push_back({fmt::format("cmu{}-f{}", c.stem().string(), f), p});
    }
    for (int k = 1; k <= o.held_out_frames_per_clip; ++k) {
      int f = static_cast<int>(double(k) * n / (o.held_out_frames_per_clip + 1));
      while (std::find(train.begin(), train.end(), f) != train.end()) ++f;
      if (f >= n) continue;
      Pose p = r.pose(f);
      p.root_translation.setZero();
      out.push_back({fmt::format("cmu{}-f{}", c.stem().string(), f), p, true});
    }
  }
  // In-betweens: pairs of training morphs (not the rest pose), chosen by the seed.
  std::vector<int> train_idx;
  for (int i = 1; i < static_cast<int>(out.size()); ++i)
    if (!out[i].held_out) train_idx.push_back(i);
  std::mt19937_64 rng(o.seed);
  auto add_blends = [&](int count, double t, bool held) {
    for (int k = 0; k < count && train_idx.size() >= 2; ++k) {
      std::uniform_int_distribution<size_t> pick(0, train_idx.size() - 1);
      int a = train_idx[pick(rng)], b = train_idx[pick(rng)];
      while (b == a) b = train_idx[pick(rng)];
      RangeOfMotionPose p{fmt::format("blend:{}+{}@{:.2f}", out[a].name, out[b].name, t),
                          slerp_pose(out[a].pose, out[b].pose, t), held, a, b, t};
      out.push_back(std::move(p));
    }
  };
  add_blends(o.training_blends, 0.5, false);
  add_blends(o.held_out_blends, 0.3, true);
  return out;
}

CharacterExamples make_character_examples(const BodyModel& model, const Eigen::MatrixX3d& V,
                                          const fs::path& makehuman_dir, const CharacterOptions& o,
                                          const ProgressCallback& progress) {
  auto t0 = std::chrono::steady_clock::now();
  if (model.rig.empty())
    throw InputError("the model has no skeleton: rebuild it without --no-rig (a character needs one)");
  model.check_topology(V, model.tmpl->faces(), "body");
  CharacterExamples ex;
  ex.rest = V;
  ex.F = model.tmpl->faces();
  ex.skeleton = model.rig.skeleton_for(V);
  ex.template_weights = model.rig.weights;
  ex.driven = driven_bones(model, ex.skeleton);
  ex.poses = range_of_motion(ex.skeleton, makehuman_dir, o.range_of_motion);
  for (auto& p : ex.poses) p.pose = restrict_pose(p.pose, ex.driven);
  const int P = static_cast<int>(ex.poses.size());
  ex.transforms.resize(P);
  ex.meshes.resize(P);
  for (int p = 0; p < P; ++p) ex.transforms[p] = forward_kinematics(ex.skeleton, ex.poses[p].pose);
  ex.flipped_before.assign(P, 0);
  ex.flipped_after.assign(P, 0);

  // Flip reference: each triangle's rest normal turned by its dominant bone (the smoothed template
  // weights AS and MWE build on, as `animate` checks its frames).
  const Eigen::MatrixXd Wt = merge_undriven_weights(Eigen::MatrixXd(ex.template_weights), ex.skeleton, ex.driven);
  const SkinningRig smooth =
      lbs_rig_from_weights(V, smooth_skin_weights(Wt, ex.F, o.weight_smoothing_steps), o.max_influences);
  const DeformationChecker checker(V, ex.F, smooth);
  const Eigen::MatrixX3d rest_normals = face_normals(V, ex.F);
  auto repair = [&](int p, Eigen::MatrixX3d& X) {
    Eigen::MatrixX3d N(ex.F.rows(), 3);
    for (Eigen::Index f = 0; f < ex.F.rows(); ++f)
      N.row(f) = (ex.transforms[p][checker.dominant_bone_of_face(static_cast<int>(f))].linear() *
                  rest_normals.row(f).transpose()).transpose();
    if (o.repair_folds) {
      // Local shape from the body skinned into the same pose (already bent at the joints; the
      // region's similarity fit places it), folds judged against the bones' rotations.
      const Eigen::MatrixX3d S = o.fold_reference_skinned ? evaluate_rig(smooth, ex.transforms[p]) : V;
      const FoldRepairSummary s = repair_folds_against_normals(X, S, N, ex.F, o.fold_repair);
      ex.flipped_before[p] = s.flipped_before;
      ex.flipped_after[p] = s.flipped_after;
    } else {
      ex.flipped_before[p] = ex.flipped_after[p] = count_flipped_triangles_against_normals(X, N, ex.F);
    }
  };

  // Morphs (every non-blend pose but the rest), in parallel with a decoder per thread.
  std::vector<int> morphs, blends;
  for (int p = 1; p < P; ++p) (ex.poses[p].blend_a >= 0 ? blends : morphs).push_back(p);
  ex.meshes[0] = V;
  std::atomic<int> done{0};
  std::mutex mtx;
  std::atomic<bool> cancelled{false};
  auto tick = [&](const std::string& what) {
    int d = ++done;
    std::lock_guard<std::mutex> lock(mtx);
    if (cancelled) return;
    try {
      report_progress(progress, double(d) / (P - 1), what);
    } catch (const Cancelled&) {
      cancelled = true;
    }
  };
  tbb::enumerable_thread_specific<std::unique_ptr<RelativeRotationDecoder>> decoders;
  auto decoder = [&]() -> RelativeRotationDecoder& {
    auto& d = decoders.local();
    if (!d) d = std::make_unique<RelativeRotationDecoder>(model.tmpl);
    return *d;
  };
  tbb::task_arena arena(o.threads > 0 ? o.threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(size_t(0), morphs.size(), [&](size_t i) {
      if (cancelled) return;
      const int p = morphs[i];
      Eigen::MatrixX3d D = pose_morph(model, decoder(), V, ex.poses[p].pose, o.pose_morph);
      // The morph is defined up to a rigid motion: place it where skinning puts the body.
      Eigen::MatrixX3d target = linear_blend_skinning(V, model.rig.weights, ex.transforms[p]);
      ex.meshes[p] = apply(fit_rigid_motion(D, target), D);
      repair(p, ex.meshes[p]);
      tick(ex.poses[p].name);
    });
    if (cancelled) return;
    // In-betweens: interpolate the two (repaired) morphs' encodings, decode with the pose morph's
    // constraints for the in-between pose (constrain_blends), place the result rigidly where
    // skinning the body with the in-between pose puts it.
    tbb::parallel_for(size_t(0), blends.size(), [&](size_t i) {
      if (cancelled) return;
      const RangeOfMotionPose& rp = ex.poses[blends[i]];
      Eigen::MatrixX3d D =
          o.constrain_blends
              ? blend_pose_morphs(model, decoder(), V, ex.meshes[rp.blend_a], ex.meshes[rp.blend_b], rp.t, rp.pose,
                                  o.pose_morph)
              : decoder().decode(interpolate(model.encode(ex.meshes[rp.blend_a], rp.name),
                                             model.encode(ex.meshes[rp.blend_b], rp.name), rp.t));
      Eigen::MatrixX3d target = linear_blend_skinning(V, model.rig.weights, ex.transforms[blends[i]]);
      ex.meshes[blends[i]] = apply(fit_rigid_motion(D, target), D);
      repair(blends[i], ex.meshes[blends[i]]);
      tick(rp.name);
    });
  });
  if (cancelled) throw Cancelled{};
  // Into the root's frame.
  for (int p = 0; p < P; ++p) {
    Eigen::Affine3d G;
    ex.transforms[p] = relative_to_root(ex.transforms[p], ex.skeleton, &G);
    const Eigen::Affine3d Gi = G.inverse(Eigen::Isometry);
    ex.meshes[p] = ((ex.meshes[p] * Gi.linear().transpose()).rowwise() + Gi.translation().transpose()).eval();
  }
  for (int p = 0; p < P; ++p)
    if (!ex.meshes[p].allFinite())
      throw NumericalError("pose morph '" + ex.poses[p].name + "' produced non-finite vertices");
  ex.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return ex;
}

namespace {

SkinningExamples training_examples(const CharacterExamples& ex) {
  SkinningExamples s;
  s.rest = ex.rest;
  for (size_t p = 0; p < ex.poses.size(); ++p)
    if (!ex.poses[p].held_out) {
      s.transforms.push_back(ex.transforms[p]);
      s.poses.push_back(ex.meshes[p]);
    }
  return s;
}

}  // namespace

namespace {

std::vector<std::vector<int>> vertex_neighbours(int n, const Eigen::MatrixX3i& F) {
  const Eigen::MatrixX2i E = unique_edges(F);
  std::vector<std::vector<int>> nb(n);
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    nb[E(e, 0)].push_back(E(e, 1));
    nb[E(e, 1)].push_back(E(e, 0));
  }
  return nb;
}

}  // namespace

Eigen::MatrixXd smooth_skin_weights(const Eigen::MatrixXd& W, const Eigen::MatrixX3i& F, int steps) {
  if (steps <= 0) return W;
  const int n = static_cast<int>(W.rows());
  const auto nb = vertex_neighbours(n, F);
  Eigen::MatrixXd A = W, B(W.rows(), W.cols());
  for (int s = 0; s < steps; ++s) {
    tbb::parallel_for(0, n, [&](int v) {
      if (nb[v].empty()) {
        B.row(v) = A.row(v);
        return;
      }
      Eigen::RowVectorXd m = Eigen::RowVectorXd::Zero(A.cols());
      for (int u : nb[v]) m += A.row(u);
      B.row(v) = 0.5 * A.row(v) + (0.5 / nb[v].size()) * m;
    });
    std::swap(A, B);
  }
  return A;
}

void smooth_mwe_refinement(SkinningRig& mwe, const SkinningRig& base, const Eigen::MatrixX3i& F, int steps,
                           const Eigen::VectorXd* keep) {
  if (mwe.method != SkinningMethod::mwe || base.method != SkinningMethod::lbs ||
      mwe.vertex_count() != base.vertex_count() || mwe.influences != base.influences)
    throw InputError("smooth_mwe_refinement: needs an MWE rig fitted over the given SSD rig (same influences)");
  const int n = mwe.vertex_count(), K = mwe.max_influences();
  const SkinningRig b12 = lbs_as_mwe(base);
  Eigen::MatrixXd D = mwe.coefficients - b12.coefficients;  // #V by 12·K
  const auto nb = vertex_neighbours(n, F);
  Eigen::MatrixXd E(D.rows(), D.cols());
  for (int s = 0; s < steps; ++s) {
    tbb::parallel_for(0, n, [&](int v) {
      for (int k = 0; k < K; ++k) {
        const int bone = mwe.influences(v, k);
        if (bone < 0 || nb[v].empty()) {
          E.block(v, 12 * k, 1, 12) = D.block(v, 12 * k, 1, 12);
          continue;
        }
        Eigen::RowVectorXd m = Eigen::RowVectorXd::Zero(12);
        for (int u : nb[v])
          for (int j = 0; j < K; ++j)
            if (mwe.influences(u, j) == bone) {
              m += D.block(u, 12 * j, 1, 12);
              break;
            }
        E.block(v, 12 * k, 1, 12) = 0.5 * D.block(v, 12 * k, 1, 12) + (0.5 / nb[v].size()) * m;
      }
    });
    std::swap(D, E);
  }
  if (keep) {
    if (keep->size() != n) throw InputError("smooth_mwe_refinement: the mask has a value per vertex");
    D = keep->asDiagonal() * D;
  }
  mwe.coefficients = b12.coefficients + D;
}

Eigen::VectorXd mwe_refinement_mask(const Eigen::MatrixXd& W, const Skeleton& skeleton, const Eigen::MatrixX3i& F,
                                    int steps) {
  return mwe_refinement_mask(W, skeleton, F, steps, {"wrist", "foot", "head"});
}

Eigen::VectorXd mwe_refinement_mask(const Eigen::MatrixXd& W, const Skeleton& skeleton, const Eigen::MatrixX3i& F,
                                    int steps, const std::vector<std::string>& prefixes) {
  Eigen::VectorXd x = Eigen::VectorXd::Zero(W.rows());
  for (int b = 0; b < skeleton.bone_count(); ++b)
    for (int a = b; a >= 0; a = skeleton.parents[a]) {
      const std::string& n = skeleton.names[a];
      if (std::any_of(prefixes.begin(), prefixes.end(), [&](const std::string& p) { return n.rfind(p, 0) == 0; })) {
        x += W.col(b);
        break;
      }
    }
  Eigen::MatrixXd m = smooth_skin_weights(Eigen::MatrixXd(x), F, steps);
  return (1.0 - m.col(0).array()).cwiseMax(0.0).cwiseMin(1.0).matrix();
}

CharacterRigs fit_character_rigs(const CharacterExamples& ex, const CharacterOptions& o,
                                 const ProgressCallback& progress) {
  CharacterRigs r;
  const SkinningExamples s = training_examples(ex);
  const Eigen::MatrixXd Wt = merge_undriven_weights(Eigen::MatrixXd(ex.template_weights), ex.skeleton, ex.driven);
  r.template_lbs = lbs_rig_from_weights(ex.rest, Wt, o.max_influences);
  r.smooth_lbs = lbs_rig_from_weights(ex.rest, smooth_skin_weights(Wt, ex.F, o.weight_smoothing_steps), o.max_influences);
  auto sub = [&](double a, double b) -> ProgressCallback {
    if (!progress) return {};
    return [=](double f, std::string_view w) { return progress(a + (b - a) * f, w); };
  };
  r.lbs = fit_lbs(s, r.smooth_lbs.influences, o.lbs, &r.lbs_summary, sub(0.0, 0.3));
  const SkinningRig& base = o.base_on_template_weights ? r.smooth_lbs : r.lbs;
  r.as = fit_animation_space(s, &base, o.animation_space, &r.as_summary, sub(0.3, 0.5));
  r.mwe = fit_mwe(s, &base, o.mwe, &r.mwe_summary, sub(0.5, 1.0));
  if (o.mwe_mask_steps >= 0) {
    const Eigen::VectorXd keep = mwe_refinement_mask(Eigen::MatrixXd(ex.template_weights), ex.skeleton, ex.F,
                                                     o.mwe_mask_steps, o.mwe_mask_bones);
    smooth_mwe_refinement(r.mwe, base, ex.F, o.mwe_smoothing_steps, &keep);
  } else {
    smooth_mwe_refinement(r.mwe, base, ex.F, o.mwe_smoothing_steps);
  }
  return r;
}

namespace {

Eigen::VectorXd vertex_errors(const SkinningRig& rig, const BoneTransforms& M, const Eigen::MatrixX3d& Y) {
  return (evaluate_rig(rig, M) - Y).rowwise().norm();
}

}  // namespace

std::vector<RigErrorRow> evaluate_character_rigs(const CharacterExamples& ex, const CharacterRigs& rigs) {
  std::vector<RigErrorRow> rows;
  const std::pair<const char*, const SkinningRig*> methods[] = {
      {"template_lbs", &rigs.template_lbs}, {"smooth_lbs", &rigs.smooth_lbs}, {"lbs", &rigs.lbs},
      {"as", &rigs.as}, {"mwe", &rigs.mwe}};
  for (auto [name, rig] : methods)
    for (bool held : {false, true}) {
      std::vector<double> e;
      int poses = 0;
      for (size_t p = 0; p < ex.poses.size(); ++p) {
        if (ex.poses[p].held_out != held) continue;
        Eigen::VectorXd v = vertex_errors(*rig, ex.transforms[p], ex.meshes[p]);
        e.insert(e.end(), v.data(), v.data() + v.size());
        ++poses;
      }
      if (!poses) continue;
      RigErrorRow row{name, held ? "held_out" : "train", poses};
      double sum = 0, sq = 0;
      for (double x : e) sum += x, sq += x * x, row.max_mm = std::max(row.max_mm, x);
      row.mean_mm = sum / e.size();
      row.rms_mm = std::sqrt(sq / e.size());
      std::nth_element(e.begin(), e.begin() + static_cast<long>(0.95 * (e.size() - 1)), e.end());
      row.p95_mm = e[static_cast<size_t>(0.95 * (e.size() - 1))];
      rows.push_back(row);
    }
  return rows;
}

PoseErrors per_pose_errors(const CharacterExamples& ex, const CharacterRigs& rigs) {
  const SkinningRig* methods[] = {&rigs.template_lbs, &rigs.smooth_lbs, &rigs.lbs, &rigs.as, &rigs.mwe};
  const int P = static_cast<int>(ex.poses.size());
  PoseErrors e;
  e.mean_mm.resize(P, 5);
  e.max_mm.resize(P, 5);
  e.max_vertex.resize(P, 5);
  tbb::parallel_for(0, P, [&](int p) {
    for (int m = 0; m < 5; ++m) {
      const Eigen::VectorXd v = vertex_errors(*methods[m], ex.transforms[p], ex.meshes[p]);
      e.mean_mm(p, m) = v.mean();
      Eigen::Index i = 0;
      e.max_mm(p, m) = v.maxCoeff(&i);
      e.max_vertex(p, m) = static_cast<int>(i);
    }
  });
  return e;
}

Eigen::VectorXd held_out_vertex_error(const CharacterExamples& ex, const SkinningRig& rig) {
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(ex.rest.rows());
  int n = 0;
  for (size_t p = 0; p < ex.poses.size(); ++p)
    if (ex.poses[p].held_out) {
      sum += vertex_errors(rig, ex.transforms[p], ex.meshes[p]);
      ++n;
    }
  return n ? Eigen::VectorXd(sum / n) : sum;
}

std::string rig_errors_csv(const std::vector<RigErrorRow>& rows) {
  std::string s = "method,split,poses,mean_mm,max_mm,rms_mm,p95_mm\n";
  for (auto& r : rows)
    s += fmt::format("{},{},{},{:.3f},{:.3f},{:.3f},{:.3f}\n", r.method, r.split, r.poses, r.mean_mm, r.max_mm,
                     r.rms_mm, r.p95_mm);
  return s;
}

void validate_character_options(const CharacterOptions& o) {
  auto fail = [](const std::string& what) { throw InputError("character: " + what); };
  if (!(std::isfinite(o.mwe.ridge_scale) && o.mwe.ridge_scale >= 0))
    fail(fmt::format("the MWE ridge scale (--mwe-s) must be a finite number ≥ 0, got {}", o.mwe.ridge_scale));
  if (o.mwe.components < 0) fail(fmt::format("--mwe-components must be ≥ 0, got {}", o.mwe.components));
  if (o.mwe_smoothing_steps < 0)
    fail(fmt::format("--mwe-smoothing-steps must be ≥ 0, got {}", o.mwe_smoothing_steps));
  if (o.weight_smoothing_steps < 0)
    fail(fmt::format("weight smoothing steps must be ≥ 0, got {}", o.weight_smoothing_steps));
  if (!(std::isfinite(o.fold_repair.max_displacement) && o.fold_repair.max_displacement > 0))
    fail(fmt::format("--fold-max-move-mm must be a positive number of millimetres, got {}",
                     o.fold_repair.max_displacement));
  if (o.threads < 0) fail(fmt::format("--threads must be ≥ 0, got {}", o.threads));
  if (o.max_influences < 1) fail(fmt::format("at least one influence per vertex, got {}", o.max_influences));
  const RangeOfMotionOptions& r = o.range_of_motion;
  if (r.training_frames_per_clip < 0 || r.held_out_frames_per_clip < 0 || r.training_blends < 0 || r.held_out_blends < 0)
    fail("the range of motion's frame and blend counts must be ≥ 0");
}

}  // namespace bodymodel
