#include "registration/metrics.h"

#include <algorithm>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/geometry.h"
#include "core/point_index.h"

namespace bodymodel {

double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                               const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Ericson, Real-Time Collision Detection §5.1.5 (closest point on a triangle).
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return (p - a).norm();
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return (p - b).norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return (p - c).norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  const double denom = 1.0 / (va + vb + vc);
  return (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm();
}

Eigen::VectorXd point_to_mesh_distance(const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& V,
                                       const Eigen::MatrixX3i& F, int candidates) {
  std::vector<std::vector<int>> vf(V.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) vf[F(f, k)].push_back(int(f));
  PointIndex index(V);
  Eigen::VectorXd d(P.rows());
  tbb::parallel_for(Eigen::Index(0), P.rows(), [&](Eigen::Index i) {
    const Eigen::Vector3d p = P.row(i).transpose();
    double best = std::numeric_limits<double>::infinity();
    for (int v : index.knn(p, candidates))
      for (int f : vf[v])
        best = std::min(best, point_triangle_distance(p, V.row(F(f, 0)).transpose(),
                                                      V.row(F(f, 1)).transpose(),
                                                      V.row(F(f, 2)).transpose()));
    d(i) = best;
  });
  return d;
}

RegistrationErrors registration_errors(const Eigen::MatrixX3d& reg, const Eigen::MatrixX3d& truth,
                                       const Eigen::MatrixX3i& F,
                                       const Eigen::MatrixX3d& scan_points,
                                       double hole_distance) {
  if (reg.rows() != truth.rows())
    throw InputError("registration errors: the registered mesh has " + std::to_string(reg.rows()) +
                     " vertices, the truth " + std::to_string(truth.rows()));
  RegistrationErrors e;
  e.vertex_errors = (reg - truth).rowwise().norm();
  e.correspondence_mean = e.vertex_errors.mean();
  e.correspondence_max = e.vertex_errors.maxCoeff();
  e.surface_errors = point_to_mesh_distance(reg, truth, F);
  const Eigen::VectorXd& surf = e.surface_errors;
  e.surface_mean = surf.mean();
  e.surface_max = surf.maxCoeff();
  PointIndex scan_index(scan_points);
  double hole_sum = 0;
  e.hole_vertex.assign(truth.rows(), 0);
  for (Eigen::Index i = 0; i < truth.rows(); ++i) {
    double d2 = 0;
    scan_index.nearest(truth.row(i).transpose(), &d2);
    if (d2 > hole_distance * hole_distance) {
      e.hole_vertex[i] = 1;
      ++e.hole_vertices;
      hole_sum += surf(i);
      e.hole_max = std::max(e.hole_max, surf(i));
    }
  }
  e.hole_mean = e.hole_vertices ? hole_sum / e.hole_vertices : 0.0;
  const Eigen::MatrixX3d Nr = face_normals(reg, F), Nt = face_normals(truth, F);
  e.flipped.assign(F.rows(), 0);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (Nr.row(f).dot(Nt.row(f)) < 0) {
      e.flipped[f] = 1;
      ++e.flipped_triangles;
      e.flipped_unseen +=
          e.hole_vertex[F(f, 0)] && e.hole_vertex[F(f, 1)] && e.hole_vertex[F(f, 2)];
    }
  return e;
}

Eigen::MatrixX3d ring_normals(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, int rings) {
  std::vector<std::vector<int>> vertex_faces(V.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int c = 0; c < 3; ++c) vertex_faces[F(f, c)].push_back(int(f));
  // Unnormalised face normals (twice the area): their sum is the area-weighted normal.
  Eigen::MatrixX3d N(F.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    N.row(f) = (V.row(F(f, 1)) - V.row(F(f, 0))).cross(V.row(F(f, 2)) - V.row(F(f, 0)));
  Eigen::MatrixX3d S(F.rows(), 3);
  std::vector<int> stamp(F.rows(), -1), front, next;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    // Triangles within `rings` vertex rings: grow through shared vertices.
    Eigen::RowVector3d sum = N.row(f);
    front.assign(1, int(f));
    stamp[f] = int(f);
    for (int r = 0; r < rings; ++r) {
      next.clear();
      for (int g : front)
        for (int c = 0; c < 3; ++c)
          for (int h : vertex_faces[F(g, c)])
            if (stamp[h] != f) {
              stamp[h] = int(f);
              next.push_back(h);
              sum += N.row(h);
            }
      front.swap(next);
    }
    S.row(f) = sum;
  }
  return S;
}

std::vector<char> locally_folded_triangles(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_rest,
                                           const Eigen::MatrixX3i& F, int rings) {
  if (V.rows() != V_rest.rows() || (F.size() > 0 && F.maxCoeff() >= V.rows()))
    throw InputError("locally_folded_triangles: V (" + std::to_string(V.rows()) + " rows) and V_rest (" +
                     std::to_string(V_rest.rows()) + ") differ or F indexes outside them");
  const auto raw_normals = [&](const Eigen::MatrixX3d& X) {
    Eigen::MatrixX3d N(F.rows(), 3);
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      N.row(f) = (X.row(F(f, 1)) - X.row(F(f, 0))).cross(X.row(F(f, 2)) - X.row(F(f, 0)));
    return N;
  };
  const Eigen::MatrixX3d N = raw_normals(V), N_rest = raw_normals(V_rest);
  const Eigen::MatrixX3d S = ring_normals(V, F, rings), S_rest = ring_normals(V_rest, F, rings);
  std::vector<char> folded(F.rows(), 0);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    folded[f] = N.row(f).dot(S.row(f)) < 0 && N_rest.row(f).dot(S_rest.row(f)) >= 0;
  return folded;
}

const std::vector<std::string>& major_joints() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n = {"root", "spine01", "neck03", "head"};
    for (const char* side : {".L", ".R"})
      for (const char* b : {"clavicle", "upperarm02", "lowerarm02", "upperleg02", "lowerleg02",
                            "foot"})
        n.push_back(std::string(b) + side);
    return n;
  }();
  return names;
}

}  // namespace bodymodel
