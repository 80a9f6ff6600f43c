#include "tools/pipeline/animate_job.h"

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "core/retarget.h"
#include "skinning/gltf_export.h"
#include "skinning/runtime_skinning.h"
#include "tools/pipeline/character.h"
#include "tools/render/render.h"

namespace bodymodel {

namespace fs = std::filesystem;

int lead_in_frames(const std::vector<Pose>& poses, double* jump_deg) {
  auto turn = [&](size_t a) {   // the largest turn of a bone from frame a to a + 1, degrees
    double m = 0;
    const auto& A = poses[a].rotations;
    const auto& B = poses[a + 1].rotations;
    for (size_t b = 0; b < std::min(A.size(), B.size()); ++b)
      m = std::max(m, Eigen::AngleAxisd(A[b].transpose() * B[b]).angle() * 180 / M_PI);
    return m;
  };
  if (jump_deg) *jump_deg = poses.size() >= 2 ? turn(0) : 0;
  if (poses.size() < 4) return 0;
  std::vector<double> later;
  for (size_t a = 1; a + 1 < poses.size() && later.size() < 60; ++a) later.push_back(turn(a));
  std::nth_element(later.begin(), later.begin() + static_cast<std::ptrdiff_t>(later.size() / 2), later.end());
  const double jump = turn(0), median = later[later.size() / 2];
  return jump > 30 && jump > 10 * median ? 1 : 0;
}

namespace {

ClipPoses retarget_all(const BvhMotion& clip, const Skeleton& skeleton, const fs::path& makehuman_dir,
                       bool with_translation, const std::string& what, RetargetOptions ro) {
  ClipPoses out;
  out.frame_time = clip.frame_time > 0 ? clip.frame_time : 1.0 / 30;
  int named = 0;
  for (const auto& j : clip.joints) named += skeleton.find(j.name) >= 0;
  if (named * 2 >= skeleton.bone_count()) {
    out.mapping = "MakeHuman names";
    for (const auto& j : clip.joints)
      if (skeleton.find(j.name) < 0) out.ignored_joints.push_back(j.name);
    out.poses = poses_from_bvh(clip, skeleton, makehuman_dir, with_translation);
    return out;
  }
  // Which names a map knows: the Poser/DAZ map and rig/cmu_mb.mhskel's references.
  std::set<std::string> known;
  RetargetMap poser = RetargetMap::poser_cmu();
  for (auto& e : poser.entries) known.insert(e.source);
  const fs::path mb = makehuman_dir / "rig" / "cmu_mb.mhskel";
  std::error_code ec;
  if (fs::exists(mb, ec))
    for (auto& e : RetargetMap::from_mhskel(mb).entries) known.insert(e.source);
  RetargetMap map;
  try {
    map = RetargetMap::for_clip(clip, makehuman_dir);
  } catch (const InputError&) {
    std::vector<std::string> unknown;
    for (const auto& j : clip.joints)
      if (!known.count(j.name) && skeleton.find(j.name) < 0) unknown.push_back(j.name);
    std::string list;
    for (size_t i = 0; i < unknown.size(); ++i) list += (i ? ", " : "") + unknown[i];
    throw InputError(fmt::format("{}: cannot map the clip onto the MakeHuman skeleton: {} of its {} joints match "
                                 "no bone or retarget map: {}",
                                 what, unknown.size(), clip.joints.size(), list));
  }
  std::set<std::string> sources;
  for (auto& e : map.entries) sources.insert(e.source);
  for (const auto& j : clip.joints)
    if (!sources.count(j.name)) out.ignored_joints.push_back(j.name);
  out.mapping = map.entries.size() == poser.entries.size() ? "Poser/DAZ CMU map" : "rig/cmu_mb.mhskel map";
  ro.apply_root_translation = with_translation;
  out.poses = Retargeter(clip, skeleton, map, ro).all_poses();
  return out;
}

}  // namespace

ClipPoses retarget_clip(const BvhMotion& clip, const Skeleton& skeleton, const fs::path& makehuman_dir,
                        bool with_translation, const std::string& what, RetargetOptions ro) {
  ClipPoses out = retarget_all(clip, skeleton, makehuman_dir, with_translation, what, ro);
  out.lead_in = lead_in_frames(out.poses, &out.lead_in_jump_deg);
  out.poses.erase(out.poses.begin(), out.poses.begin() + out.lead_in);
  return out;
}

SkinWeights skin_weights_of(const SkinningRig& lbs) {
  std::vector<Eigen::Triplet<double>> t;
  for (int v = 0; v < lbs.vertex_count(); ++v)
    for (int k = 0; k < lbs.max_influences(); ++k) {
      const int b = lbs.influences(v, k);
      if (b >= 0 && lbs.coefficients(v, k) > 0) t.emplace_back(v, b, lbs.coefficients(v, k));
    }
  SkinWeights W(lbs.vertex_count(), lbs.bone_count);
  W.setFromTriplets(t.begin(), t.end());
  return W;
}

FoldRepairOptions AnimateOptions::default_animation_repair() {
  FoldRepairOptions o;
  o.rings = 2;
  // Wide creases need regions grown over several passes: 8 (as `generate`) left 2 armpit
  // triangles of the demo character on 12_03, 16 none. Later passes run only on frames with
  // flips left.
  o.passes = 16;
  // A solve that would stretch an edge beyond 3x rest (the exploded-triangle bound of
  // animation.csv) and beyond what it was is refused (a later pass tries a wider region).
  o.max_edge_ratio = 3;
  return o;
}

std::vector<Eigen::Matrix3d> blended_vertex_rotations(const SkinningRig& lbs, const BoneTransforms& M) {
  std::vector<Eigen::Quaterniond> q(M.size());
  for (size_t b = 0; b < M.size(); ++b) q[b] = Eigen::Quaterniond(Eigen::Matrix3d(M[b].linear())).normalized();
  std::vector<Eigen::Matrix3d> out(lbs.vertex_count(), Eigen::Matrix3d::Identity());
  for (int v = 0; v < lbs.vertex_count(); ++v) {
    Eigen::Vector4d sum = Eigen::Vector4d::Zero();
    Eigen::Vector4d first = Eigen::Vector4d::Zero();
    for (int k = 0; k < lbs.max_influences(); ++k) {
      const int b = lbs.influences(v, k);
      const double w = lbs.coefficients(v, k);
      if (b < 0 || !(w > 0) || b >= static_cast<int>(q.size())) continue;
      Eigen::Vector4d c = q[b].coeffs();
      if (first.isZero()) first = c;
      if (c.dot(first) < 0) c = -c;  // same hemisphere (q and −q are one rotation)
      sum += w * c;
    }
    if (sum.norm() > 1e-12) out[v] = Eigen::Quaterniond(sum.normalized()).toRotationMatrix();
  }
  return out;
}

double AnimateResult::max_edge_ratio(const std::vector<FrameCheck>& c) const {
  double m = 0;
  for (auto& x : c) m = std::isnan(x.max_edge_ratio) ? x.max_edge_ratio : std::max(m, x.max_edge_ratio);
  return m;
}

int AnimateResult::max_flipped(const std::vector<FrameCheck>& c) const {
  int m = 0;
  for (auto& x : c) m = std::max(m, x.flipped);
  return m;
}

AnimateResult animate_character(const CharacterRigFile& ch, const ClipPoses& clip, const fs::path& dir,
                                const AnimateOptions& o, const ProgressCallback& progress) {
  if (!(o.fps > 0)) throw InputError("--fps must be positive");
  if (o.format != "ply" && o.format != "obj" && o.format != "none")
    throw InputError("--format must be ply, obj or none (got '" + o.format + "')");
  AnimateResult res;
  const int src = static_cast<int>(clip.poses.size());
  const int stride = std::max(1, static_cast<int>(std::lround(1.0 / (clip.frame_time * o.fps))));
  for (int f = 0; f < src; f += stride) {
    if (o.max_frames > 0 && static_cast<int>(res.source_frames.size()) >= o.max_frames) break;
    res.source_frames.push_back(f);
  }
  res.frames = static_cast<int>(res.source_frames.size());
  res.frame_time = stride * clip.frame_time;
  const RuntimeSkinner skinner(ch.rig);
  const DeformationChecker checker(ch.rig.rest, ch.F, ch.lbs);
  std::vector<BoneTransforms> transforms;
  std::vector<Eigen::MatrixX3d> sheet;
  std::vector<int> sheet_at;
  for (int k = 0; k < o.sheet_frames && res.frames > 0; ++k)
    sheet_at.push_back(static_cast<int>(std::lround(double(k) * (res.frames - 1) / std::max(1, o.sheet_frames - 1))));
  auto t0 = std::chrono::steady_clock::now();
  std::string details =
      "frame,clip_frame,kind,element,bone,value,bone_angle_deg,parent,parent_angle_deg\n";
  auto angle_deg = [](const Eigen::Matrix3d& R) { return Eigen::AngleAxisd(R).angle() * 180 / M_PI; };
  for (int i = 0; i < res.frames; ++i) {
    // Undriven bones follow their parent; skin in the root's frame, then place (see
    // relative_to_root: MWE is not invariant to a global rigid motion).
    const Pose pose = restrict_pose(clip.poses[res.source_frames[i]], ch.driven);
    const BoneTransforms M = forward_kinematics(ch.skeleton, pose);
    Eigen::Affine3d G;
    const BoneTransforms L = relative_to_root(M, ch.skeleton, &G);
    auto ts = std::chrono::steady_clock::now();
    const Eigen::MatrixX3d XL = skinner.pose(L).cast<double>();
    Eigen::MatrixX3d X = ((XL * G.linear().transpose()).rowwise() + G.translation().transpose()).eval();
    res.skin_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - ts).count();
    if (!X.allFinite())
      throw NumericalError(fmt::format("frame {} of the clip gave non-finite vertices", res.source_frames[i]));
    res.rig_before_repair.push_back(checker.check(X, M));
    const Eigen::MatrixX3d X_skinned = o.details ? X : Eigen::MatrixX3d();
    if (o.repair && res.rig_before_repair.back().flipped > 0) {
      const auto tr = std::chrono::steady_clock::now();
      const Eigen::MatrixX3d N_ref = checker.reference_normals(M);
      auto repair = [&](Eigen::MatrixX3d& Y, int rings) {
        FoldRepairOptions ro = o.repair_options;
        ro.rings = rings;
        return o.repair_vertex_rotations
                   ? repair_folds_against_normals(Y, ch.rig.rest, N_ref, blended_vertex_rotations(ch.lbs, M), ch.F, ro)
                   : repair_folds_against_normals(Y, ch.rig.rest, N_ref, ch.F, ro);
      };
      const Eigen::MatrixX3d X0 = X;
      FoldRepairSummary s = repair(X, o.repair_options.rings);
      // Flips left: the frame again from its skinned state with other first-ring widths, keeping
      // the attempt with the fewest (a kept solve can leave one triangle flipped inside its area
      // that no wider pass undoes; a different start rarely does the same).
      for (int extra : o.repair_retry_rings) {
        if (s.flipped_after == 0) break;
        Eigen::MatrixX3d Y = X0;
        const FoldRepairSummary t = repair(Y, extra);
        if (t.flipped_after < s.flipped_after) X = Y, s = t;
      }
      res.repair_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - tr).count();
      res.repaired_frames += s.regions_kept > 0;
      if (!X.allFinite())
        throw NumericalError(fmt::format("frame {}: the fold repair gave non-finite vertices", res.source_frames[i]));
      res.rig.push_back(checker.check(X, M));
    } else {
      res.rig.push_back(res.rig_before_repair.back());
    }
    const Eigen::MatrixX3d XS = evaluate_rig(ch.lbs, M);
    res.lbs.push_back(checker.check(XS, M));
    if (o.details) {
      auto row = [&](const char* kind, int element, int bone, double value) {
        const int p = ch.skeleton.parents[bone];
        details += fmt::format("{},{},{},{},{},{:.4f},{:.1f},{},{:.1f}\n", i, res.source_frames[i], kind, element,
                               ch.skeleton.names[bone], value, angle_deg(pose.rotations[bone]),
                               p >= 0 ? ch.skeleton.names[p] : "", p >= 0 ? angle_deg(pose.rotations[p]) : 0.0);
      };
      // Joint angles of the driven bones: value = twist about the bone's own axis (deg).
      for (int b = 0; b < ch.skeleton.bone_count(); ++b) {
        if (!ch.driven[b] || ch.skeleton.parents[b] < 0) continue;
        const Eigen::Quaterniond q(pose.rotations[b]);
        const Eigen::Vector3d axis = (ch.skeleton.tails.row(b) - ch.skeleton.heads.row(b)).transpose().normalized();
        const double twist = 2 * std::atan2(q.vec().dot(axis), q.w()) * 180 / M_PI;
        row("joint", -1, b, twist);
      }
      for (int f : checker.flipped_faces(X_skinned, M)) row("flip", f, checker.dominant_bone_of_face(f), 1);
      if (o.repair)
        for (int f : checker.flipped_faces(X, M)) row("flip_after_repair", f, checker.dominant_bone_of_face(f), 1);
      for (int f : checker.flipped_faces(XS, M)) row("flip_ssd", f, checker.dominant_bone_of_face(f), 1);
      for (Eigen::Index e = 0; e < checker.edges().rows(); ++e) {
        const int a = checker.edges()(e, 0), b = checker.edges()(e, 1);
        const double r = (X.row(a) - X.row(b)).norm() / checker.rest_length(static_cast<int>(e));
        if (r > o.details_edge_ratio) row("edge", static_cast<int>(e), checker.dominant_bone_of_vertex(a), r);
      }
    }
    res.template_lbs.push_back(checker.check(evaluate_rig(ch.template_lbs, M), M));
    if (o.format != "none") write_mesh(dir / fmt::format("frame_{:04d}.{}", i, o.format), X, ch.F);
    if (std::find(sheet_at.begin(), sheet_at.end(), i) != sheet_at.end()) sheet.push_back(X);
    transforms.push_back(M);
    report_progress(progress, double(i + 1) / res.frames, fmt::format("frame {}", i));
  }
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::string csv =
      "frame,clip_frame,time_s,max_edge_ratio,min_edge_ratio,flipped,lbs_max_edge_ratio,lbs_flipped,"
      "template_max_edge_ratio,template_flipped,p99_edge_ratio,worst_vertex_a,worst_vertex_b,worst_rest_mm,"
      "worst_bone,flipped_before_repair,max_edge_ratio_before_repair,p99_edge_ratio_before_repair\n";
  for (int i = 0; i < res.frames; ++i) {
    const FrameCheck& c = res.rig[i];
    const int e = std::max(c.worst_edge, 0);
    const int a = checker.edges()(e, 0), b = checker.edges()(e, 1);
    const FrameCheck& u = res.rig_before_repair[i];
    csv += fmt::format("{},{},{:.4f},{:.4f},{:.4f},{},{:.4f},{},{:.4f},{},{:.4f},{},{},{:.3f},{},{},{:.4f},{:.4f}\n", i,
                       res.source_frames[i], i * res.frame_time, c.max_edge_ratio, c.min_edge_ratio, c.flipped,
                       res.lbs[i].max_edge_ratio, res.lbs[i].flipped, res.template_lbs[i].max_edge_ratio,
                       res.template_lbs[i].flipped, c.p99_edge_ratio, a, b, checker.rest_length(e),
                       ch.skeleton.names[checker.dominant_bone_of_vertex(a)], u.flipped, u.max_edge_ratio,
                       u.p99_edge_ratio);
  }
  write_text_file(dir / "animation.csv", csv);
  if (o.details) write_text_file(dir / "details.csv", details);
  if (!sheet.empty()) {
    // Frames side by side; each centred horizontally (a walk travels), common scale.
    render_row(sheet, ch.F, {}, 200, 400).save_png(dir / "frames.png");
  }
  if (o.write_glb && res.frames > 0) {
    GltfAnimation anim;
    anim.name = "clip";
    anim.frame_time = res.frame_time;
    anim.frames = transforms;
    GltfExportOptions go;
    go.mesh_name = "character";
    write_skinned_gltf(dir / "animated.glb", ch.lbs.rest, ch.F, {}, ch.skeleton, skin_weights_of(ch.lbs), &anim, go);
    res.wrote_glb = true;
  }
  return res;
}

}  // namespace bodymodel
