#include "tools/pipeline/character_judge.h"

#include <fmt/format.h>
#include <Eigen/Cholesky>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>

#include "core/error.h"
#include "core/geometry.h"
#include "core/rotation.h"
#include "registration/mesh_scan.h"
#include "tools/pipeline/character.h"

namespace bodymodel {

namespace {

using RowMatrixX3d = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

// The bones whose rotation the fit sets: driven, not a root (the placement is the root's motion).
std::vector<int> fitted_bones(const Skeleton& sk, const std::vector<char>& driven) {
  std::vector<int> b;
  for (int i = 0; i < sk.bone_count(); ++i)
    if (driven[i] && sk.parents[i] >= 0) b.push_back(i);
  return b;
}

// `start` restricted to the driven bones, roots at rest (rotation and translation).
Pose clean_start(const Pose& start, const Skeleton& sk, const std::vector<char>& driven) {
  Pose p = Pose::rest(sk.bone_count());
  for (int b = 0; b < sk.bone_count() && b < static_cast<int>(start.rotations.size()); ++b)
    if (driven[b] && sk.parents[b] >= 0) p.rotations[b] = start.rotations[b];
  return p;
}

// Residuals of the placed rig against the target. Unknowns x: [0, 3) the placement's rotation
// increment, [3, 6) its translation (mm), then one rotation increment per fitted bone — each
// rotation R = exp(δ)·R_start, so the unknowns start at zero and stay far from the rotation
// vector's singularity at π. The placement turns about the start's centroid c:
// p ↦ R (p − c) + c + t, which decouples rotation from translation.
struct PoseResidual {
  const SkinningRig& rig;
  const Skeleton& sk;
  const std::vector<int>& bones;
  const Pose& start;
  Eigen::Matrix3d R0;
  Eigen::Vector3d c;
  const Eigen::MatrixX3d& Y;
  double prior = 0;   // mm per radian

  Pose pose_of(const Eigen::VectorXd& x) const {
    Pose pose = start;
    for (size_t i = 0; i < bones.size(); ++i)
      pose.rotations[bones[i]] = rotation_from_vector(x.segment<3>(6 + 3 * i)) * start.rotations[bones[i]];
    return pose;
  }
  Eigen::Affine3d placement_of(const Eigen::VectorXd& x) const {
    const Eigen::Matrix3d R = rotation_from_vector(x.segment<3>(0)) * R0;
    Eigen::Affine3d G = Eigen::Affine3d::Identity();
    G.linear() = R;
    G.translation() = c + x.segment<3>(3) - R * c;
    return G;
  }
  // 3·#V residuals (x, y, z of each vertex), mm.
  Eigen::VectorXd operator()(const Eigen::VectorXd& x) const {
    const Eigen::MatrixX3d X = evaluate_rig(rig, forward_kinematics(sk, pose_of(x)));
    const Eigen::Affine3d G = placement_of(x);
    RowMatrixX3d res = ((X * G.linear().transpose()).rowwise() + G.translation().transpose()) - Y;
    Eigen::VectorXd out(res.size() + (prior > 0 ? x.size() - 6 : 0));
    out.head(res.size()) = Eigen::Map<const Eigen::VectorXd>(res.data(), res.size());
    if (prior > 0) out.tail(x.size() - 6) = prior * x.tail(x.size() - 6);
    return out;
  }
};

}  // namespace

RigPoseFit fit_rig_pose(const SkinningRig& rig, const Skeleton& sk, const std::vector<char>& driven,
                        const Eigen::MatrixX3d& target, const Pose& start, const RigPoseFitOptions& o) {
  if (rig.bone_count != sk.bone_count() || static_cast<int>(driven.size()) != sk.bone_count())
    throw InputError(fmt::format("fit_rig_pose: the rig has {} bones, the skeleton {}, the driven flags {}",
                                 rig.bone_count, sk.bone_count(), driven.size()));
  if (target.rows() != rig.vertex_count())
    throw InputError(fmt::format("fit_rig_pose: the target has {} vertices, the rig {}", target.rows(),
                                 rig.vertex_count()));
  if (o.vertex_stride < 1) throw InputError("fit_rig_pose: the vertex stride must be ≥ 1");
  if (!(o.prior_mm_per_rad >= 0)) throw InputError("fit_rig_pose: the prior weight must be ≥ 0");
  const std::vector<int> bones = fitted_bones(sk, driven);
  const Pose s = clean_start(start, sk, driven);
  // The fit's vertices: every vertex_stride-th (rows of the rig and the target).
  std::vector<int> keep;
  for (int v = 0; v < rig.vertex_count(); v += o.vertex_stride) keep.push_back(v);
  SkinningRig sub = rig;
  sub.rest = rig.rest(keep, Eigen::all);
  sub.influences = rig.influences(keep, Eigen::all);
  sub.coefficients = rig.coefficients(keep, Eigen::all);
  const Eigen::MatrixX3d Ysub = target(keep, Eigen::all);
  // Roots at rest: forward kinematics is already in the root's frame (relative_to_root is the
  // identity), the frame the character's rigs are trained in.
  const Eigen::MatrixX3d X0 = evaluate_rig(sub, forward_kinematics(sk, s));
  const RigidMotion m = fit_rigid_motion(X0, Ysub);
  const Eigen::Vector3d c = X0.colwise().mean().transpose();
  const PoseResidual f{sub, sk, bones, s, m.R, c, Ysub, o.prior_mm_per_rad};
  const int P = static_cast<int>(6 + 3 * bones.size());
  Eigen::VectorXd x = Eigen::VectorXd::Zero(P);
  // Start translation: R0 p + t0 = R0 (p − c) + c + t  ⇒  t = R0 c + t0 − c.
  x.segment<3>(3) = m.R * c + m.t - c;

  // Levenberg–Marquardt (Marquardt's diagonal scaling) with forward-difference Jacobians: a
  // hand-written loop because the problem is one dense block (≈ 40 000 residuals × ≈ 100
  // unknowns), where Ceres' generic evaluation spent ten times longer per iteration.
  Eigen::VectorXd r = f(x);
  double cost = r.squaredNorm();
  double lambda = 1e-3;
  Eigen::MatrixXd J(r.size(), P);
  int it = 0;
  bool converged = false;
  for (; it < o.max_iterations && !converged; ++it) {
    for (int k = 0; k < P; ++k) {
      const double h = k >= 3 && k < 6 ? 1e-4 : 1e-7;   // mm for the translation, radians else
      Eigen::VectorXd xp = x;
      xp[k] += h;
      J.col(k) = (f(xp) - r) / h;
    }
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(P, P);
    A.selfadjointView<Eigen::Lower>().rankUpdate(J.transpose());
    A = A.selfadjointView<Eigen::Lower>();
    const Eigen::VectorXd g = J.transpose() * r;
    bool improved = false;
    for (int tries = 0; tries < 12 && !improved; ++tries) {
      Eigen::MatrixXd D = A;
      D.diagonal() += lambda * A.diagonal().cwiseMax(1e-9);
      const Eigen::VectorXd dx = -D.ldlt().solve(g);
      const Eigen::VectorXd xn = x + dx;
      const Eigen::VectorXd rn = f(xn);
      const double cn = rn.squaredNorm();
      if (cn < cost) {
        const double drop = (cost - cn) / std::max(cost, 1e-300);
        x = xn, r = rn, cost = cn;
        lambda = std::max(lambda / 3, 1e-9);
        improved = true;
        converged = drop < o.function_tolerance;
      } else {
        lambda *= 4;
      }
    }
    if (!improved) break;
  }

  RigPoseFit out;
  out.pose = f.pose_of(x);
  out.placement = f.placement_of(x);
  out.transforms = forward_kinematics(sk, out.pose);
  const Eigen::MatrixX3d X = evaluate_rig(rig, out.transforms);
  out.posed = (X * out.placement.linear().transpose()).rowwise() + out.placement.translation().transpose();
  out.iterations = it;
  out.rms_mm = std::sqrt((out.posed - target).rowwise().squaredNorm().mean());
  return out;
}

Eigen::MatrixX3d inverse_linear_blend_skinning(const Eigen::MatrixX3d& Y, const Eigen::MatrixXd& W,
                                               const BoneTransforms& M) {
  if (W.rows() != Y.rows() || W.cols() != static_cast<Eigen::Index>(M.size()))
    throw InputError(fmt::format("inverse_linear_blend_skinning: {} vertices and {} weight rows, {} bones and {} "
                                 "weight columns",
                                 Y.rows(), W.rows(), M.size(), W.cols()));
  Eigen::MatrixX3d X(Y.rows(), 3);
  tbb::parallel_for(Eigen::Index(0), Y.rows(), [&](Eigen::Index v) {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
    Eigen::Index dom = 0;
    W.row(v).maxCoeff(&dom);
    for (Eigen::Index b = 0; b < W.cols(); ++b) {
      const double w = W(v, b);
      if (w == 0) continue;
      A += w * M[b].linear();
      t += w * M[b].translation();
    }
    const Eigen::Vector3d y = Y.row(v).transpose();
    // A blend of rotations far apart shrinks (|det| ≪ 1): invert the dominant bone alone there.
    if (std::abs(A.determinant()) > 0.05)
      X.row(v) = (A.inverse() * (y - t)).transpose();
    else
      X.row(v) = (M[dom].inverse() * y).transpose();
  });
  return X;
}

UnposeOptions unpose_with_prior() {
  UnposeOptions o;
  o.fit_pose = true;
  o.fit.prior_mm_per_rad = 2000;
  return o;
}

UnposeResult unpose_body(const BodyModel& model, const Eigen::MatrixX3d& posed, const Pose& given,
                         const UnposeOptions& o, const ProgressCallback& progress) {
  if (model.rig.empty()) throw InputError("unpose: the model has no skeleton");
  model.check_topology(posed, model.tmpl->faces(), "the posed body");
  if (o.rounds < 1) throw InputError("unpose: at least one round");
  if (static_cast<int>(given.rotations.size()) != static_cast<int>(model.rig.bone_names.size()))
    throw InputError(fmt::format("unpose: the pose has {} bones, the model's skeleton {}", given.rotations.size(),
                                 model.rig.bone_names.size()));
  UnposeResult r;
  Eigen::MatrixX3d V = model.tmpl->rest_vertices();
  Pose pose = given;
  pose.root_translation.setZero();   // the rigid placement takes it
  const Eigen::MatrixXd W0 = Eigen::MatrixXd(model.rig.weights);
  for (int k = 0; k < o.rounds; ++k) {
    report_progress(progress, double(k) / o.rounds, fmt::format("unpose round {}", k + 1));
    const Skeleton sk = model.rig.skeleton_for(V);
    BoneTransforms M;
    Eigen::MatrixXd W;
    if (o.fit_pose) {
      const std::vector<char> driven = driven_bones(model, sk);
      W = merge_undriven_weights(W0, sk, driven);
      const SkinningRig rig = lbs_rig_from_weights(V, W, o.max_influences);
      // From the given pose every round: the prior pulls towards it, not towards the last round's.
      const RigPoseFit fit = fit_rig_pose(rig, sk, driven, posed, given, o.fit);
      r.rms_mm.push_back(fit.rms_mm);
      pose = fit.pose;
      M = fit.transforms;
      for (auto& m : M) m = fit.placement * m;
      r.placement = fit.placement;
      W = dense_weights(rig);   // the weights the fit used (largest max_influences, renormalised)
    } else {
      // Every bone as the pose has it (fingers and toes too), placed rigidly.
      const SkinningRig rig = lbs_rig_from_weights(V, W0, o.max_influences);
      M = forward_kinematics(sk, pose);
      const Eigen::MatrixX3d X = evaluate_rig(rig, M);
      const RigidMotion g = fit_rigid_motion(X, posed);
      Eigen::Affine3d G = Eigen::Affine3d::Identity();
      G.linear() = g.R;
      G.translation() = g.t;
      for (auto& m : M) m = G * m;
      r.rms_mm.push_back(std::sqrt((apply(g, X) - posed).rowwise().squaredNorm().mean()));
      r.placement = G;
      W = dense_weights(rig);
    }
    V = inverse_linear_blend_skinning(posed, W, M);
  }
  r.rest = V;
  r.pose = pose;
  report_progress(progress, 1.0, "unposed");
  return r;
}

namespace {

JudgeRow stats_row(std::string method, std::string pose, std::vector<double> e) {
  JudgeRow row{std::move(method), std::move(pose)};
  if (e.empty()) return row;
  double sum = 0, sq = 0;
  for (double x : e) sum += x, sq += x * x, row.max_mm = std::max(row.max_mm, x);
  row.mean_mm = sum / e.size();
  row.rms_mm = std::sqrt(sq / e.size());
  const size_t k = static_cast<size_t>(0.95 * (e.size() - 1));
  std::nth_element(e.begin(), e.begin() + static_cast<long>(k), e.end());
  row.p95_mm = e[k];
  return row;
}

}  // namespace

std::vector<JudgeRow> judge_rigs_on_poses(const std::vector<NamedRig>& rigs, const Skeleton& sk,
                                          const std::vector<char>& driven, const Eigen::MatrixX3i& F,
                                          const std::vector<JudgePose>& poses,
                                          const RigPoseFitOptions& o, const ProgressCallback& progress) {
  const int R = static_cast<int>(rigs.size()), P = static_cast<int>(poses.size());
  for (auto& r : rigs)
    if (!r.rig) throw InputError("judge: rig '" + r.name + "' is missing");
  std::vector<Eigen::VectorXd> err(static_cast<size_t>(R) * P);
  std::vector<int> iters(err.size(), 0);
  std::vector<double> scan(err.size(), std::numeric_limits<double>::quiet_NaN());
  std::atomic<int> done{0};
  std::mutex mtx;
  std::atomic<bool> cancelled{false};
  tbb::parallel_for(0, R * P, [&](int task) {
    if (cancelled) return;
    const int r = task / P, p = task % P;
    const RigPoseFit f = fit_rig_pose(*rigs[r].rig, sk, driven, poses[p].target, poses[p].start, o);
    err[task] = (f.posed - poses[p].target).rowwise().norm();
    iters[task] = f.iterations;
    if (poses[p].scan.V.rows() > 0) scan[task] = mesh_scan_distance(f.posed, F, poses[p].scan).two_sided_mean;
    const int d = ++done;
    std::lock_guard<std::mutex> lock(mtx);
    if (cancelled) return;
    try {
      report_progress(progress, double(d) / (R * P), rigs[r].name + " on " + poses[p].name);
    } catch (const Cancelled&) {
      cancelled = true;
    }
  });
  if (cancelled) throw Cancelled{};
  std::vector<JudgeRow> rows;
  for (int r = 0; r < R; ++r) {
    std::vector<double> all;
    int it = 0;
    double scan_sum = 0;   // NaN as soon as one pose has no scan
    for (int p = 0; p < P; ++p) {
      const Eigen::VectorXd& e = err[r * P + p];
      JudgeRow row = stats_row(rigs[r].name, poses[p].name, std::vector<double>(e.data(), e.data() + e.size()));
      row.iterations = iters[r * P + p];
      row.scan_two_sided_mm = scan[r * P + p];
      it += row.iterations;
      scan_sum += row.scan_two_sided_mm;
      rows.push_back(row);
      all.insert(all.end(), e.data(), e.data() + e.size());
    }
    JudgeRow row = stats_row(rigs[r].name, "all", std::move(all));
    row.poses = P;
    row.iterations = it;
    if (P) row.scan_two_sided_mm = scan_sum / P;
    rows.push_back(row);
  }
  return rows;
}

std::string judge_csv(const std::vector<JudgeRow>& rows, const std::vector<JudgePose>& poses) {
  std::string s = "pose,method,poses,mean_mm,max_mm,rms_mm,p95_mm,fit_iterations,registration_mm,scan_two_sided_mm\n";
  auto num = [](double x) { return std::isfinite(x) ? fmt::format("{:.3f}", x) : std::string(); };
  for (auto& r : rows) {
    double reg = std::numeric_limits<double>::quiet_NaN();
    if (r.pose == "all") {
      double sum = 0;
      int n = 0;
      for (auto& p : poses)
        if (std::isfinite(p.registration_mm)) sum += p.registration_mm, ++n;
      if (n == static_cast<int>(poses.size()) && n) reg = sum / n;
    } else {
      for (auto& p : poses)
        if (p.name == r.pose) reg = p.registration_mm;
    }
    s += fmt::format("{},{},{},{:.3f},{:.3f},{:.3f},{:.3f},{},{},{}\n", r.pose, r.method, r.poses, r.mean_mm, r.max_mm,
                     r.rms_mm, r.p95_mm, r.iterations, num(reg), num(r.scan_two_sided_mm));
  }
  return s;
}

}  // namespace bodymodel
