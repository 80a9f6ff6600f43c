#include "population/bounded_lm.h"

#include <Eigen/Cholesky>

namespace bodymodel {

std::vector<int> free_parameters(const Eigen::VectorXd& x, const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                                 const Eigen::VectorXd& g) {
  std::vector<int> free;
  for (Eigen::Index j = 0; j < x.size(); ++j) {
    const bool at_lo = x(j) <= lo(j) + 1e-12 && g(j) > 0, at_hi = x(j) >= hi(j) - 1e-12 && g(j) < 0;
    if (!at_lo && !at_hi) free.push_back(static_cast<int>(j));
  }
  return free;
}

FreeSystem free_system(const Eigen::MatrixXd& J, const Eigen::VectorXd& r, const std::vector<int>& free) {
  FreeSystem s;
  s.free = free;
  Eigen::MatrixXd Jf(J.rows(), static_cast<Eigen::Index>(free.size()));
  for (size_t c = 0; c < free.size(); ++c) Jf.col(static_cast<Eigen::Index>(c)) = J.col(free[c]);
  s.JtJ = Jf.transpose() * Jf;
  s.g = Jf.transpose() * r;
  return s;
}

Eigen::VectorXd damped_step(const Eigen::VectorXd& x, const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                            const FreeSystem& s, double lambda) {
  Eigen::MatrixXd A = s.JtJ;
  A.diagonal() += lambda * s.JtJ.diagonal() + Eigen::VectorXd::Constant(static_cast<Eigen::Index>(s.free.size()), 1e-9);
  const Eigen::VectorXd d = -A.ldlt().solve(s.g);
  Eigen::VectorXd xn = x;
  for (size_t c = 0; c < s.free.size(); ++c) xn(s.free[c]) += d(static_cast<Eigen::Index>(c));
  return xn.cwiseMax(lo).cwiseMin(hi);
}

}  // namespace bodymodel
