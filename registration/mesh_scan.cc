#include "registration/mesh_scan.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/fold_repair.h"
#include "core/geometry.h"
#include "core/io/atomic_write.h"
#include "core/point_index.h"
#include "registration/metrics.h"

namespace bodymodel {

namespace {

void check_mesh(const Mesh& mesh, const std::string& what) {
  if (mesh.V.rows() == 0 || mesh.F.rows() == 0)
    throw InputError(what + ": expected a triangle mesh, found " + std::to_string(mesh.V.rows()) +
                     " vertices and " + std::to_string(mesh.F.rows()) + " triangles");
  if (!mesh.V.allFinite()) throw InputError(what + ": non-finite vertex coordinates");
  if (mesh.F.minCoeff() < 0 || mesh.F.maxCoeff() >= mesh.V.rows())
    throw InputError(what + ": a face index is outside 0.." + std::to_string(mesh.V.rows() - 1));
}

// Mean, 95th percentile and max of d.
void stats(Eigen::VectorXd d, double* mean, double* p95, double* max) {
  *mean = d.mean();
  *max = d.maxCoeff();
  std::vector<double> s(d.data(), d.data() + d.size());
  const size_t k = std::min(s.size() - 1, size_t(0.95 * double(s.size())));
  std::nth_element(s.begin(), s.begin() + k, s.end());
  *p95 = s[k];
}

}  // namespace

PointCloud mesh_to_scan(const Mesh& mesh, const MeshScanOptions& options, const std::string& what) {
  check_mesh(mesh, what);
  const double sign = signed_volume(mesh.V, mesh.F) < 0 ? -1.0 : 1.0;
  const Eigen::MatrixX3d VN = vertex_normals(mesh.V, mesh.F);
  const Eigen::MatrixX3d FN = face_normals(mesh.V, mesh.F);
  const int n = int(mesh.V.rows());
  const int s = std::max(0, options.samples);
  PointCloud c;
  c.P.resize(n + s, 3);
  c.N.resize(n + s, 3);
  c.P.topRows(n) = mesh.V;
  c.N.topRows(n) = sign * VN;
  if (s > 0) {
    const SurfaceSamples ss = sample_surface(mesh.V, mesh.F, s, options.seed);
    c.P.bottomRows(s) = ss.P;
    for (int i = 0; i < s; ++i) c.N.row(n + i) = sign * FN.row(ss.face(i));
  }
  // Isolated vertices or degenerate faces give zero normals: keep those points out.
  std::vector<int> keep;
  keep.reserve(c.P.rows());
  for (Eigen::Index i = 0; i < c.P.rows(); ++i)
    if (c.N.row(i).allFinite() && c.N.row(i).squaredNorm() > 0.5) keep.push_back(int(i));
  if (keep.size() < size_t(c.P.rows())) {
    PointCloud k;
    k.P.resize(keep.size(), 3);
    k.N.resize(keep.size(), 3);
    for (size_t i = 0; i < keep.size(); ++i) {
      k.P.row(i) = c.P.row(keep[i]);
      k.N.row(i) = c.N.row(keep[i]);
    }
    c = std::move(k);
  }
  if (c.P.rows() == 0) throw InputError(what + ": every triangle is degenerate");
  return c;
}

std::vector<Landmark> read_mesh_landmarks(const std::filesystem::path& path,
                                          const LandmarkTable& table,
                                          const Eigen::MatrixX3d& scan_V) {
  const std::string text = read_text_file(path);
  const std::string expected =
      "expected a JSON object {name: scan vertex index} or {name: [x, y, z]}";
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const std::exception& e) {
    throw InputError(path.string() + ": " + expected + ", parse error: " + e.what());
  }
  if (!j.is_object())
    throw InputError(path.string() + ": " + expected + ", found " + std::string(j.type_name()));
  std::vector<Landmark> out;
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& name = it.key();
    const int vertex = template_landmark_vertex(table, name, path);
    Landmark l;
    l.vertex = vertex;
    l.name = name;
    const auto& a = it.value();
    if (a.is_number_integer()) {
      const long long index = a.get<long long>();
      if (index < 0 || index >= scan_V.rows())
        throw InputError(path.string() + ": landmark '" + name + "' refers to scan vertex " +
                         std::to_string(index) + ", expected 0.." +
                         std::to_string(scan_V.rows() - 1) + " (0-based)");
      l.target = scan_V.row(Eigen::Index(index)).transpose();
    } else if (a.is_array() && a.size() == 3 && a[0].is_number() && a[1].is_number() &&
               a[2].is_number()) {
      l.target = {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
    } else {
      throw InputError(path.string() + ": landmark '" + name +
                       "' must be a scan vertex index or three numbers, found " + a.dump());
    }
    if (!l.target.allFinite())
      throw InputError(path.string() + ": landmark '" + name + "' is not finite");
    out.push_back(std::move(l));
  }
  if (out.empty()) throw InputError(path.string() + ": " + expected + ", found no landmarks");
  return out;
}

int folded_triangles(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& reference_V,
                     const Eigen::MatrixX3i& F) {
  const Eigen::MatrixX3d a = face_normals(V, F), b = face_normals(reference_V, F);
  int count = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (a.row(f).dot(b.row(f)) < 0) ++count;
  return count;
}

int unfold_triangles(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& reference_V,
                     const Eigen::MatrixX3i& F, const UnfoldOptions& options) {
  if (V.rows() != reference_V.rows())
    throw InputError("unfold: the mesh has " + std::to_string(V.rows()) +
                     " vertices, the reference " + std::to_string(reference_V.rows()));
  // The single fold repair (core/fold_repair.h), with no cap on the region's size.
  FoldRepairOptions o;
  o.rings = options.rings;
  o.passes = options.max_rounds;
  o.max_region_vertices = int(V.rows());
  return repair_folds(V, reference_V, F, o).flipped_after;
}

MeshScanDistance mesh_scan_distance(const Eigen::MatrixX3d& reg_V, const Eigen::MatrixX3i& reg_F,
                                    const Mesh& scan, const Eigen::MatrixX3d* reference_V,
                                    int samples, double near_distance) {
  check_mesh(scan, "scan mesh");
  check_mesh({reg_V, reg_F}, "registered mesh");
  MeshScanDistance d;
  const SurfaceSamples rs = sample_surface(reg_V, reg_F, samples, 7);
  const SurfaceSamples ss = sample_surface(scan.V, scan.F, samples, 11);
  stats(point_to_mesh_distance(rs.P, scan.V, scan.F), &d.registered_to_scan_mean,
        &d.registered_to_scan_p95, &d.registered_to_scan_max);
  stats(point_to_mesh_distance(ss.P, reg_V, reg_F), &d.scan_to_registered_mean,
        &d.scan_to_registered_p95, &d.scan_to_registered_max);
  d.two_sided_mean = 0.5 * (d.registered_to_scan_mean + d.scan_to_registered_mean);
  if (reference_V) d.folded_triangles = folded_triangles(reg_V, *reference_V, reg_F);

  // Orientation against the scan: closest scan triangle to each registered triangle's centroid
  // among the triangles around its 8 nearest scan vertices.
  const double sign = signed_volume(scan.V, scan.F) < 0 ? -1.0 : 1.0;
  const Eigen::MatrixX3d RN = face_normals(reg_V, reg_F), SN = sign * face_normals(scan.V, scan.F);
  std::vector<std::vector<int>> vf(scan.V.rows());
  for (Eigen::Index f = 0; f < scan.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) vf[scan.F(f, k)].push_back(int(f));
  const PointIndex index(scan.V);
  std::vector<char> flipped(reg_F.rows(), 0);
  tbb::parallel_for(Eigen::Index(0), reg_F.rows(), [&](Eigen::Index f) {
    const Eigen::Vector3d c =
        (reg_V.row(reg_F(f, 0)) + reg_V.row(reg_F(f, 1)) + reg_V.row(reg_F(f, 2))).transpose() /
        3.0;
    double best = std::numeric_limits<double>::infinity();
    int best_f = -1;
    for (int v : index.knn(c, 8))
      for (int t : vf[v]) {
        const double e = point_triangle_distance(c, scan.V.row(scan.F(t, 0)).transpose(),
                                                 scan.V.row(scan.F(t, 1)).transpose(),
                                                 scan.V.row(scan.F(t, 2)).transpose());
        if (e < best) best = e, best_f = t;
      }
    if (best_f >= 0 && best <= near_distance && RN.row(f).dot(SN.row(best_f)) < 0) flipped[f] = 1;
  });
  for (char x : flipped) d.flipped_against_scan += x;
  return d;
}

}  // namespace bodymodel
