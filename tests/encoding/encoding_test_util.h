// Helpers shared by the encoding tests.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <vector>

#include "core/geometry.h"
#include "core/mesh.h"

namespace bodymodel::testing {

// Max vertex distance between X and Y after the best rigid alignment of X onto Y, over the
// vertices selected by `use` (all if empty); the alignment uses the same vertices.
inline double max_error_after_alignment(const Eigen::MatrixX3d& X, const Eigen::MatrixX3d& Y,
                                        const std::vector<char>& use = {}) {
  Eigen::VectorXd w = Eigen::VectorXd::Ones(X.rows());
  if (!use.empty())
    for (Eigen::Index i = 0; i < X.rows(); ++i) w(i) = use[i] ? 1.0 : 0.0;
  const Eigen::MatrixX3d A = apply(fit_rigid_motion(X, Y, w), X);
  double worst = 0;
  for (Eigen::Index i = 0; i < X.rows(); ++i)
    if (w(i) > 0) worst = std::max(worst, (A.row(i) - Y.row(i)).norm());
  return worst;
}

// Mean over edges of |l − l_ref| / l_ref.
inline double mean_relative_edge_change(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref,
                                        const Eigen::MatrixX2i& E) {
  double sum = 0;
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    const double l = (V.row(E(e, 0)) - V.row(E(e, 1))).norm();
    const double l0 = (V_ref.row(E(e, 0)) - V_ref.row(E(e, 1))).norm();
    sum += std::abs(l - l0) / l0;
  }
  return sum / static_cast<double>(E.rows());
}

// A closed torus grid mesh: `rings` × `segments` vertices (radii R, r), 2·rings·segments
// triangles, counter-clockwise seen from outside.
inline Mesh torus_mesh(int rings, int segments, double R = 100, double r = 30) {
  Mesh m;
  m.V.resize(rings * segments, 3);
  m.F.resize(2 * rings * segments, 3);
  const double pi = 3.14159265358979323846;
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const double u = 2 * pi * i / rings, v = 2 * pi * j / segments;
      m.V.row(i * segments + j) << (R + r * std::cos(v)) * std::cos(u),
          (R + r * std::cos(v)) * std::sin(u), r * std::sin(v);
    }
  int f = 0;
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const int a = i * segments + j, b = ((i + 1) % rings) * segments + j,
                c = ((i + 1) % rings) * segments + (j + 1) % segments,
                d = i * segments + (j + 1) % segments;
      m.F.row(f++) << a, b, c;
      m.F.row(f++) << a, c, d;
    }
  return m;
}

// An open, flat grid of nx × ny vertices with spacing h (a mesh with boundary).
inline Mesh grid_mesh(int nx, int ny, double h = 10) {
  Mesh m;
  m.V.resize(nx * ny, 3);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) m.V.row(j * nx + i) << i * h, j * h, 0;
  m.F.resize(2 * (nx - 1) * (ny - 1), 3);
  int f = 0;
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      const int a = j * nx + i, b = a + 1, c = a + nx + 1, d = a + nx;
      m.F.row(f++) << a, b, c;
      m.F.row(f++) << a, c, d;
    }
  return m;
}

}  // namespace bodymodel::testing
