// Procedural fixtures for the registration tests: an icosphere and a capsule-like limb with a
// three-bone skeleton and smooth LBS weights. Units: millimetres.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <vector>

#include "core/geometry.h"
#include "core/mesh.h"
#include "core/skeleton.h"

namespace bodymodel::test {

// Icosphere of radius r centred at the origin, `levels` subdivisions (2562 vertices at 4).
inline Mesh icosphere(double r, int levels) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> v = {{-1, t, 0}, {1, t, 0},  {-1, -t, 0}, {1, -t, 0},
                                    {0, -1, t}, {0, 1, t},  {0, -1, -t}, {0, 1, -t},
                                    {t, 0, -1}, {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  std::vector<Eigen::Vector3i> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                    {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                    {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                    {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (auto& p : v) p.normalize();
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      return mid[key] = int(v.size()) - 1;
    };
    std::vector<Eigen::Vector3i> g;
    for (auto& tri : f) {
      int a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]), c = midpoint(tri[2], tri[0]);
      g.push_back({tri[0], a, c});
      g.push_back({tri[1], b, a});
      g.push_back({tri[2], c, b});
      g.push_back({a, b, c});
    }
    f = g;
  }
  Mesh m;
  m.V.resize(v.size(), 3);
  for (size_t i = 0; i < v.size(); ++i) m.V.row(i) = r * v[i].transpose();
  m.F.resize(f.size(), 3);
  for (size_t i = 0; i < f.size(); ++i) m.F.row(i) = f[i].transpose();
  return m;
}

// An asymmetric closed blob (an icosphere with anisotropic scale and smooth bumps): unlike a
// sphere, it does not let a registration slide freely along its surface.
inline Mesh potato(double r, int levels) {
  Mesh m = icosphere(1.0, levels);
  for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
    const Eigen::Vector3d u = m.V.row(i).transpose();
    const double bump = 1.0 + 0.18 * std::sin(3.0 * u.x() + 1.0) * std::cos(2.0 * u.y()) +
                        0.12 * std::sin(4.0 * u.z() + 2.0 * u.x());
    m.V.row(i) = (r * bump * Eigen::Vector3d(1.4 * u.x(), u.y(), 0.7 * u.z())).transpose();
  }
  return m;
}

// Closed tube along +y from y = 0 to y = length, radius r, `rings` × `segments` grid with
// capped ends (fan to a centre vertex). Outward-oriented.
inline Mesh tube(double length, double r, int rings, int segments) {
  Mesh m;
  const int n = rings * segments + 2;
  m.V.resize(n, 3);
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const double a = 2 * M_PI * j / segments, y = length * i / (rings - 1);
      m.V.row(i * segments + j) << r * std::cos(a), y, -r * std::sin(a);
    }
  const int bottom = rings * segments, top = bottom + 1;
  m.V.row(bottom) << 0, 0, 0;
  m.V.row(top) << 0, length, 0;
  std::vector<Eigen::Vector3i> f;
  for (int i = 0; i + 1 < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const int a = i * segments + j, b = i * segments + (j + 1) % segments;
      const int c = a + segments, d = b + segments;
      f.push_back({a, b, d});
      f.push_back({a, d, c});
    }
  for (int j = 0; j < segments; ++j) {
    const int a = j, b = (j + 1) % segments;
    f.push_back({bottom, b, a});
    const int c = (rings - 1) * segments + j, d = (rings - 1) * segments + (j + 1) % segments;
    f.push_back({top, c, d});
  }
  m.F.resize(f.size(), 3);
  for (size_t i = 0; i < f.size(); ++i) m.F.row(i) = f[i].transpose();
  // Make sure the orientation is outward (positive volume).
  if (signed_volume(m.V, m.F) < 0) m.F.col(1).swap(m.F.col(2));
  return m;
}

// A limb: tube of length 600 mm, radius 50, three bones along y (0–200, 200–400, 400–600)
// with weights blended linearly over ±40 mm around each joint.
struct Limb {
  Mesh mesh;
  Skeleton skeleton;
  SkinWeights weights;
};

inline Limb limb() {
  Limb l;
  l.mesh = tube(600.0, 50.0, 61, 24);
  l.skeleton.names = {"upper", "lower", "hand"};
  l.skeleton.parents = {-1, 0, 1};
  l.skeleton.heads.resize(3, 3);
  l.skeleton.tails.resize(3, 3);
  for (int b = 0; b < 3; ++b) {
    l.skeleton.heads.row(b) << 0, 200.0 * b, 0;
    l.skeleton.tails.row(b) << 0, 200.0 * (b + 1), 0;
  }
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < l.mesh.V.rows(); ++i) {
    const double y = l.mesh.V(i, 1);
    double w[3] = {0, 0, 0};
    auto ramp = [](double y, double joint) {  // 0 below joint − 40, 1 above joint + 40
      return std::clamp((y - joint + 40.0) / 80.0, 0.0, 1.0);
    };
    const double a = ramp(y, 200), b = ramp(y, 400);
    w[0] = 1 - a;
    w[1] = a - b;
    w[2] = b;
    for (int k = 0; k < 3; ++k)
      if (w[k] > 0) t.emplace_back(i, k, w[k]);
  }
  l.weights.resize(l.mesh.V.rows(), 3);
  l.weights.setFromTriplets(t.begin(), t.end());
  return l;
}

// Dense samples of a mesh surface with face normals (a synthetic scan).
inline PointCloud scan_of(const Mesh& m, int count, unsigned seed, double noise_mm = 0.0) {
  SurfaceSamples s = sample_surface(m.V, m.F, count, seed);
  Eigen::MatrixX3d FN = face_normals(m.V, m.F);
  PointCloud c;
  c.P = s.P;
  c.N.resize(s.P.rows(), 3);
  for (Eigen::Index i = 0; i < s.P.rows(); ++i) c.N.row(i) = FN.row(s.face(i));
  if (noise_mm > 0) {
    unsigned state = seed * 2654435761u + 1;
    auto uniform = [&] {
      state = state * 1664525u + 1013904223u;
      return (state >> 8) / double(1 << 24);
    };
    for (Eigen::Index i = 0; i < c.P.rows(); ++i) {
      // Box–Muller along the normal (scanner noise).
      const double g = std::sqrt(-2 * std::log(std::max(uniform(), 1e-12))) *
                       std::cos(2 * M_PI * uniform());
      c.P.row(i) += noise_mm * g * c.N.row(i);
    }
  }
  return c;
}

// Rotation (3×3) by `deg` degrees about `axis` (any length).
inline Eigen::Matrix3d rot(double deg, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(deg * M_PI / 180.0, axis.normalized()).toRotationMatrix();
}

}  // namespace bodymodel::test
