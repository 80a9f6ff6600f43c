#include "core/point_index.h"

#include <nanoflann.hpp>

namespace bodymodel {

namespace {
struct Adaptor {
  const Eigen::MatrixX3d* P;
  size_t kdtree_get_point_count() const { return P->rows(); }
  double kdtree_get_pt(size_t i, size_t d) const { return (*P)(i, d); }
  template <class B>
  bool kdtree_get_bbox(B&) const {
    return false;
  }
};
using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Adaptor>,
                                                 Adaptor, 3, int>;
}  // namespace

struct PointIndex::Impl {
  Eigen::MatrixX3d P;
  Adaptor adaptor;
  std::unique_ptr<Tree> tree;
};

PointIndex::PointIndex(const Eigen::MatrixX3d& P) : impl_(std::make_unique<Impl>()) {
  impl_->P = P;
  impl_->adaptor.P = &impl_->P;
  impl_->tree = std::make_unique<Tree>(3, impl_->adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  impl_->tree->buildIndex();
}
PointIndex::~PointIndex() = default;
PointIndex::PointIndex(PointIndex&&) noexcept = default;
PointIndex& PointIndex::operator=(PointIndex&&) noexcept = default;

int PointIndex::nearest(const Eigen::Vector3d& q, double* squared_distance) const {
  if (impl_->P.rows() == 0) return -1;
  int idx = -1;
  double d2 = 0;
  nanoflann::KNNResultSet<double, int> result(1);
  result.init(&idx, &d2);
  impl_->tree->findNeighbors(result, q.data(), nanoflann::SearchParams());
  if (squared_distance) *squared_distance = d2;
  return idx;
}

std::vector<int> PointIndex::knn(const Eigen::Vector3d& q, int k,
                                 std::vector<double>* squared_distances) const {
  k = std::min<int>(k, static_cast<int>(impl_->P.rows()));
  std::vector<int> idx(k);
  std::vector<double> d2(k);
  if (k == 0) return idx;
  nanoflann::KNNResultSet<double, int> result(k);
  result.init(idx.data(), d2.data());
  impl_->tree->findNeighbors(result, q.data(), nanoflann::SearchParams());
  idx.resize(result.size());
  d2.resize(result.size());
  if (squared_distances) *squared_distances = d2;
  return idx;
}

std::vector<int> PointIndex::within(const Eigen::Vector3d& q, double radius) const {
  std::vector<std::pair<int, double>> matches;
  nanoflann::SearchParams params;
  params.sorted = false;
  impl_->tree->radiusSearch(q.data(), radius * radius, matches, params);
  std::vector<int> out;
  out.reserve(matches.size());
  for (auto& m : matches) out.push_back(m.first);
  return out;
}

const Eigen::MatrixX3d& PointIndex::points() const { return impl_->P; }
int PointIndex::size() const { return static_cast<int>(impl_->P.rows()); }

}  // namespace bodymodel
