// Small meshes made in code for unit tests (no data files needed).
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>

#include "core/mesh.h"

namespace bodymodel::fixtures {

// Icosphere-like UV sphere: `rings` latitude bands, `segments` longitudes, outward faces.
inline Mesh uv_sphere(double radius, int rings, int segments) {
  Mesh m;
  const int nv = 2 + (rings - 1) * segments;
  m.V.resize(nv, 3);
  m.V.row(0) << 0, radius, 0;
  for (int r = 1; r < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      double th = M_PI * r / rings, ph = 2 * M_PI * s / segments;
      m.V.row(1 + (r - 1) * segments + s) << radius * std::sin(th) * std::cos(ph),
          radius * std::cos(th), radius * std::sin(th) * std::sin(ph);
    }
  m.V.row(nv - 1) << 0, -radius, 0;
  std::vector<Eigen::Vector3i> f;
  auto id = [&](int r, int s) { return 1 + (r - 1) * segments + (s % segments); };
  for (int s = 0; s < segments; ++s) f.emplace_back(0, id(1, s + 1), id(1, s));
  for (int r = 1; r < rings - 1; ++r)
    for (int s = 0; s < segments; ++s) {
      f.emplace_back(id(r, s), id(r, s + 1), id(r + 1, s));
      f.emplace_back(id(r, s + 1), id(r + 1, s + 1), id(r + 1, s));
    }
  for (int s = 0; s < segments; ++s) f.emplace_back(nv - 1, id(rings - 1, s), id(rings - 1, s + 1));
  m.F.resize(f.size(), 3);
  for (size_t i = 0; i < f.size(); ++i) m.F.row(i) = f[i].transpose();
  return m;
}

// Closed cylinder along +y from y=0 to y=height, `segments` sides, `stacks` bands, capped.
inline Mesh cylinder(double radius, double height, int segments, int stacks) {
  Mesh m;
  const int ring = segments;
  const int nv = (stacks + 1) * ring + 2;
  m.V.resize(nv, 3);
  for (int k = 0; k <= stacks; ++k)
    for (int s = 0; s < ring; ++s) {
      double ph = 2 * M_PI * s / segments;
      m.V.row(k * ring + s) << radius * std::cos(ph), height * k / stacks, radius * std::sin(ph);
    }
  const int bottom = nv - 2, top = nv - 1;
  m.V.row(bottom) << 0, 0, 0;
  m.V.row(top) << 0, height, 0;
  std::vector<Eigen::Vector3i> f;
  auto id = [&](int k, int s) { return k * ring + (s % ring); };
  for (int k = 0; k < stacks; ++k)
    for (int s = 0; s < ring; ++s) {
      f.emplace_back(id(k, s), id(k + 1, s), id(k, s + 1));
      f.emplace_back(id(k, s + 1), id(k + 1, s), id(k + 1, s + 1));
    }
  for (int s = 0; s < ring; ++s) {
    f.emplace_back(bottom, id(0, s), id(0, s + 1));
    f.emplace_back(top, id(stacks, s + 1), id(stacks, s));
  }
  m.F.resize(f.size(), 3);
  for (size_t i = 0; i < f.size(); ++i) m.F.row(i) = f[i].transpose();
  return m;
}

// Axis-aligned box [0,a]×[0,b]×[0,c] with outward faces (12 triangles).
inline Mesh box(double a, double b, double c) {
  Mesh m;
  m.V.resize(8, 3);
  for (int i = 0; i < 8; ++i) m.V.row(i) << (i & 1 ? a : 0), (i & 2 ? b : 0), (i & 4 ? c : 0);
  m.F.resize(12, 3);
  m.F << 0, 2, 1, 1, 2, 3,   // z = 0
      4, 5, 6, 5, 7, 6,      // z = c
      0, 1, 4, 1, 5, 4,      // y = 0
      2, 6, 3, 3, 6, 7,      // y = b
      0, 4, 2, 2, 4, 6,      // x = 0
      1, 3, 5, 3, 7, 5;      // x = a
  return m;
}

// A fresh temporary folder removed at destruction.
struct TempDir {
  std::filesystem::path path;
  TempDir() {
    static std::mt19937_64 rng(std::random_device{}());
    path = std::filesystem::temp_directory_path() / ("bodymodel_test_" + std::to_string(rng()));
    std::filesystem::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  std::filesystem::path operator/(const std::string& name) const { return path / name; }
};

}  // namespace bodymodel::fixtures
