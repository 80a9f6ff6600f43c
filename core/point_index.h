// Nearest-neighbour search over a fixed point set (nanoflann k-d tree).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

namespace bodymodel {

class PointIndex {
 public:
  // P #P by 3. The points are copied; the index is immutable after construction.
  explicit PointIndex(const Eigen::MatrixX3d& P);
  ~PointIndex();
  PointIndex(PointIndex&&) noexcept;
  PointIndex& operator=(PointIndex&&) noexcept;

  // Index of the closest point to q and the squared distance to it. Thread-safe.
  int nearest(const Eigen::Vector3d& q, double* squared_distance = nullptr) const;
  // The k closest points (sorted by distance). Thread-safe.
  std::vector<int> knn(const Eigen::Vector3d& q, int k,
                       std::vector<double>* squared_distances = nullptr) const;
  // All points within `radius`. Thread-safe.
  std::vector<int> within(const Eigen::Vector3d& q, double radius) const;

  const Eigen::MatrixX3d& points() const;
  int size() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bodymodel
