#include "registration/pose_fit.h"

#include <ceres/ceres.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

#include "core/error.h"
#include "core/geometry.h"
#include "core/point_index.h"
#include "core/rotation.h"
#include "registration/hand_stage.h"
#include "registration/pose_problem.h"

namespace bodymodel {

Eigen::MatrixX3d pose_template(const Eigen::MatrixX3d& V_rest, const Skeleton& skeleton,
                               const SkinWeights& weights, double scale, const Pose& pose) {
  const Eigen::RowVector3d o = skeleton.heads.row(0);
  Skeleton s = skeleton;
  s.heads = ((skeleton.heads.rowwise() - o) * scale).rowwise() + o;
  s.tails = ((skeleton.tails.rowwise() - o) * scale).rowwise() + o;
  const Eigen::MatrixX3d V = ((V_rest.rowwise() - o) * scale).rowwise() + o;
  return linear_blend_skinning(V, weights, forward_kinematics(s, pose));
}

namespace {

// The pairs of one body-stage iteration (docs/pose_fit.md#correspondences).
struct BodyPairs {
  std::vector<int> match;                 // per ICP sample: its scan point, -1 none
  std::vector<std::pair<int, int>> back;  // (ICP sample, scan point): symmetric ICP's pairs
  // Trimmed ICP: pairs farther apart are left out (mm), per direction.
  double trim_fwd = std::numeric_limits<double>::infinity();
  double trim_back = std::numeric_limits<double>::infinity();
};

// Template → scan: each ICP sample (not on late bones) to its closest scan point, within dmax and
// with agreeing normals (§2.2).
std::vector<int> forward_pairs(const PoseProblem& p, const Eigen::MatrixX3d& V,
                               const Eigen::MatrixX3d& VN, double dmax) {
  std::vector<int> match(p.body_samples, -1);
  tbb::parallel_for(0, p.body_samples, [&](int si) {
    const int i = p.samples[si];
    if (p.on_late[si]) return;
    double d2 = 0;
    const int j = p.scan_index.nearest(V.row(i).transpose(), &d2);
    if (j < 0 || d2 > dmax * dmax) return;
    if (p.scan.has_normals() && p.normal_agreement(j, VN.row(i)) < p.cos_min) return;
    match[si] = j;
  });
  return match;
}

// Scan → template (symmetric ICP): every scan_samples-th scan point pulls its closest template
// sample. Template → scan pairs alone never pull a template limb towards scan surface it does not
// already face (an arm stuck against the torso matches the torso).
std::vector<std::pair<int, int>> backward_pairs(const PoseProblem& p, const Eigen::MatrixX3d& V,
                                                const Eigen::MatrixX3d& VN, double dmax) {
  std::vector<std::pair<int, int>> back;
  Eigen::MatrixX3d SV(p.body_samples, 3);
  for (int si = 0; si < p.body_samples; ++si) SV.row(si) = V.row(p.samples[si]);
  PointIndex sample_index(SV);
  const int m = int(p.scan.P.rows());
  const int sstride = std::max(1, m / std::max(1, p.o.scan_samples));
  const int count = (m + sstride - 1) / sstride;
  std::vector<int> bmatch(count, -1);
  tbb::parallel_for(0, count, [&](int k) {
    const int j = k * sstride;
    double d2 = 0;
    const int si = sample_index.nearest(p.scan.P.row(j).transpose(), &d2);
    if (si < 0 || d2 > dmax * dmax || p.on_late[si]) return;
    if (p.scan.has_normals() && p.normal_agreement(j, VN.row(p.samples[si])) < p.cos_min) return;
    bmatch[k] = si;
  });
  for (int k = 0; k < count; ++k)
    if (bmatch[k] >= 0) back.emplace_back(bmatch[k], k * sstride);
  return back;
}

// The pairs of body-stage iteration data_iter (≥ 0: an ICP iteration; trimmed from the second on).
BodyPairs body_pairs(const PoseProblem& p, const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& VN,
                     double dmax, int data_iter) {
  BodyPairs pairs;
  pairs.match = forward_pairs(p, V, VN, dmax);
  if (p.o.symmetric_weight > 0) pairs.back = backward_pairs(p, V, VN, dmax);
  if (data_iter >= 1 && p.o.trim_fraction > 0) {
    auto quantile = [&](std::vector<double> d) {
      if (d.size() < 10) return std::numeric_limits<double>::infinity();
      const size_t k = size_t((1.0 - p.o.trim_fraction) * double(d.size() - 1));
      std::nth_element(d.begin(), d.begin() + k, d.end());
      return d[k];
    };
    std::vector<double> df, db;
    for (int si = 0; si < p.body_samples; ++si)
      if (pairs.match[si] >= 0)
        df.push_back((V.row(p.samples[si]) - p.scan.P.row(pairs.match[si])).norm());
    for (const auto& [si, j] : pairs.back)
      db.push_back((V.row(p.samples[si]) - p.scan.P.row(j)).norm());
    pairs.trim_fwd = quantile(df);
    pairs.trim_back = quantile(db);
  }
  return pairs;
}

// What the residuals of one body-stage iteration measured before the solve.
struct BodyResidualStats {
  int matched = 0;     // forward pairs used
  double d2sum = 0;    // their squared distances (mm²)
  double l2 = 0;       // squared distances of the body landmarks (mm²)
};

// Adds the data residuals (both directions, Huber loss) and the body landmarks.
BodyResidualStats add_body_data(ceres::Problem& problem, const PoseProblem& p, PoseUnknowns& u,
                                const Eigen::MatrixX3d& V, const BodyPairs& pairs) {
  const PointCloud& scan = p.scan;
  const PoseFitOptions& o = p.o;
  BodyResidualStats st;
  for (int si = 0; si < p.body_samples; ++si) {
    if (pairs.match[si] < 0) continue;
    const Eigen::Vector3d target = scan.P.row(pairs.match[si]).transpose();
    const double d2 = (V.row(p.samples[si]).transpose() - target).squaredNorm();
    if (d2 > pairs.trim_fwd * pairs.trim_fwd) continue;
    ++st.matched;
    st.d2sum += d2;
    const Eigen::Vector3d normal = scan.has_normals() ? Eigen::Vector3d(scan.N.row(pairs.match[si]))
                                                      : Eigen::Vector3d::Zero();
    add_sample(problem, p, u, si, target, normal, 1.0, 1.0, o.point_to_point_weight,
               new ceres::HuberLoss(o.robust_scale));
  }
  if (!pairs.back.empty()) {
    // Both directions weigh the same in total.
    const double w =
        o.symmetric_weight * std::sqrt(double(std::max(st.matched, 1)) / pairs.back.size());
    for (const auto& [si, j] : pairs.back) {
      const Eigen::Vector3d target = scan.P.row(j).transpose();
      if ((V.row(p.samples[si]).transpose() - target).norm() > pairs.trim_back) continue;
      const Eigen::Vector3d normal =
          scan.has_normals() ? Eigen::Vector3d(scan.N.row(j)) : Eigen::Vector3d::Zero();
      add_sample(problem, p, u, si, target, normal, w, 1.0, o.point_to_point_weight,
                 new ceres::HuberLoss(o.robust_scale));
    }
  }
  for (size_t k = 0; k < p.landmarks.size(); ++k) {
    if (!p.landmark_in_body[k]) continue;
    const int si = p.body_samples + int(k);
    st.l2 += (V.row(p.landmarks[k].vertex).transpose() - p.landmarks[k].target).squaredNorm();
    add_sample(problem, p, u, si, p.landmarks[k].target, Eigen::Vector3d::Zero(),
               o.landmark_weight * std::sqrt(double(p.body_samples) / 100.0), 0.0, 1.0, nullptr);
  }
  return st;
}

// Adds the priors of every body parameter (docs/pose_fit.md#priors): towards rest, annealed
// (landmark-only solve `iter` of lm_iters, or ICP iteration data_iter ≥ 0), and towards `anchor`
// (the landmark-only pose; empty: none). A tied group of g bones costs g times its rotation.
void add_body_priors(ceres::Problem& problem, const PoseProblem& p, PoseUnknowns& u, int iter,
                     int lm_iters, const std::vector<Eigen::Vector3d>& anchor) {
  const PoseFitOptions& o = p.o;
  const bool data = iter >= lm_iters;
  const int data_iter = iter - lm_iters;
  for (int k = 0; k < p.z.count(); ++k) {
    const FittedParameter& prm = p.z.params[k];
    const double anneal =
        data ? std::max(1.0, o.initial_prior_factor * std::pow(0.5, data_iter))
             : std::pow(o.landmark_prior_factor,
                        lm_iters > 1 ? double(lm_iters - 1 - iter) / double(lm_iters - 1) : 1.0);
    const double w = std::sqrt(anneal * o.pose_prior * prm.prior * double(prm.bones.size()));
    add_joint_prior(problem, prm.one_dof(), w, Eigen::Vector3d::Zero(), u.joints[k]);
    if (data && !anchor.empty() && o.anchor_prior > 0 && !prm.late && prm.anchored) {
      const double wa = std::sqrt(o.anchor_prior * double(prm.bones.size()));
      add_joint_prior(problem, prm.one_dof(), wa, anchor[k], u.joints[k]);
    }
  }
}

// The largest rotation change (degrees) of the root and every joint from `old` to `now`.
double largest_rotation_change_deg(const PoseProblem& p, const PoseUnknowns& old,
                                   const PoseUnknowns& now) {
  double max_deg = rotation_angle_deg(rotation_from_vector(now.root), rotation_from_vector(old.root));
  for (int k = 0; k < p.z.count(); ++k) {
    const bool one = p.z.params[k].one_dof();
    const Eigen::Vector3d a = one ? Eigen::Vector3d(now.joints[k][0], 0, 0) : now.joints[k];
    const Eigen::Vector3d b = one ? Eigen::Vector3d(old.joints[k][0], 0, 0) : old.joints[k];
    max_deg = std::max(max_deg, rotation_angle_deg(rotation_from_vector(a), rotation_from_vector(b)));
  }
  return max_deg;
}

// The landmark-only solves, then the ICP iterations, on the body parameters (the late ones held
// at rest) until converged (docs/pose_fit.md#stages). InputError when the scan does not overlap.
void run_body_stage(const PoseProblem& p, PoseUnknowns& u, PoseFitSummary& sum,
                    const ProgressCallback& progress) {
  const PoseFitOptions& o = p.o;
  const int lm_iters = p.body_landmarks >= 3 ? o.landmark_iterations : 0;
  const int total_iters = lm_iters + o.max_icp_iterations;
  std::vector<Eigen::Vector3d> anchor;  // joint parameters after the landmark-only solves
  for (int iter = 0; iter < total_iters; ++iter) {
    report_progress(progress, double(iter) / total_iters, "pose fit");
    const bool data = iter >= lm_iters;
    const int data_iter = iter - lm_iters;
    if (data_iter == 0 && lm_iters > 0) anchor = u.joints;
    const Eigen::MatrixX3d V = posed_template(p, u);
    const Eigen::MatrixX3d VN = vertex_normals(V, p.tpl.F);
    const double dmax =
        std::max(o.max_distance, o.initial_max_distance * std::pow(0.5, std::max(0, data_iter)));
    BodyPairs pairs;
    if (data)
      pairs = body_pairs(p, V, VN, dmax, data_iter);
    else
      pairs.match.assign(p.body_samples, -1);

    ceres::Problem problem;
    add_parameter_blocks(problem, p, u);
    for (int k = 0; k < p.z.count(); ++k)
      if (p.z.params[k].late) problem.SetParameterBlockConstant(u.joints[k].data());
    if (!o.fit_scale) problem.SetParameterBlockConstant(&u.scale);
    else problem.SetParameterLowerBound(&u.scale, 0, 0.2);
    const BodyResidualStats st = add_body_data(problem, p, u, V, pairs);
    add_body_priors(problem, p, u, iter, lm_iters, anchor);
    sum.rms = st.matched ? std::sqrt(st.d2sum / st.matched) : 0.0;
    sum.matched_samples = st.matched;
    sum.landmark_rms = p.body_landmarks == 0 ? 0.0 : std::sqrt(st.l2 / p.body_landmarks);
    if (data && st.matched + p.body_landmarks < 10)
      throw InputError("pose fit: only " + std::to_string(st.matched) +
                       " template samples found a scan point within " + std::to_string(dmax) +
                       " mm and 30° — the scan does not overlap the template (wrong unit or "
                       "far-off position? supply landmarks)");

    const PoseUnknowns old = u;
    solve_pose_problem(problem, data ? o.solver_iterations : 50, o.threads);
    const double max_deg = largest_rotation_change_deg(p, old, u);
    const double dmm = (u.translation - old.translation).norm() + std::abs(u.scale - old.scale) * 1000.0;
    sum.icp_iterations = iter + 1;
    if (data_iter > 0 && dmax <= o.max_distance && max_deg < o.convergence_deg &&
        dmm < o.convergence_mm) {
      sum.converged = true;
      break;
    }
  }
}

// Two-sided distance of the posed template V (#V by 3) and the scan (at most 20 000 scan points
// and 5 000 vertices, evenly strided), each distance capped at max_distance: comparable across
// options (mm).
double two_sided_distance(const PoseProblem& p, const Eigen::MatrixX3d& V) {
  const double cap = p.o.max_distance;
  PointIndex vertex_index(V);
  const int m = int(p.scan.P.rows()), n = p.vertex_count;
  const int sstride = std::max(1, m / 20000), vstride = std::max(1, n / 5000);
  double a = 0, b = 0;
  int na = 0, nb = 0;
  for (int j = 0; j < m; j += sstride, ++na) {
    double d2 = 0;
    vertex_index.nearest(p.scan.P.row(j).transpose(), &d2);
    a += std::min(std::sqrt(d2), cap);
  }
  for (int i = 0; i < n; i += vstride, ++nb) {
    double d2 = 0;
    p.scan_index.nearest(V.row(i).transpose(), &d2);
    b += std::min(std::sqrt(d2), cap);
  }
  return 0.5 * (a / std::max(na, 1) + b / std::max(nb, 1));
}

}  // namespace

PoseFitResult fit_pose(const Mesh& tpl, const Skeleton& skeleton, const SkinWeights& W,
                       const PointCloud& scan, const std::vector<Landmark>& landmarks,
                       const PoseFitOptions& o, PoseFitSummary* summary,
                       const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  o.validate();
  const PoseProblem problem(tpl, skeleton, W, scan, landmarks, o);
  PoseUnknowns unknowns = initial_unknowns(problem);
  PoseFitSummary sum;
  sum.landmarks_used = int(problem.landmarks.size());
  run_body_stage(problem, unknowns, sum, progress);
  run_hand_stage(problem, unknowns, sum, progress);

  PoseFitResult result;
  result.scale = unknowns.scale;
  result.pose = current_pose(problem, unknowns);
  result.V = pose_template(tpl.V, skeleton, W, unknowns.scale, result.pose);
  result.free_bones = problem.z.free_bones;
  if (!result.V.allFinite()) throw NumericalError("pose fit produced non-finite vertices");
  sum.two_sided_mm = two_sided_distance(problem, result.V);
  report_progress(progress, 1.0, "pose fit");
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (summary) *summary = sum;
  return result;
}

}  // namespace bodymodel
