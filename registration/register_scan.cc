#include "registration/register_scan.h"

#include <chrono>

#include "core/error.h"

namespace bodymodel {

namespace {

// One shape fit from the current pose: in the learned space (so.space) or the macro sliders.
ShapeFitResult shape_step(const MakeHuman& mh, const ShapeFitOptions& so, const MacroSettings& settings,
                          const Eigen::VectorXd& coefficients, const PoseFitResult& pose, const PointCloud& scan,
                          const std::vector<Landmark>& landmarks, ShapeFitSummary* ss) {
  return so.space || so.vertex_space ? fit_shape_in_space(mh, coefficients, pose.scale, pose.pose, scan, landmarks, so, ss)
                  : fit_shape(mh, settings, pose.scale, pose.pose, scan, landmarks, so, ss);
}

// How far a shape fit moved the shape, in slider units (a learned space's sd times `unit`).
double shape_moved(const ShapeFitOptions& so, const ShapeFitResult& sr, const MacroSettings& before,
                   const Eigen::VectorXd& coefficients_before, double unit) {
  if (so.space || so.vertex_space) return unit * (sr.coefficients - coefficients_before).cwiseAbs().maxCoeff();
  double moved = 0;
  for (const auto& n : so.sliders) moved = std::max(moved, std::abs(macro_slider(sr.settings, n) - macro_slider(before, n)));
  return moved;
}

// The non-rigid solver on `weights_rest`'s cotangent weights, with the template's body segments
// when contacts are refused.
NonrigidRegistration nonrigid_solver(const RegistrationTemplate& tpl, const Mesh& weights_rest, const NonrigidOptions& no) {
  NonrigidRegistration reg(weights_rest, no);
  if (no.contact_segments && tpl.weights.rows() == tpl.mesh.V.rows())
    reg.set_segments(body_segments(tpl.skeleton, tpl.weights, tpl.mesh.F));
  return reg;
}

// The start of a shape fit in a learned or vertex space: the template's coefficients, else the
// space's mean body (g = 0.5).
Eigen::VectorXd start_coefficients(const RegistrationTemplate& tpl, const ShapeFitOptions& so) {
  if (tpl.learned_start.size() > 0) return tpl.learned_start;
  if (so.vertex_space) return Eigen::VectorXd::Zero(so.vertex_space->components());
  if (!so.space) return {};
  Eigen::VectorXd c = Eigen::VectorXd::Zero(so.space->dimension());
  if (so.space->has_sex()) c[so.space->components()] = 0.5;
  return c;
}

}  // namespace

RegistrationResult register_scan(const RegistrationTemplate& tpl, PointCloud& scan,
                                 const std::vector<Landmark>& landmarks,
                                 const RegistrationOptions& options, const std::string& what,
                                 RegistrationSummary* summary, const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  RegistrationSummary sum;
  sum.scan = prepare_scan(scan, tpl.mesh.V, what, options.scan);
  check_landmarks(landmarks, int(tpl.mesh.V.rows()), what);
  PoseFitOptions po = options.pose;
  NonrigidOptions no = options.nonrigid;
  if (sum.scan.normals_estimated) po.unsigned_normals = no.unsigned_normals = true;
  const double pose_share = options.skip_nonrigid ? 1.0 : 0.25;
  auto sub = [&](double a, double b) -> ProgressCallback {
    if (!progress) return {};
    return [&progress, a, b](double f, std::string_view w) { return progress(a + (b - a) * f, w); };
  };
  RegistrationResult r;
  Mesh rest = tpl.mesh;
  Skeleton skeleton = tpl.skeleton;
  const bool given_start = options.start_vertices.rows() > 0 || options.start_pose.has_value();
  // With a given start pose (evaluation), the shape is fitted with that pose held.
  const bool shape = tpl.shape_space.has_value() && options.fit_shape &&
                     options.start_vertices.rows() == 0 && options.shape_rounds > 0;
  if (options.fit_proportions && landmarks.size() >= 3 &&
      (!shape || options.proportions_with_shape)) {
    r.proportions = estimate_proportions(tpl.mesh.V, landmarks, options.proportions);
    apply_proportions(tpl.mesh.V, tpl.skeleton, tpl.weights, r.proportions, options.proportions,
                      &rest.V, &skeleton);
    if (po.initial_scale <= 0 && !r.proportions.segment.empty())
      po.initial_scale = r.proportions.global_scale;
  }
  if (options.start_vertices.rows() > 0) {
    if (options.start_vertices.rows() != tpl.mesh.V.rows() || !options.start_vertices.allFinite())
      throw InputError(what + ": the start vertices have " +
                       std::to_string(options.start_vertices.rows()) +
                       " rows or are not finite, expected " + std::to_string(tpl.mesh.V.rows()) +
                       " finite rows");
    r.pose.V = options.start_vertices;
    r.pose.pose = Pose::rest(int(skeleton.names.size()));  // unknown: written as the rest pose
  } else if (options.start_pose) {
    const PoseRecord& p = *options.start_pose;
    r.pose.scale = p.scale;
    r.pose.pose = p.pose;
    if (shape) {
      // Fold the record's rigid placement into the root: Q₀ ← G·Q₀, and the posed root head
      // G(h + t) + g = h + t' gives t' = G(h + t) + g − h (h: the scaled root head = h).
      const Eigen::Vector3d h = skeleton.heads.row(0).transpose();
      r.pose.pose.rotations[0] = p.global_rotation * p.pose.rotations[0];
      r.pose.pose.root_translation =
          p.global_rotation * (h + p.pose.root_translation) + p.global_translation - h;
    }
    r.pose.V = pose_template(rest.V, skeleton, tpl.weights, p.scale, p.pose);
    r.pose.V = ((r.pose.V * p.global_rotation.transpose()).rowwise() +
                p.global_translation.transpose())
                   .eval();
  }
  // The pose fits (`pose` and its alternatives) on the current rest template, keeping the best.
  const int fits = given_start ? 0 : 1 + int(options.pose_alternatives.size());
  const int rounds = shape ? options.shape_rounds : 1;
  auto fit_poses = [&](int round) {
    for (int k = 0; k < fits; ++k) {
      PoseFitOptions pk = k == 0 ? po : options.pose_alternatives[k - 1];
      if (k > 0) {
        pk.unsigned_normals = po.unsigned_normals;
        if (pk.initial_scale <= 0 || round > 0) pk.initial_scale = po.initial_scale;
        if (round > 0) pk.fit_scale = po.fit_scale;
      }
      const double a = pose_share * (round * fits + k) / (rounds * fits);
      const double b = pose_share * (round * fits + k + 1) / (rounds * fits);
      PoseFitSummary sk;
      PoseFitResult rk = fit_pose(rest, skeleton, tpl.weights, scan, landmarks, pk, &sk, sub(a, b));
      if (k == 0 || sk.two_sided_mm < sum.pose.two_sided_mm) {
        r.pose = std::move(rk);
        sum.pose = sk;
        sum.pose_choice = k;
      }
    }
  };
  if (!shape) {
    fit_poses(0);
  } else {
    const MakeHuman& mh = *tpl.shape_space;
    ShapeFitOptions so = options.shape;
    so.unsigned_normals = po.unsigned_normals;
    MacroSettings settings = tpl.shape_start;
    so.space = tpl.learned_space.get();
    so.vertex_space = tpl.vertex_space.get();
    const bool in_space = so.space || so.vertex_space;
    Eigen::VectorXd coefficients = start_coefficients(tpl, so);
    // "Moved" in slider units; a learned space's sd units are scaled to compare with the same bar.
    const double unit = in_space ? options.shape_convergence / options.learned_space_convergence : 1.0;
    double moved_last = 0;
    for (int round = 0; round < rounds; ++round) {
      if (!given_start) fit_poses(round);
      ShapeFitSummary ss;
      ShapeFitResult sr = shape_step(mh, so, settings, coefficients, r.pose, scan, landmarks, &ss);
      const double moved = shape_moved(so, sr, settings, coefficients, unit);
      if (in_space) coefficients = sr.coefficients;
      settings = sr.settings;
      r.pose.V = std::move(sr.V);
      r.pose.scale = sr.scale;
      r.pose.pose = std::move(sr.pose);
      rest.V = sr.body.mesh.V;
      skeleton = std::move(sr.body.skeleton);
      if (options.fit_proportions && options.proportions_with_shape && landmarks.size() >= 3) {
        r.proportions = estimate_proportions(rest.V, landmarks, options.proportions);
        // The segment ratios relative to the shaped body; its size is the shape fit's scale.
        Eigen::MatrixX3d Vp;
        Skeleton sp;
        apply_proportions(rest.V, skeleton, tpl.weights, r.proportions, options.proportions, &Vp,
                          &sp);
        rest.V = std::move(Vp);
        skeleton = std::move(sp);
      }
      sum.shape = ss;
      sum.shape_seconds += ss.seconds;
      sum.shape_rounds = round + 1;
      po.initial_scale = r.pose.scale;
      if (options.shape_fixes_scale) po.fit_scale = false;
      moved_last = moved;
      if (moved < options.shape_convergence) break;
    }
    if (!so.vertex_space) r.shape = settings;  // a vertex space's bodies have no sliders
    if (in_space) r.shape_coefficients = coefficients;
    if (options.final_pose_fit && !given_start && moved_last >= options.shape_convergence) {
      fit_poses(rounds - 1);
    } else if (options.proportions_with_shape && !r.proportions.segment.empty() && !given_start) {
      // The last shape fit's pose is on the unproportioned body: pose the proportioned one.
      fit_poses(rounds - 1);
    }
  }
  r.rest = rest;
  r.rest_skeleton = skeleton;
  if (options.skip_nonrigid) {
    r.V = r.pose.V;
  } else {
    // Cotangent weights of the template the pose was fitted on (the shaped body with a shape fit).
    NonrigidRegistration reg = nonrigid_solver(tpl, shape && options.nonrigid_on_shaped_rest ? rest : tpl.mesh, no);
    r.V = reg.fit(r.pose.V, scan, landmarks, &sum.nonrigid, sub(pose_share, 1.0));
    if (options.repair_flipped_rings > 0)
      sum.folded_triangles =
          repair_flipped_triangles(r.V, r.pose.V, tpl.mesh.F, options.repair_flipped_rings,
                                   options.repair_flipped_passes, landmark_vertices(landmarks));
  }
  if (!r.V.allFinite()) throw NumericalError(what + ": registration produced non-finite vertices");
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (summary) *summary = sum;
  return r;
}

}  // namespace bodymodel
