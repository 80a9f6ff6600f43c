#include "model/model_rig.h"

#include <Eigen/Dense>
#include "model/format.h"
#include <random>

#include "core/error.h"
#include "core/point_index.h"

namespace bodymodel {

Skeleton ModelRig::skeleton_for(const Eigen::MatrixX3d& V) const {
  if (empty()) throw InputError("the model has no skeleton (it was built without MakeHuman data)");
  if (V.rows() != head_regressor.cols())
    throw InputError(fmt::format("skeleton: body has {} vertices, the rig expects {}", V.rows(),
                                 head_regressor.cols()));
  Skeleton s;
  s.names = bone_names;
  s.parents = parents;
  s.heads = head_regressor * V;
  s.tails = tail_regressor * V;
  return s;
}

namespace {

MacroSettings random_settings(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  MacroSettings s;
  s.gender = u(rng) < 0.5 ? 0.15 * u(rng) : 0.85 + 0.15 * u(rng);
  s.age = 0.45 + 0.4 * u(rng);
  s.muscle = 0.1 + 0.8 * u(rng);
  s.weight = 0.1 + 0.8 * u(rng);
  s.height = 0.1 + 0.8 * u(rng);
  s.proportions = 0.2 + 0.6 * u(rng);
  double a = u(rng) + 0.2, b = u(rng) + 0.2, c = u(rng) + 0.2;
  s.african = a / (a + b + c);
  s.asian = b / (a + b + c);
  s.caucasian = c / (a + b + c);
  return s;
}

// Affine weights (sum 1) of `support` vertices reproducing the joints J (one per body) best.
Eigen::VectorXd fit_weights(const std::vector<Eigen::MatrixX3d>& bodies,
                            const std::vector<Eigen::Vector3d>& joints, const std::vector<int>& support,
                            double ridge) {
  const int k = static_cast<int>(support.size());
  const int n = static_cast<int>(bodies.size());
  // Unknown w (k), constraint Σw = 1 eliminated: w = u + N a with u uniform, N a basis of
  // {Σ = 0}. Minimise Σ_bodies ‖P_b w − j_b‖² + ridge·scale·‖a‖².
  Eigen::MatrixXd A(3 * n, k);
  Eigen::VectorXd y(3 * n);
  for (int b = 0; b < n; ++b)
    for (int i = 0; i < k; ++i)
      for (int c = 0; c < 3; ++c) {
        A(3 * b + c, i) = bodies[b](support[i], c);
        y(3 * b + c) = joints[b](c);
      }
  Eigen::VectorXd u = Eigen::VectorXd::Constant(k, 1.0 / k);
  Eigen::MatrixXd Nb = Eigen::MatrixXd::Zero(k, k - 1);
  for (int i = 0; i < k - 1; ++i) {
    Nb(i, i) = 1;
    Nb(k - 1, i) = -1;
  }
  Eigen::MatrixXd AN = A * Nb;
  Eigen::VectorXd r = y - A * u;
  double scale = AN.squaredNorm() / std::max(1, k - 1);
  Eigen::MatrixXd H = AN.transpose() * AN + ridge * scale * Nb.transpose() * Nb;
  Eigen::VectorXd a = H.ldlt().solve(AN.transpose() * r);
  return u + Nb * a;
}

}  // namespace

ModelRig fit_makehuman_rig(const MakeHuman& mh, const ModelRigOptions& o, ModelRigSummary* summary) {
  std::mt19937_64 rng(o.seed);
  std::vector<Eigen::MatrixX3d> bodies;
  std::vector<Skeleton> skels;
  MakeHuman::Body def = mh.body(MacroSettings{});
  bodies.push_back(def.mesh.V);
  skels.push_back(def.skeleton);
  for (int i = 1; i < o.training_bodies; ++i) {
    MakeHuman::Body b = mh.body(random_settings(rng));
    bodies.push_back(b.mesh.V);
    skels.push_back(b.skeleton);
  }
  const Skeleton& s0 = def.skeleton;
  const int B = s0.bone_count(), V = static_cast<int>(def.mesh.V.rows());
  ModelRig rig;
  rig.bone_names = s0.names;
  rig.parents = s0.parents;
  rig.weights = def.weights;
  PointIndex index(def.mesh.V);
  double max_err = 0, sum_err = 0;
  int count = 0;
  for (int which = 0; which < 2; ++which) {
    std::vector<Eigen::Triplet<double>> trip;
    for (int b = 0; b < B; ++b) {
      Eigen::Vector3d p0 = (which == 0 ? s0.heads : s0.tails).row(b).transpose();
      std::vector<int> support = index.knn(p0, o.support_vertices);
      std::vector<Eigen::Vector3d> joints;
      for (auto& s : skels) joints.push_back((which == 0 ? s.heads : s.tails).row(b).transpose());
      Eigen::VectorXd w = fit_weights(bodies, joints, support, o.ridge);
      for (size_t i = 0; i < support.size(); ++i) trip.emplace_back(b, support[i], w(i));
      for (size_t j = 0; j < bodies.size(); ++j) {
        Eigen::Vector3d q = Eigen::Vector3d::Zero();
        for (size_t i = 0; i < support.size(); ++i) q += w(i) * bodies[j].row(support[i]).transpose();
        double e = (q - joints[j]).norm();
        max_err = std::max(max_err, e);
        sum_err += e;
        ++count;
      }
    }
    auto& R = which == 0 ? rig.head_regressor : rig.tail_regressor;
    R.resize(B, V);
    R.setFromTriplets(trip.begin(), trip.end());
  }
  if (summary) {
    summary->max_joint_error_mm = max_err;
    summary->mean_joint_error_mm = count ? sum_err / count : 0;
  }
  return rig;
}

}  // namespace bodymodel
