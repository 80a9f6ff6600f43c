#include "registration/pose_problem.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <set>
#include <string>

#include "core/error.h"
#include "core/geometry.h"
#include "core/rotation.h"
#include "registration/pose_fit.h"

namespace bodymodel {

namespace {

// InputError unless the weights fit template and skeleton, bone 0 is the only root, the scan has
// points and the landmarks are template vertices. Returns the template's vertex count.
int check_inputs(const Mesh& tpl, const Skeleton& skeleton, const SkinWeights& W,
                 const PointCloud& scan, const std::vector<Landmark>& landmarks) {
  skeleton.validate();
  const int n = int(tpl.V.rows()), nb = skeleton.bone_count();
  if (W.rows() != n || W.cols() != nb)
    throw InputError("pose fit: skinning weights are " + std::to_string(W.rows()) + " by " +
                     std::to_string(W.cols()) + ", expected " + std::to_string(n) + " by " +
                     std::to_string(nb));
  if (nb == 0 || skeleton.parents[0] != -1)
    throw InputError("pose fit: expected bone 0 to be the skeleton's root");
  for (int b = 1; b < nb; ++b)
    if (skeleton.parents[b] < 0)
      throw InputError("pose fit: the skeleton has more than one root (bone '" +
                       skeleton.names[b] + "')");
  if (scan.P.rows() == 0) throw InputError("pose fit: the scan has no points");
  check_landmarks(landmarks, n, "pose fit");
  return n;
}

// Per bone: a bone of a late parameter or below one.
std::vector<char> late_bones(const PoseProblem& p) {
  std::vector<char> late_bone(p.bone_count, 0);
  for (int b = 1; b < p.bone_count; ++b) {
    const int k = p.z.free_index[b];
    late_bone[b] = (k >= 0 && p.z.params[k].late) || late_bone[p.skeleton.parents[b]];
  }
  return late_bone;
}

// Landmarks on parts the fit keeps rigid far from a fitted joint (less than half of the vertex's
// weight on bones within landmark_rigid_depth fixed bones of a fitted one: a fingertip with fixed
// fingers) cannot follow the scan's pose of those parts and would drag the free joints; the
// non-rigid fit uses them instead. Counted twice: with the hand stage's (late) parameters fitted,
// and held at rest as they are in the body stages.
void select_landmarks(PoseProblem& p, const std::vector<Landmark>& all_landmarks) {
  std::vector<int> rigid_depth(p.bone_count, 0), rigid_depth_body(p.bone_count, 0);
  for (int b = 1; b < p.bone_count; ++b) {
    const int pb = p.skeleton.parents[b];
    const bool fitted = p.z.free_index[b] >= 0;
    const bool late = fitted && p.z.params[p.z.free_index[b]].late;
    rigid_depth[b] = fitted ? 0 : rigid_depth[pb] + 1;
    rigid_depth_body[b] = fitted && !late ? 0 : rigid_depth_body[pb] + 1;
  }
  for (const Landmark& l : all_landmarks) {
    double movable = 0, movable_body = 0;
    for (SkinWeights::InnerIterator it(p.W, l.vertex); it; ++it) {
      if (it.col() == 0 || rigid_depth[it.col()] <= p.o.landmark_rigid_depth) movable += it.value();
      if (it.col() == 0 || rigid_depth_body[it.col()] <= p.o.landmark_rigid_depth)
        movable_body += it.value();
    }
    if (movable >= 0.5) {
      p.landmarks.push_back(l);
      p.landmark_in_body.push_back(movable_body >= 0.5);
    }
  }
  p.body_landmarks = int(std::count(p.landmark_in_body.begin(), p.landmark_in_body.end(), 1));
}

// PoseProblem::hand_samples and hand_region.
void select_hand_samples(PoseProblem& p, const std::vector<char>& late_bone) {
  p.hand_region.assign(p.vertex_count, 0);
  std::vector<char> hand_bone(p.bone_count, 0);
  for (int b = 1; b < p.bone_count; ++b)
    if (late_bone[b]) hand_bone[b] = hand_bone[p.skeleton.parents[b]] = 1;
  std::vector<int> cand;
  for (int i = 0; i < p.vertex_count; ++i) {
    double wl = 0, wh = 0;
    for (SkinWeights::InnerIterator it(p.W, i); it; ++it) {
      if (late_bone[it.col()]) wl += it.value();
      if (hand_bone[it.col()]) wh += it.value();
    }
    if (wl > 0.25) cand.push_back(i);
    p.hand_region[i] = wh >= 0.5;
  }
  const int hstride = std::max<int>(1, int(cand.size()) / std::max(1, p.o.hand_sample_vertices));
  for (size_t k = 0; k < cand.size(); k += hstride) p.hand_samples.push_back(cand[k]);
}

// PoseProblem::samples (ICP samples, landmarks, hand samples) and on_late.
void select_samples(PoseProblem& p, const std::vector<char>& late_bone) {
  const int stride = std::max(1, p.vertex_count / std::max(1, p.o.sample_vertices));
  for (int i = 0; i < p.vertex_count; i += stride) p.samples.push_back(i);
  p.body_samples = int(p.samples.size());
  for (const Landmark& l : p.landmarks) p.samples.push_back(l.vertex);  // chains for landmarks too
  p.hand_first = int(p.samples.size());
  p.samples.insert(p.samples.end(), p.hand_samples.begin(), p.hand_samples.end());
  p.on_late.assign(p.samples.size(), 0);
  for (size_t si = 0; si < p.samples.size(); ++si) {
    double wl = 0;
    for (SkinWeights::InnerIterator it(p.W, p.samples[si]); it; ++it)
      if (late_bone[it.col()]) wl += it.value();
    p.on_late[si] = wl >= 0.5;
  }
}

// The chain of template vertex i and, per chain block, its parameter (`params`).
Chain chain_of(const PoseProblem& p, int i, std::vector<int>& params) {
  std::set<int> bones;
  std::vector<std::pair<int, double>> blend;
  for (SkinWeights::InnerIterator it(p.W, i); it; ++it) {
    if (it.value() <= 0) continue;
    blend.emplace_back(int(it.col()), it.value());
    for (int b = int(it.col()); b >= 0; b = p.skeleton.parents[b]) bones.insert(b);
  }
  Chain ch;
  ch.bones.assign(bones.begin(), bones.end());  // sorted: parents first
  if (ch.bones.empty() || ch.bones[0] != 0) {   // unweighted vertex: follows the root
    ch.bones.insert(ch.bones.begin(), 0);
    if (blend.empty()) blend.emplace_back(0, 1.0);
  }
  std::vector<int> pos(p.bone_count, -1);
  for (size_t c = 0; c < ch.bones.size(); ++c) pos[ch.bones[c]] = int(c);
  for (size_t c = 0; c < ch.bones.size(); ++c) {
    const int b = ch.bones[c];
    ch.parent.push_back(b == 0 ? -1 : pos[p.skeleton.parents[b]]);
    if (b != 0 && p.z.free_index[b] >= 0) {
      const int k = p.z.free_index[b];
      auto at = std::find(params.begin(), params.end(), k);
      if (at == params.end()) at = params.insert(params.end(), k);
      ch.slot.push_back(3 + int(at - params.begin()));
      ch.twist_axis.push_back(p.z.params[k].one_dof() ? p.z.dof_axis[b] : Eigen::Vector3d::Zero());
    } else {
      ch.slot.push_back(-1);
      ch.twist_axis.push_back(Eigen::Vector3d::Zero());
    }
  }
  for (auto& [b, w] : blend) {
    ch.blend.emplace_back(pos[b], w);
    std::vector<char> below(ch.bones.size(), 0);
    for (int c = pos[b]; c >= 0; c = ch.parent[c]) below[c] = 1;
    ch.below.push_back(std::move(below));
  }
  return ch;
}

}  // namespace

PoseProblem::PoseProblem(const Mesh& template_rest, const Skeleton& skeleton_,
                         const SkinWeights& weights, const PointCloud& scan_,
                         const std::vector<Landmark>& all_landmarks, const PoseFitOptions& options)
    : tpl(template_rest), skeleton(skeleton_), W(weights), scan(scan_), o(options),
      vertex_count(check_inputs(template_rest, skeleton_, weights, scan_, all_landmarks)),
      bone_count(skeleton_.bone_count()),
      z(resolve_pose_parameters(skeleton_, options.free_bones, options.parameters)),
      scan_index(scan_.P),
      cos_min(std::cos(options.max_normal_angle_deg * M_PI / 180.0)) {
  const std::vector<char> late_bone = late_bones(*this);
  select_landmarks(*this, all_landmarks);
  select_hand_samples(*this, late_bone);
  select_samples(*this, late_bone);
  chains.resize(samples.size());
  chain_params.resize(samples.size());
  for (size_t si = 0; si < samples.size(); ++si) chains[si] = chain_of(*this, samples[si], chain_params[si]);
}

double PoseProblem::normal_agreement(int j, const Eigen::RowVector3d& n) const {
  const double c = scan.N.row(j).dot(n);
  return o.unsigned_normals ? std::abs(c) : c;
}

PoseUnknowns initial_unknowns(const PoseProblem& p) {
  // Similarity x → s R x + τ, as root rotation R, scale s, t = τ + sR·h_root − h_root.
  const PoseFitOptions& o = p.o;
  double s = 1.0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d tau;
  if (p.body_landmarks >= 3) {
    Eigen::Matrix3Xd A(3, p.body_landmarks), B(3, p.body_landmarks);
    for (size_t k = 0, c = 0; k < p.landmarks.size(); ++k) {
      if (!p.landmark_in_body[k]) continue;
      A.col(c) = p.tpl.V.row(p.landmarks[k].vertex).transpose();
      B.col(c++) = p.landmarks[k].target;
    }
    if (o.initial_scale > 0) A *= o.initial_scale;
    const Eigen::Matrix4d T = Eigen::umeyama(A, B, o.fit_scale && !(o.initial_scale > 0));
    const Eigen::Matrix3d sR = T.topLeftCorner<3, 3>();
    s = std::cbrt(sR.determinant());
    R = sR / s;
    if (o.initial_scale > 0) s = o.initial_scale;
    tau = T.topRightCorner<3, 1>();
  } else {
    if (o.initial_scale > 0)
      s = o.initial_scale;
    else if (o.fit_scale)
      s = bounding_box_diagonal(p.scan.P) / std::max(1e-12, bounding_box_diagonal(p.tpl.V));
    tau = p.scan.P.colwise().mean().transpose() - s * p.tpl.V.colwise().mean().transpose();
  }
  if (!(s > 0) || !std::isfinite(s) || !R.allFinite() || !tau.allFinite())
    throw InputError("pose fit: could not initialise the global alignment from the landmarks "
                     "(are three or more of them collinear or coincident?)");
  const Eigen::Vector3d root_head = p.skeleton.heads.row(0).transpose();
  PoseUnknowns u;
  u.joints.assign(p.z.count(), Eigen::Vector3d::Zero());
  u.scale = s;
  u.root = rotation_vector_of(R);
  u.translation = tau + s * R * root_head - root_head;
  return u;
}

Pose current_pose(const PoseProblem& p, const PoseUnknowns& u) {
  return pose_of(p.z, u, p.bone_count);
}

Eigen::MatrixX3d posed_template(const PoseProblem& p, const PoseUnknowns& u) {
  return pose_template(p.tpl.V, p.skeleton, p.W, u.scale, current_pose(p, u));
}

void add_parameter_blocks(ceres::Problem& problem, const PoseProblem& p, PoseUnknowns& u) {
  problem.AddParameterBlock(&u.scale, 1);
  problem.AddParameterBlock(u.root.data(), 3);
  problem.AddParameterBlock(u.translation.data(), 3);
  for (int k = 0; k < p.z.count(); ++k)
    problem.AddParameterBlock(u.joints[k].data(), p.z.params[k].one_dof() ? 1 : 3);
}

void add_sample(ceres::Problem& problem, const PoseProblem& p, PoseUnknowns& u, int si,
                const Eigen::Vector3d& target, const Eigen::Vector3d& normal, double weight,
                double plane_weight, double point_weight, ceres::LossFunction* loss) {
  std::vector<int> sizes;
  for (int k : p.chain_params[si]) sizes.push_back(p.z.params[k].one_dof() ? 1 : 3);
  auto* cost = new PointResidual(&p.chains[si], &p.skeleton, p.tpl.V.row(p.samples[si]).transpose(),
                                 target, normal, weight, plane_weight, point_weight, sizes);
  std::vector<double*> blocks = {&u.scale, u.root.data(), u.translation.data()};
  for (int k : p.chain_params[si]) blocks.push_back(u.joints[k].data());
  problem.AddResidualBlock(cost, loss, blocks);
}

void add_joint_prior(ceres::Problem& problem, bool one_dof, double weight,
                     const Eigen::Vector3d& centre, Eigen::Vector3d& aa) {
  if (one_dof)
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<PriorResidual1, 1, 1>(
                                 new PriorResidual1{weight, centre[0]}),
                             nullptr, aa.data());
  else
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<PriorResidual, 3, 3>(
                                 new PriorResidual{weight, centre}),
                             nullptr, aa.data());
}

void solve_pose_problem(ceres::Problem& problem, int max_iterations, int threads) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  so.max_num_iterations = max_iterations;
  so.num_threads = threads;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary cs;
  ceres::Solve(so, &problem, &cs);
}

}  // namespace bodymodel
