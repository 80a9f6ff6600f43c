#include "assets/helpers.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <random>
#include <string>
#include <tbb/parallel_for.h>
#include <vector>

#include "core/error.h"
#include "core/makehuman.h"
#include "core/point_index.h"
#include "registration/correspondence.h"

namespace bodymodel {

namespace {

// The triangle's orthonormal frame: columns edge a→b, normal × edge, normal.
Eigen::Matrix3d triangle_frame(const Eigen::MatrixX3d& V, const Eigen::Vector3i& t) {
  const Eigen::Vector3d a = V.row(t[0]), b = V.row(t[1]), c = V.row(t[2]);
  Eigen::Vector3d e = b - a, n = (b - a).cross(c - a);
  if (e.norm() == 0 || n.norm() == 0) return Eigen::Matrix3d::Identity();  // degenerate: world axes
  e.normalize();
  n.normalize();
  Eigen::Matrix3d R;
  R.col(0) = e;
  R.col(1) = n.cross(e);
  R.col(2) = n;
  return R;
}

}  // namespace

HelperBinding bind_helpers(const Eigen::MatrixX3d& reference, const Eigen::MatrixX3i& body_F,
                           int body_vertex_count) {
  if (body_vertex_count < 3 || reference.rows() < body_vertex_count)
    throw InputError("bind_helpers: the reference has " + std::to_string(reference.rows()) +
                     " vertices, fewer than the " + std::to_string(body_vertex_count) + " skin vertices");
  if (body_F.rows() == 0 || body_F.maxCoeff() >= body_vertex_count || body_F.minCoeff() < 0)
    throw InputError("bind_helpers: the skin faces must index the first " + std::to_string(body_vertex_count) +
                     " vertices");
  HelperBinding h;
  h.body_vertex_count = body_vertex_count;
  h.vertex_count = static_cast<int>(reference.rows());
  const int n = h.vertex_count - body_vertex_count;
  h.triangle.resize(n, 3);
  h.bary.resize(n, 3);
  h.local.resize(n, 3);
  const Eigen::MatrixX3d skin = reference.topRows(body_vertex_count);
  const auto loc = locate_on_surface(reference.bottomRows(n), skin, body_F);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3i t = body_F.row(loc[i].face).transpose();
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) p += loc[i].bary[k] * skin.row(t[k]).transpose();
    h.triangle.row(i) = t.transpose();
    h.bary.row(i) = loc[i].bary.transpose();
    h.local.row(i) = (triangle_frame(skin, t).transpose() * (reference.row(body_vertex_count + i).transpose() - p)).transpose();
  }
  return h;
}

Eigen::MatrixX3d complete_with_helpers(const HelperBinding& h, const Eigen::MatrixX3d& body) {
  if (body.rows() != h.body_vertex_count)
    throw InputError("complete_with_helpers: expected " + std::to_string(h.body_vertex_count) +
                     " skin vertices, found " + std::to_string(body.rows()));
  Eigen::MatrixX3d out(h.vertex_count, 3);
  out.topRows(h.body_vertex_count) = body;
  for (Eigen::Index i = 0; i < h.triangle.rows(); ++i) {
    const Eigen::Vector3i t = h.triangle.row(i).transpose();
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) p += h.bary(i, k) * body.row(t[k]).transpose();
    out.row(h.body_vertex_count + i) = (p + triangle_frame(body, t) * h.local.row(i).transpose()).transpose();
  }
  return out;
}

}  // namespace bodymodel

namespace bodymodel {

namespace {

MacroSettings random_sliders(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  MacroSettings s;
  s.gender = u(rng);
  s.age = 0.1875 + (1 - 0.1875) * u(rng);  // 10 to 90 years
  s.muscle = u(rng), s.weight = u(rng), s.height = u(rng), s.proportions = u(rng);
  s.cup = u(rng), s.firmness = u(rng);
  const double a = u(rng) + 1e-3, b = u(rng) + 1e-3, c = u(rng) + 1e-3;
  s.african = a / (a + b + c), s.asian = b / (a + b + c), s.caucasian = c / (a + b + c);
  return s;
}

// The weights (summing to one) of skin vertices `nb` that best give helper h over the bodies:
// h − s_0 = Σ_{j≥1} w_j (s_j − s_0), w_0 = 1 − Σ w_j, ridge-regularised.
Eigen::VectorXd helper_weights(const std::vector<Eigen::MatrixX3d>& bodies, int h, const std::vector<int>& nb,
                               double ridge) {
  const int k = static_cast<int>(nb.size()), n = static_cast<int>(bodies.size());
  Eigen::MatrixXd A(3 * n, k - 1);
  Eigen::VectorXd y(3 * n);
  for (int b = 0; b < n; ++b)
    for (int d = 0; d < 3; ++d) {
      const double s0 = bodies[b](nb[0], d);
      for (int j = 1; j < k; ++j) A(3 * b + d, j - 1) = bodies[b](nb[j], d) - s0;
      y(3 * b + d) = bodies[b](h, d) - s0;
    }
  Eigen::MatrixXd N = A.transpose() * A;
  N.diagonal().array() += ridge * N.diagonal().mean() + 1e-12;
  const Eigen::VectorXd z = N.ldlt().solve(A.transpose() * y);
  Eigen::VectorXd w(k);
  w[0] = 1 - z.sum();
  w.tail(k - 1) = z;
  return w;
}

}  // namespace

HelperRegressor fit_helper_regressor(const MakeHuman& mh, const HelperRegressorOptions& o) {
  if (o.bodies < 2 || o.neighbours < 4)
    throw InputError("fit_helper_regressor: needs at least 2 bodies and 4 neighbours");
  std::mt19937_64 rng(o.seed);
  std::vector<Eigen::MatrixX3d> bodies(o.bodies);
  for (auto& B : bodies) B = mh.build_vertices(random_sliders(rng));
  HelperRegressor r;
  r.body_vertex_count = MakeHuman::kBodyVertexCount;
  r.vertex_count = static_cast<int>(bodies[0].rows());
  const Eigen::MatrixX3d reference = mh.build_vertices(MacroSettings{});
  const PointIndex skin(reference.topRows(r.body_vertex_count));
  const int helpers = r.vertex_count - r.body_vertex_count;
  std::vector<std::vector<Eigen::Triplet<double>>> rows(helpers);
  tbb::parallel_for(0, helpers, [&](int i) {
    const int h = r.body_vertex_count + i;
    const std::vector<int> nb = skin.knn(reference.row(h).transpose(), o.neighbours);
    const Eigen::VectorXd w = helper_weights(bodies, h, nb, o.ridge);
    for (size_t j = 0; j < nb.size(); ++j) rows[i].emplace_back(i, nb[j], w[static_cast<Eigen::Index>(j)]);
  });
  std::vector<Eigen::Triplet<double>> all;
  for (const auto& t : rows) all.insert(all.end(), t.begin(), t.end());
  r.R.resize(helpers, r.body_vertex_count);
  r.R.setFromTriplets(all.begin(), all.end());
  return r;
}

Eigen::MatrixX3d complete_with_helpers(const HelperRegressor& r, const Eigen::MatrixX3d& body) {
  if (body.rows() != r.body_vertex_count)
    throw InputError("complete_with_helpers: expected " + std::to_string(r.body_vertex_count) +
                     " skin vertices, found " + std::to_string(body.rows()));
  Eigen::MatrixX3d out(r.vertex_count, 3);
  out.topRows(r.body_vertex_count) = body;
  out.bottomRows(r.vertex_count - r.body_vertex_count) = r.R * body;
  return out;
}

}  // namespace bodymodel
