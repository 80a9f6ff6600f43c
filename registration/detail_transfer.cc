#include "registration/detail_transfer.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/geometry.h"
#include "core/io/npz.h"
#include "core/point_index.h"
#include "registration/nonrigid.h"

namespace bodymodel {

MidEdgeSubdivision mid_edge_subdivision(const Eigen::MatrixX3i& F, int vertex_count) {
  if (F.rows() > 0 && (F.minCoeff() < 0 || F.maxCoeff() >= vertex_count))
    throw InputError("mid-edge subdivision: a face index is outside 0.." +
                     std::to_string(vertex_count - 1));
  MidEdgeSubdivision s;
  s.face_edges.resize(F.rows(), 3);
  std::map<std::pair<int, int>, int> index;
  std::vector<std::pair<int, int>> edges;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const auto key = std::minmax(F(f, k), F(f, (k + 1) % 3));
      auto [it, inserted] = index.emplace(key, int(edges.size()));
      if (inserted) edges.push_back(key);
      s.face_edges(f, k) = it->second;
    }
  s.edges.resize(edges.size(), 2);
  for (size_t e = 0; e < edges.size(); ++e) s.edges.row(e) << edges[e].first, edges[e].second;
  s.F.resize(4 * F.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const int a = F(f, 0), b = F(f, 1), c = F(f, 2);
    const int ab = vertex_count + s.face_edges(f, 0), bc = vertex_count + s.face_edges(f, 1),
              ca = vertex_count + s.face_edges(f, 2);
    s.F.row(4 * f + 0) << a, ab, ca;
    s.F.row(4 * f + 1) << b, bc, ab;
    s.F.row(4 * f + 2) << c, ca, bc;
    s.F.row(4 * f + 3) << ab, bc, ca;
  }
  return s;
}

Eigen::MatrixX3d edge_midpoint_normals(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                                       const MidEdgeSubdivision& sub) {
  const Eigen::MatrixX3d VN = vertex_normals(V, F);
  Eigen::MatrixX3d N(sub.edges.rows(), 3);
  for (Eigen::Index e = 0; e < sub.edges.rows(); ++e) {
    Eigen::Vector3d n = (VN.row(sub.edges(e, 0)) + VN.row(sub.edges(e, 1))).transpose();
    const double len = n.norm();
    if (len > 1e-12) n /= len;
    else n.setZero();
    N.row(e) = n.transpose();
  }
  return N;
}

SurfaceDetail capture_detail(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                             const PointCloud& scan, const DetailTransferOptions& options) {
  if (V.rows() == 0 || F.rows() == 0 || !V.allFinite())
    throw InputError("detail transfer: expected a finite fitted mesh, found " +
                     std::to_string(V.rows()) + " vertices and " + std::to_string(F.rows()) +
                     " triangles");
  if (scan.P.rows() == 0 || !scan.has_normals() || !scan.P.allFinite() || !scan.N.allFinite())
    throw InputError("detail transfer: expected a scan with finite points and unit normals, "
                     "found " + std::to_string(scan.P.rows()) + " points and " +
                     std::to_string(scan.N.rows()) + " normals");
  const MidEdgeSubdivision sub = mid_edge_subdivision(F, int(V.rows()));
  const Eigen::MatrixX3d N = edge_midpoint_normals(V, F, sub);
  const PointIndex index(scan.P);
  SurfaceDetail d;
  d.line_radius =
      options.line_radius > 0 ? options.line_radius : 3.0 * median_point_spacing(index);
  const double r2 = d.line_radius * d.line_radius;
  const double cos_max = std::cos(options.max_normal_angle_deg * M_PI / 180.0);
  const double search = std::sqrt(options.max_offset * options.max_offset + r2);
  // Points whose offsets differ from the one nearest the base surface by more than this belong
  // to another sheet (the other side of a fold or a thin part).
  const double band = std::max(2.0, d.line_radius);
  Eigen::VectorXd edge_offset = Eigen::VectorXd::Zero(sub.edges.rows());
  std::vector<char> found(sub.edges.rows(), 0);
  tbb::parallel_for(Eigen::Index(0), sub.edges.rows(), [&](Eigen::Index e) {
    const Eigen::Vector3d n = N.row(e).transpose();
    if (n.squaredNorm() < 0.5) return;
    const Eigen::Vector3d m =
        0.5 * (V.row(sub.edges(e, 0)) + V.row(sub.edges(e, 1))).transpose();
    // Local frame (u, w) across the normal line.
    Eigen::Vector3d u = n.unitOrthogonal(), w = n.cross(u);
    struct Hit {
      double t, a, b, rho2;
    };
    std::vector<Hit> hits;
    for (int p : index.within(m, search)) {
      const Eigen::Vector3d q = scan.P.row(p).transpose() - m;
      const double t = q.dot(n);
      const Eigen::Vector3d side = q - t * n;
      if (std::abs(t) > options.max_offset || side.squaredNorm() > r2) continue;
      const double c = scan.N.row(p).dot(n.transpose());
      if ((options.unsigned_normals ? std::abs(c) : c) < cos_max) continue;
      hits.push_back({t, side.dot(u), side.dot(w), side.squaredNorm()});
    }
    if (hits.empty()) return;
    // The sheet nearest the base surface (another sheet: the far side of a thin part).
    const double t0 = std::min_element(hits.begin(), hits.end(), [](const Hit& x, const Hit& y) {
                        return std::abs(x.t) < std::abs(y.t);
                      })->t;
    std::erase_if(hits, [&](const Hit& h) { return std::abs(h.t - t0) > band; });
    // The points nearest the line; the offset on the line from a plane t = c0 + c1·a + c2·b
    // fitted to them (a tilted surface biases their plain mean), the mean if too few.
    const size_t keep = std::min<size_t>(hits.size(), 10);
    std::partial_sort(hits.begin(), hits.begin() + keep, hits.end(),
                      [](const Hit& x, const Hit& y) { return x.rho2 < y.rho2; });
    double sum = 0;
    int count = 0;
    for (size_t i = 0; i < keep; ++i) sum += hits[i].t, ++count;
    double value = sum / count;
    if (keep >= 5) {
      Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
      Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
      for (size_t i = 0; i < keep; ++i) {
        const Eigen::Vector3d x(1.0, hits[i].a, hits[i].b);
        A += x * x.transpose();
        rhs += x * hits[i].t;
      }
      const Eigen::Vector3d c = A.ldlt().solve(rhs);
      // Keep the plane only where it is well determined (points around the line, not on one
      // side of it) and agrees with the points.
      if (c.allFinite() && std::abs(c(0) - value) <= band) value = c(0);
    }
    edge_offset(e) = value;
    found[e] = 1;
  });
  d.offsets.resize(F.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) d.offsets(f, k) = edge_offset(sub.face_edges(f, k));
  for (char x : found) (x ? d.edges_found : d.edges_missing) += 1;
  return d;
}

Mesh apply_detail(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                  const SurfaceDetail& detail, double amount) {
  if (detail.offsets.rows() != F.rows())
    throw InputError("detail transfer: the detail was captured on " +
                     std::to_string(detail.offsets.rows()) + " triangles, the mesh has " +
                     std::to_string(F.rows()) + " (expected the same topology)");
  if (!V.allFinite() || !detail.offsets.allFinite())
    throw InputError("detail transfer: non-finite vertices or offsets");
  const MidEdgeSubdivision sub = mid_edge_subdivision(F, int(V.rows()));
  const Eigen::MatrixX3d N = edge_midpoint_normals(V, F, sub);
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(sub.edges.rows());
  Eigen::VectorXd count = Eigen::VectorXd::Zero(sub.edges.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      sum(sub.face_edges(f, k)) += detail.offsets(f, k);
      count(sub.face_edges(f, k)) += 1;
    }
  Mesh out;
  out.V.resize(V.rows() + sub.edges.rows(), 3);
  out.V.topRows(V.rows()) = V;
  for (Eigen::Index e = 0; e < sub.edges.rows(); ++e)
    out.V.row(V.rows() + e) = 0.5 * (V.row(sub.edges(e, 0)) + V.row(sub.edges(e, 1))) +
                              amount * sum(e) / std::max(1.0, count(e)) * N.row(e);
  out.F = sub.F;
  return out;
}

void write_detail(const std::filesystem::path& path, const SurfaceDetail& detail,
                  const Eigen::MatrixX3i& F) {
  Npz z;
  z.put("offsets", Eigen::MatrixXd(detail.offsets));
  z.put("faces", Eigen::MatrixXi(F));
  z.put_int("edges_found", detail.edges_found);
  z.put_int("edges_missing", detail.edges_missing);
  z.put("line_radius", detail.line_radius);
  z.save(path);
}

SurfaceDetail read_detail(const std::filesystem::path& path, const Eigen::MatrixX3i& F) {
  const Npz z = Npz::load(path);
  SurfaceDetail d;
  const Eigen::MatrixXd offsets = z.matrix("offsets");
  const Eigen::MatrixXi faces = z.int_matrix("faces");
  if (offsets.cols() != 3 || faces.cols() != 3 || offsets.rows() != faces.rows())
    throw InputError(path.string() + ": expected 'offsets' and 'faces' of #F by 3, found " +
                     std::to_string(offsets.rows()) + "x" + std::to_string(offsets.cols()) +
                     " and " + std::to_string(faces.rows()) + "x" +
                     std::to_string(faces.cols()));
  if (!offsets.allFinite()) throw InputError(path.string() + ": non-finite offsets");
  if (F.rows() > 0 && (faces.rows() != F.rows() || faces != Eigen::MatrixXi(F)))
    throw InputError(path.string() + ": the detail was captured on another topology (" +
                     std::to_string(faces.rows()) + " triangles), expected the mesh's " +
                     std::to_string(F.rows()) + " triangles with the same faces");
  d.offsets = offsets;
  if (z.has("edges_found")) d.edges_found = int(z.scalar("edges_found"));
  if (z.has("edges_missing")) d.edges_missing = int(z.scalar("edges_missing"));
  if (z.has("line_radius")) d.line_radius = z.scalar("line_radius");
  return d;
}

}  // namespace bodymodel
