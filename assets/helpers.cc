#include "assets/helpers.h"

#include <Eigen/Geometry>
#include <string>

#include "core/error.h"
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
