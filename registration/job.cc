#include "registration/job.h"

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/io/json_text.h"
#include "registration/fit_check.h"
#include "registration/local_fold_repair.h"
#include "registration/mesh_scan.h"
#include "registration/pose_parameters.h"

namespace bodymodel {

void validate(const RegistrationJobOptions& o) {
  if (o.schedule != "paper" && o.schedule != "fast")
    throw InputError("--schedule: expected 'paper' or 'fast', got '" + o.schedule + "'");
  if (o.pose_joints != "default" && o.pose_joints != "segment" && o.pose_joints != "bone" &&
      o.pose_joints != "best")
    throw InputError("--pose-joints: expected 'segment', 'bone' or 'best', got '" + o.pose_joints + "'");
  if (o.fast_steps < 1) throw InputError(fmt::format("--fast-steps must be at least 1, got {}", o.fast_steps));
  if (!(o.fast_k_end > 0)) throw InputError(fmt::format("--fast-stiffness-end must be positive, got {}", o.fast_k_end));
  if (!(o.landmark_floor >= 0) || !std::isfinite(o.landmark_floor))
    throw InputError(fmt::format("--landmark-floor must be a finite number ≥ 0, got {}", o.landmark_floor));
  if (!(o.transform_length > 0))
    throw InputError(fmt::format("--transform-length must be positive, got {}", o.transform_length));
  if (o.pose_iterations < 0)
    throw InputError(fmt::format("--pose-iterations must not be negative, got {}", o.pose_iterations));
  if (!(o.learned_space_prior >= 0) || !std::isfinite(o.learned_space_prior))
    throw InputError(fmt::format("--shape-space-prior must be a finite number ≥ 0, got {}", o.learned_space_prior));
  if (!(o.model_space_prior >= 0) || !std::isfinite(o.model_space_prior))
    throw InputError(fmt::format("--model-prior must be a finite number ≥ 0, got {}", o.model_space_prior));
  if (o.learned_space && o.model_space) throw InputError("--shape-space and --model: give one shape space");
}

RegistrationTemplate registration_template(const RegistrationJobOptions& o) {
  MakeHuman mh = MakeHuman::load();
  if (o.model_space) {
    if (!o.shape_fit) throw InputError("a model's shape space (--model) needs the shape fit (drop --no-shape-fit)");
    o.model_space->validate("--model shape space");
    MakeHuman::Body body = vertex_space_body(mh, *o.model_space, Eigen::VectorXd());
    RegistrationTemplate tpl{body.mesh, body.skeleton, body.weights, std::move(mh), MacroSettings{}, {}, {}};
    tpl.vertex_space = o.model_space;
    return tpl;
  }
  if (o.learned_space) {
    if (!o.shape_fit) throw InputError("a learned shape space (--shape-space) needs the shape fit (drop --no-shape-fit)");
    o.learned_space->validate(mh, "shape space");
    MakeHuman::Body body = shape_space_body(mh, *o.learned_space, Eigen::VectorXd());
    const MacroSettings macros = shape_space_parameters(mh, *o.learned_space, Eigen::VectorXd()).macros;
    RegistrationTemplate tpl{body.mesh, body.skeleton, body.weights, std::move(mh), macros, o.learned_space, {}};
    return tpl;
  }
  const MacroSettings start = o.start_shape.value_or(MacroSettings{});
  MakeHuman::Body body = mh.body(start);
  RegistrationTemplate tpl{body.mesh, body.skeleton, body.weights, {}, start, {}, {}};
  if (o.shape_fit) tpl.shape_space = std::move(mh);
  return tpl;
}

RegistrationSetup registration_setup(const RegistrationJobOptions& o) {
  validate(o);
  RegistrationSetup s;
  s.folds = o.folds;
  RegistrationOptions& r = s.options;
  r.nonrigid.schedule = o.schedule == "paper" ? NonrigidSchedule::paper : NonrigidSchedule::fast;
  r.nonrigid.fast_steps = o.fast_steps;
  r.nonrigid.fast_k_end = o.fast_k_end;
  r.nonrigid.landmark_floor = o.landmark_floor;
  r.nonrigid.normalization_length = o.transform_length;
  r.nonrigid.contact_segments = o.contact_segments;
  r.skip_nonrigid = o.pose_only;
  r.fit_proportions = o.proportions;
  r.fit_shape = o.shape_fit;  // only read when the template has a shape space
  r.proportions_with_shape = o.proportions_with_shape;
  r.shape.space_prior_weight = o.model_space ? o.model_space_prior : o.learned_space_prior;
  r.pose.max_icp_iterations = o.pose_iterations;

  // pose.parameters left empty means default_pose_parameters() (PoseFitOptions).
  s.pose_joint_names = {o.pose_joints, "bone"};
  if (o.pose_joints == "bone") r.pose.parameters = bone_pose_parameters();
  if (o.pose_joints == "segment") r.pose.parameters = segment_pose_parameters();
  if (o.pose_joints == "best") {
    r.pose.parameters = segment_pose_parameters();
    r.pose_alternatives.push_back(r.pose);
    r.pose_alternatives.back().parameters = bone_pose_parameters();
    s.pose_joint_names[0] = "segment";
  }
  if (o.hand_stage) {
    if (r.pose.parameters.empty()) r.pose.parameters = default_pose_parameters();
    r.pose.parameters = with_hand_stage(r.pose.parameters);
    for (auto& alt : r.pose_alternatives) alt.parameters = with_hand_stage(alt.parameters);
  }
  return s;
}

RegistrationJobResult run_registration_job(const RegistrationTemplate& tpl, const RegistrationSetup& setup,
                                           PointCloud& scan, const std::vector<Landmark>& landmarks,
                                           const std::string& what, const ProgressCallback& progress) {
  const RegistrationOptions& options = setup.options;
  const FoldRepair folds = setup.folds;
  RegistrationJobResult out;
  RegistrationResult& r = out.registration;
  r = register_scan(tpl, scan, landmarks, options, what, &out.summary, progress);
  const size_t choice = size_t(out.summary.pose_choice);
  out.pose_joints = choice < setup.pose_joint_names.size() ? setup.pose_joint_names[choice] : "";
  if (options.skip_nonrigid) return out;
  if (folds == FoldRepair::full) unfold_triangles(r.V, r.pose.V, tpl.mesh.F);
  // Folds the posed template itself carries (its skinning creases) are not flipped against it:
  // the local repair re-solves them from the rest template's shape.
  if (folds != FoldRepair::keep) out.local_folds_repaired = repair_local_folds(r.V, r.rest.V, tpl.mesh.F).folded_before;
  // The Laplacian repair stops where its solves do not lower a region's count (a crumpled
  // crease); the untangling solve moves what it left as little as it can until none is left.
  // Exempt are only the sharp features both the fitted body and the start body have: a fitted
  // blend of MakeHuman's targets can fold a pair of the head's triangles the template has not.
  if (folds != FoldRepair::keep)
    out.untangle = untangle_local_folds(r.V, std::vector<Eigen::MatrixX3d>{r.rest.V, tpl.mesh.V}, tpl.mesh.F);
  // Not a body (a sphere), or landmarks not its own: failed, nothing for the caller to write.
  const FitCheck fc = check_registration_fit(r.V, r.pose.V, r.rest.V, tpl.mesh.F, scan);
  if (!fc.plausible) throw InputError(what + ": registration failed: " + fc.reason);
  return out;
}

std::string registration_shape_json(const RegistrationResult& r) {
  const std::vector<double> c(r.shape_coefficients.data(), r.shape_coefficients.data() + r.shape_coefficients.size());
  if (!r.shape) return c.empty() ? std::string() : json_text(nlohmann::json{{"model_coefficients", c}}, 2) + "\n";
  nlohmann::json j = r.shape->to_json();
  if (!c.empty()) j["shape_space_coefficients"] = c;
  return json_text(j, 2) + "\n";
}

Eigen::MatrixX3d unpose_registration(const RegistrationResult& r, const SkinWeights& W) {
  const Skeleton& sk0 = r.rest_skeleton;
  if (W.rows() != r.V.rows() || W.cols() != sk0.bone_count() || int(r.pose.pose.rotations.size()) != sk0.bone_count())
    throw InputError(fmt::format("unpose: {} vertices, {} weight rows, {} bones, {} weight columns, {} rotations",
                                 r.V.rows(), W.rows(), sk0.bone_count(), W.cols(), r.pose.pose.rotations.size()));
  // The skeleton pose_template posed: scaled about the root head.
  const Eigen::RowVector3d o = sk0.heads.row(0);
  Skeleton sk = sk0;
  sk.heads = ((sk0.heads.rowwise() - o) * r.pose.scale).rowwise() + o;
  sk.tails = ((sk0.tails.rowwise() - o) * r.pose.scale).rowwise() + o;
  const BoneTransforms M = forward_kinematics(sk, r.pose.pose);
  Eigen::MatrixX3d X(r.V.rows(), 3);
  for (Eigen::Index v = 0; v < r.V.rows(); ++v) {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
    int dom = -1;
    double wmax = -1;
    for (SkinWeights::InnerIterator it(W, v); it; ++it) {
      A += it.value() * M[it.col()].linear();
      t += it.value() * M[it.col()].translation();
      if (it.value() > wmax) wmax = it.value(), dom = int(it.col());
    }
    const Eigen::Vector3d y = r.V.row(v).transpose();
    // A blend of rotations far apart shrinks (|det| ≪ 1): invert the dominant bone alone there.
    if (dom >= 0 && std::abs(A.determinant()) > 0.05)
      X.row(v) = (A.inverse() * (y - t)).transpose();
    else
      X.row(v) = dom >= 0 ? (M[dom].inverse() * y).transpose() : y.transpose();
  }
  if (!X.allFinite()) throw NumericalError("unpose: non-finite vertices");
  return X;
}

}  // namespace bodymodel
