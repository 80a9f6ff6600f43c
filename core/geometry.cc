#include "core/geometry.h"

#include <Eigen/Dense>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <unordered_map>

#include "core/error.h"

namespace bodymodel {

namespace {
inline Eigen::Vector3d row(const Eigen::MatrixX3d& V, int i) { return V.row(i).transpose(); }
}  // namespace

Eigen::VectorXd face_areas(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  Eigen::VectorXd A(F.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    Eigen::Vector3d a = row(V, F(f, 0)), b = row(V, F(f, 1)), c = row(V, F(f, 2));
    A(f) = 0.5 * (b - a).cross(c - a).norm();
  }
  return A;
}

Eigen::MatrixX3d face_normals(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  Eigen::MatrixX3d N(F.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    Eigen::Vector3d a = row(V, F(f, 0)), b = row(V, F(f, 1)), c = row(V, F(f, 2));
    Eigen::Vector3d n = (b - a).cross(c - a);
    double len = n.norm();
    N.row(f) = len > 0 ? Eigen::RowVector3d((n / len).transpose()) : Eigen::RowVector3d::Zero();
  }
  return N;
}

Eigen::MatrixX3d vertex_normals(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  Eigen::MatrixX3d N = Eigen::MatrixX3d::Zero(V.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    Eigen::Vector3d a = row(V, F(f, 0)), b = row(V, F(f, 1)), c = row(V, F(f, 2));
    Eigen::RowVector3d n = (b - a).cross(c - a).transpose();  // length = 2·area
    for (int k = 0; k < 3; ++k) N.row(F(f, k)) += n;
  }
  for (Eigen::Index i = 0; i < N.rows(); ++i) {
    double len = N.row(i).norm();
    if (len > 0) N.row(i) /= len;
  }
  return N;
}

SparseMatrixd cotangent_laplacian(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(F.rows() * 12);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      // Angle at corner k is opposite the edge (k+1, k+2).
      int i = F(f, (k + 1) % 3), j = F(f, (k + 2) % 3), o = F(f, k);
      Eigen::Vector3d u = row(V, i) - row(V, o), w = row(V, j) - row(V, o);
      double cross = u.cross(w).norm();
      double cot = cross > 1e-300 ? u.dot(w) / cross : 0.0;
      double h = 0.5 * cot;
      t.emplace_back(i, j, h);
      t.emplace_back(j, i, h);
      t.emplace_back(i, i, -h);
      t.emplace_back(j, j, -h);
    }
  }
  SparseMatrixd L(V.rows(), V.rows());
  L.setFromTriplets(t.begin(), t.end());
  return L;
}

SparseMatrixd mass_matrix_barycentric(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  Eigen::VectorXd A = face_areas(V, F);
  Eigen::VectorXd m = Eigen::VectorXd::Zero(V.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) m(F(f, k)) += A(f) / 3.0;
  SparseMatrixd M(V.rows(), V.rows());
  std::vector<Eigen::Triplet<double>> t;
  for (Eigen::Index i = 0; i < m.size(); ++i) t.emplace_back(i, i, m(i));
  M.setFromTriplets(t.begin(), t.end());
  return M;
}

SparseMatrixd gradient_operator(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  const Eigen::Index nf = F.rows();
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(nf * 9);
  for (Eigen::Index f = 0; f < nf; ++f) {
    Eigen::Vector3d p[3] = {row(V, F(f, 0)), row(V, F(f, 1)), row(V, F(f, 2))};
    Eigen::Vector3d n = (p[1] - p[0]).cross(p[2] - p[0]);
    double dbl_area = n.norm();
    if (dbl_area <= 0) continue;  // degenerate: zero gradient rows
    n /= dbl_area;
    for (int k = 0; k < 3; ++k) {
      // grad of hat function k = n × (edge opposite k) / (2A), edge oriented counter-clockwise.
      Eigen::Vector3d e = p[(k + 2) % 3] - p[(k + 1) % 3];
      Eigen::Vector3d g = n.cross(e) / dbl_area;
      for (int d = 0; d < 3; ++d) t.emplace_back(d * nf + f, F(f, k), g(d));
    }
  }
  SparseMatrixd G(3 * nf, V.rows());
  G.setFromTriplets(t.begin(), t.end());
  return G;
}

namespace {
inline uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<uint64_t>(static_cast<uint32_t>(a)) << 32) | static_cast<uint32_t>(b);
}
}  // namespace

Eigen::MatrixX2i unique_edges(const Eigen::MatrixX3i& F) {
  std::vector<uint64_t> keys;
  keys.reserve(F.rows() * 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) keys.push_back(edge_key(F(f, k), F(f, (k + 1) % 3)));
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  Eigen::MatrixX2i E(keys.size(), 2);
  for (size_t e = 0; e < keys.size(); ++e) {
    E(e, 0) = static_cast<int>(keys[e] >> 32);
    E(e, 1) = static_cast<int>(keys[e] & 0xffffffffu);
  }
  return E;
}

Eigen::MatrixX3i triangle_adjacency(const Eigen::MatrixX3i& F) {
  // Sort half-edges by undirected key; pairs of equal keys are adjacent triangles.
  struct HalfEdge {
    uint64_t key;
    int face, corner;
  };
  std::vector<HalfEdge> h;
  h.reserve(F.rows() * 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      h.push_back({edge_key(F(f, k), F(f, (k + 1) % 3)), static_cast<int>(f), k});
  std::sort(h.begin(), h.end(), [](const HalfEdge& a, const HalfEdge& b) { return a.key < b.key; });
  Eigen::MatrixX3i TT = Eigen::MatrixX3i::Constant(F.rows(), 3, -1);
  for (size_t i = 0; i < h.size();) {
    size_t j = i;
    while (j < h.size() && h[j].key == h[i].key) ++j;
    if (j - i > 2) {
      int a = static_cast<int>(h[i].key >> 32), b = static_cast<int>(h[i].key & 0xffffffffu);
      throw InputError("non-manifold edge (" + std::to_string(a) + ", " + std::to_string(b) +
                       ") is shared by " + std::to_string(j - i) +
                       " triangles (expected at most 2)");
    }
    if (j - i == 2) {
      TT(h[i].face, h[i].corner) = h[i + 1].face;
      TT(h[i + 1].face, h[i + 1].corner) = h[i].face;
    }
    i = j;
  }
  return TT;
}

void check_triangle_mesh(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                         const std::string& what) {
  if (!V.allFinite()) {
    for (Eigen::Index i = 0; i < V.rows(); ++i)
      if (!V.row(i).allFinite())
        throw InputError(what + ": vertex " + std::to_string(i) +
                         " has a NaN or infinite coordinate");
  }
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      if (F(f, k) < 0 || F(f, k) >= V.rows())
        throw InputError(what + ": triangle " + std::to_string(f) + " refers to vertex " +
                         std::to_string(F(f, k)) + " but there are only " +
                         std::to_string(V.rows()) + " vertices");
    }
    if (F(f, 0) == F(f, 1) || F(f, 1) == F(f, 2) || F(f, 0) == F(f, 2))
      throw InputError(what + ": triangle " + std::to_string(f) + " repeats a vertex");
  }
  try {
    triangle_adjacency(F);
  } catch (const InputError& e) {
    throw InputError(what + ": " + e.what());
  }
}

double bounding_box_diagonal(const Eigen::MatrixX3d& V) {
  if (V.rows() == 0) return 0;
  return (V.colwise().maxCoeff() - V.colwise().minCoeff()).norm();
}

double signed_volume(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  double vol = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    Eigen::Vector3d a = row(V, F(f, 0)), b = row(V, F(f, 1)), c = row(V, F(f, 2));
    vol += a.dot(b.cross(c));
  }
  return vol / 6.0;
}

SurfaceSamples sample_surface(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, int count,
                              unsigned seed) {
  Eigen::VectorXd A = face_areas(V, F);
  std::vector<double> cdf(A.size());
  double acc = 0;
  for (Eigen::Index f = 0; f < A.size(); ++f) cdf[f] = (acc += A(f));
  if (acc <= 0) throw InputError("sample_surface: the mesh has zero area");
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  SurfaceSamples s;
  s.P.resize(count, 3);
  s.face.resize(count);
  s.bary.resize(count, 3);
  for (int i = 0; i < count; ++i) {
    double r = u(rng) * acc;
    int f = static_cast<int>(std::lower_bound(cdf.begin(), cdf.end(), r) - cdf.begin());
    f = std::min<int>(f, static_cast<int>(F.rows()) - 1);
    double r1 = std::sqrt(u(rng)), r2 = u(rng);
    Eigen::Vector3d b(1 - r1, r1 * (1 - r2), r1 * r2);
    s.face(i) = f;
    s.bary.row(i) = b.transpose();
    s.P.row(i) = b(0) * V.row(F(f, 0)) + b(1) * V.row(F(f, 1)) + b(2) * V.row(F(f, 2));
  }
  return s;
}

RigidMotion fit_rigid_motion(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B,
                             const Eigen::VectorXd& w_in) {
  if (A.rows() != B.rows() || A.rows() == 0)
    throw InputError("fit_rigid_motion: point sets differ in size or are empty");
  Eigen::VectorXd w = w_in.size() == A.rows() ? w_in : Eigen::VectorXd::Ones(A.rows());
  double ws = w.sum();
  Eigen::RowVector3d ca = (w.asDiagonal() * A).colwise().sum() / ws;
  Eigen::RowVector3d cb = (w.asDiagonal() * B).colwise().sum() / ws;
  Eigen::Matrix3d H = (A.rowwise() - ca).transpose() * w.asDiagonal() * (B.rowwise() - cb);
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  if ((svd.matrixV() * svd.matrixU().transpose()).determinant() < 0) D(2, 2) = -1;
  RigidMotion m;
  m.R = svd.matrixV() * D * svd.matrixU().transpose();
  m.t = cb.transpose() - m.R * ca.transpose();
  return m;
}

Eigen::MatrixX3d apply(const RigidMotion& m, const Eigen::MatrixX3d& A) {
  return ((A * m.R.transpose()).rowwise() + m.t.transpose());
}

}  // namespace bodymodel
