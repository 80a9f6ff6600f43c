// The pose fitter's residuals as Ceres cost functions (docs/pose_fit.md#residuals): a template
// sample against its scan target through the sample's kinematic chain (analytic Jacobians), and
// the priors on joint parameters (automatic differentiation).
#pragma once

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <utility>
#include <vector>

#include "core/skeleton.h"

namespace bodymodel {

// The kinematic chain a template vertex depends on: its weighted bones and all their ancestors.
struct Chain {
  std::vector<int> bones;        // skeleton indices, parents before children (bones[0] = root)
  std::vector<int> parent;       // index into `bones` of the parent, -1 for the root
  std::vector<int> slot;         // parameter block of the bone's rotation (see PointResidual), -1 fixed
  std::vector<Eigen::Vector3d> twist_axis;   // unit axis of a 1-DOF bone, else zero
  std::vector<std::pair<int, double>> blend;  // (index into bones, skinning weight)
  std::vector<std::vector<char>> below;       // below[e][a]: blend bone e is a or below it
};

// The cross-product matrix [v]× (3×3) of v.
Eigen::Matrix3d skew(const Eigen::Vector3d& v);

// Rotation R (3×3) of a rotation vector aa (3, rad) and its left Jacobian J (3×3):
// R(φ + dφ) ≈ exp([J dφ]×) R(φ).
void rotation_and_left_jacobian(const double* aa, Eigen::Matrix3d* R, Eigen::Matrix3d* J);

// One template sample against its scan target: residuals [λn·nᵀ(v − c); λp·(v − c)] times
// `weight` (point-to-plane plus a weaker point-to-point term, Hasler et al. 2009 §2.2 "up to
// three constraint equations per point"; mm), with analytic Jacobians.
// Parameter blocks: [0] scale (1), [1] root rotation vector (3), [2] translation (3, mm), then
// the chain's joint parameters (slot ≥ 3, sizes `block_sizes`): a rotation vector (3) or, for a
// 1-DOF bone, an angle about the bone's axis (1). Several bones of a chain may share one block
// (tied groups); every rotation is relative to the parent bone, in world-aligned axes.
class PointResidual : public ceres::CostFunction {
 public:
  // x: the sample's rest position (mm); target, normal: its scan point and unit normal (zero
  // normal: no plane term). chain and skeleton must outlive the residual.
  PointResidual(const Chain* chain, const Skeleton* skeleton, const Eigen::Vector3d& x,
                const Eigen::Vector3d& target, const Eigen::Vector3d& normal, double weight,
                double plane_weight, double point_weight, const std::vector<int>& block_sizes);

  bool Evaluate(double const* const* p, double* r, double** jac) const override;

 private:
  const Chain* chain_;
  const Skeleton* skeleton_;
  Eigen::Vector3d x_, target_, normal_;
  double weight_, plane_weight_, point_weight_;
};

// weight·(aa − centre) (3): a ball joint towards the rest pose (centre 0) or towards the
// landmark-only pose.
struct PriorResidual {
  double weight;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  template <typename T>
  bool operator()(const T* aa, T* r) const {
    for (int k = 0; k < 3; ++k) r[k] = T(weight) * (aa[k] - T(centre[k]));
    return true;
  }
};

// weight·(a − centre) (1): the same for a one-angle parameter.
struct PriorResidual1 {
  double weight;
  double centre = 0.0;
  template <typename T>
  bool operator()(const T* a, T* r) const {
    r[0] = T(weight) * (a[0] - T(centre));
    return true;
  }
};

// weight·(aa · axis) (1): the component of a rotation vector along a unit `axis` (a ball joint's
// twist about its bone; exact for a pure twist).
struct AxisPriorResidual {
  double weight;
  Eigen::Vector3d axis;
  template <typename T>
  bool operator()(const T* aa, T* r) const {
    r[0] = T(weight) * (aa[0] * axis[0] + aa[1] * axis[1] + aa[2] * axis[2]);
    return true;
  }
};

// weight·(a − m) (1): a finger's curl a towards its hand's mean curl m (both rad, both free).
struct CouplingResidual {
  double weight;
  template <typename T>
  bool operator()(const T* a, const T* m, T* r) const {
    r[0] = T(weight) * (a[0] - m[0]);
    return true;
  }
};

}  // namespace bodymodel
