// The bound-constrained Levenberg–Marquardt step the two body fitters share (fit_measurements.cc,
// fit_proportions.cc): an active set (parameters at a bound the gradient pushes further out stay
// there) and a damped Gauss–Newton step on the others, projected into the bounds.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace bodymodel {

// Indices of the parameters free to move: not at a bound that the gradient g = Jᵀr pushes
// further out.
std::vector<int> free_parameters(const Eigen::VectorXd& x, const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                                 const Eigen::VectorXd& g);

// The normal equations of the free columns of J against residual r.
struct FreeSystem {
  std::vector<int> free;
  Eigen::MatrixXd JtJ;
  Eigen::VectorXd g;
};
FreeSystem free_system(const Eigen::MatrixXd& J, const Eigen::VectorXd& r, const std::vector<int>& free);

// x plus the step −(JᵀJ + λ diag(JᵀJ) + 1e-9 I)⁻¹ g on the free parameters, clamped to [lo, hi].
Eigen::VectorXd damped_step(const Eigen::VectorXd& x, const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                            const FreeSystem& s, double lambda);

}  // namespace bodymodel
