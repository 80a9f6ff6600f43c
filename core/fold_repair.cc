#include "core/fold_repair.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/geometry.h"

namespace bodymodel {

namespace {

Eigen::Vector3d cross_of(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, Eigen::Index f) {
  const Eigen::Vector3d a = V.row(F(f, 0)).transpose();
  return (V.row(F(f, 1)).transpose() - a).cross(V.row(F(f, 2)).transpose() - a);
}

bool flipped(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref, const Eigen::MatrixX3i& F,
             Eigen::Index f) {
  return cross_of(V, F, f).dot(cross_of(V_ref, F, f)) < 0;
}

void check_input(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref, const Eigen::MatrixX3i& F) {
  if (V.rows() != V_ref.rows())
    throw InputError("fold repair: the mesh has " + std::to_string(V.rows()) + " vertices, the reference " +
                     std::to_string(V_ref.rows()));
  if (F.size() > 0 && (F.minCoeff() < 0 || F.maxCoeff() >= V.rows()))
    throw InputError("fold repair: a face index is outside 0.." + std::to_string(V.rows() - 1));
}

// Similarity transform (s, R, reference centroid a, target centroid b) mapping the reference
// points P onto Q in the least-squares sense (Umeyama 1991).
struct Similarity {
  double s = 1;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
};

Similarity fit_similarity(const std::vector<int>& idx, const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& Q) {
  Similarity out;
  if (idx.size() < 3) return out;
  Eigen::RowVector3d a = Eigen::RowVector3d::Zero(), b = Eigen::RowVector3d::Zero();
  for (int i : idx) a += P.row(i), b += Q.row(i);
  a /= double(idx.size());
  b /= double(idx.size());
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  double var = 0;
  for (int i : idx) {
    const Eigen::Vector3d p = (P.row(i) - a).transpose(), q = (Q.row(i) - b).transpose();
    H += q * p.transpose();
    var += p.squaredNorm();
  }
  if (!(var > 0) || !H.allFinite()) return out;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d d(1, 1, 1);
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) d(2) = -1;
  // Points spanning less than a plane (a border on one line) leave the rotation undetermined.
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv(1) > 1e-9 * sv(0))) return out;
  out.R = svd.matrixU() * d.asDiagonal() * svd.matrixV().transpose();
  out.s = (sv.array() * d.array()).sum() / var;
  if (!(out.s > 0) || !std::isfinite(out.s)) out = Similarity{};
  return out;
}

}  // namespace

int count_flipped_triangles(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref,
                            const Eigen::MatrixX3i& F) {
  check_input(V, V_ref, F);
  int count = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (flipped(V, V_ref, F, f)) ++count;
  return count;
}

namespace {

// FoldRepairOptions::smoothing_steps on the flipped faces `bad` (updated); marks moved vertices.
void smooth_remaining_folds(Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const std::vector<std::vector<int>>& nbr,
                            const FoldRepairOptions& o, const std::function<bool(const Eigen::MatrixX3d&, Eigen::Index)>& flipped,
                            std::vector<int>& bad, std::vector<char>& moved, FoldRepairSummary& summary) {
  for (int step = 0; step < o.smoothing_steps && !bad.empty(); ++step) {
    std::vector<int> verts;
    for (int f : bad)
      for (int c = 0; c < 3; ++c) verts.push_back(F(f, c));
    std::sort(verts.begin(), verts.end());
    verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
    Eigen::MatrixX3d W = V;
    for (int i : verts) {
      if (nbr[i].empty() || std::find(o.pinned.begin(), o.pinned.end(), i) != o.pinned.end()) continue;
      Eigen::RowVector3d mean = Eigen::RowVector3d::Zero();
      for (int j : nbr[i]) mean += V.row(j);
      const Eigen::RowVector3d target = 0.5 * V.row(i) + 0.5 * mean / double(nbr[i].size());
      if ((target - V.row(i)).norm() <= o.max_displacement) W.row(i) = target;
    }
    std::vector<int> now;
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      if (flipped(W, f)) now.push_back(int(f));
    if (now.size() >= bad.size()) break;  // only steps that lower the count are kept
    V.swap(W);
    bad.swap(now);
    for (int i : verts) moved[i] = 1;
    ++summary.smoothing_steps;
  }
}

// The repair of repair_folds with the flip test `is_flipped(V, f)` as a parameter.
FoldRepairSummary repair_folds_impl(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref, const Eigen::MatrixX3i& F,
                                    const FoldRepairOptions& o,
                                    const std::function<bool(const Eigen::MatrixX3d&, Eigen::Index)>& flipped_in,
                                    const std::vector<Eigen::Matrix3d>* vertex_frames = nullptr) {
  FoldRepairSummary summary;
  auto flipped = [&](const Eigen::MatrixX3d& X, const Eigen::MatrixX3d&, const Eigen::MatrixX3i&, Eigen::Index f) {
    return flipped_in(X, f);
  };
  const int n = int(V.rows());
  std::vector<int> bad;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (flipped(V, V_ref, F, f)) bad.push_back(int(f));
  summary.flipped_before = summary.flipped_after = int(bad.size());
  if (bad.empty()) return summary;

  // Vertex neighbours and vertex → faces, built once.
  std::vector<std::vector<int>> nbr(n), vf(n);
  {
    const Eigen::MatrixX2i E = unique_edges(F);
    for (Eigen::Index e = 0; e < E.rows(); ++e) {
      nbr[E(e, 0)].push_back(E(e, 1));
      nbr[E(e, 1)].push_back(E(e, 0));
    }
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      for (int c = 0; c < 3; ++c) vf[F(f, c)].push_back(int(f));
  }
  std::vector<char> moved(n, 0);
  std::vector<int> id(n, -1), comp_of(n, -1);
  for (int pass = 0; pass < std::max(1, o.passes) && !bad.empty(); ++pass) {
    ++summary.passes;
    std::vector<char> in(n, 0);
    for (int f : bad)
      for (int c = 0; c < 3; ++c) in[F(f, c)] = 1;
    for (int r = 0; r < o.rings + pass; ++r) {
      std::vector<char> grown = in;
      for (int i = 0; i < n; ++i)
        if (in[i])
          for (int j : nbr[i]) grown[j] = 1;
      in.swap(grown);
    }
    for (int i : o.pinned)
      if (i >= 0 && i < n) in[i] = 0;
    // Connected regions, each solved on its own.
    std::fill(comp_of.begin(), comp_of.end(), -1);
    int components = 0;
    for (int seed = 0; seed < n; ++seed) {
      if (!in[seed] || comp_of[seed] >= 0) continue;
      std::vector<int> region{seed};
      comp_of[seed] = components;
      for (size_t k = 0; k < region.size(); ++k)
        for (int j : nbr[region[k]])
          if (in[j] && comp_of[j] < 0) comp_of[j] = components, region.push_back(j);
      ++components;
      const int m = int(region.size());
      if (m > o.max_region_vertices) continue;
      for (int k = 0; k < m; ++k) id[region[k]] = k;
      // The region's border: fixed neighbours (they glue the solution to the mesh).
      std::vector<int> border;
      for (int i : region)
        for (int j : nbr[i])
          if (!in[j]) border.push_back(j);
      std::sort(border.begin(), border.end());
      border.erase(std::unique(border.begin(), border.end()), border.end());
      Similarity sim;
      if (o.local_similarity) sim = fit_similarity(border.size() >= 3 ? border : region, V_ref, V);
      const Eigen::Matrix3d M = sim.s * sim.R;  // reference → mesh, applied to differences
      // Umbrella system: deg·x_i − Σ_{j in region} x_j = M δ_i + Σ_{j fixed} v_j.
      const double eps = border.empty() ? 1e-6 : 0.0;  // a closed region needs an anchor
      std::vector<Eigen::Triplet<double>> t;
      Eigen::MatrixX3d b(m, 3);
      for (int k = 0; k < m; ++k) {
        const int i = region[k];
        Eigen::Vector3d delta = double(nbr[i].size()) * V_ref.row(i).transpose();
        for (int j : nbr[i]) delta -= V_ref.row(j).transpose();
        const Eigen::Matrix3d& Mi = vertex_frames ? (*vertex_frames)[i] : M;
        Eigen::RowVector3d rhs = (Mi * delta).transpose() + eps * V.row(i);
        t.emplace_back(k, k, double(nbr[i].size()) + eps);
        for (int j : nbr[i]) {
          if (id[j] >= 0) t.emplace_back(k, id[j], -1.0);
          else rhs += V.row(j);
        }
        b.row(k) = rhs;
      }
      SparseMatrixd A(m, m);
      A.setFromTriplets(t.begin(), t.end());
      // Natural (breadth-first growth) order: the regions are grown ring by ring, so their order is
      // already banded. AMD is not used: under AddressSanitizer its permutation was allocated by a
      // non-sanitised copy of Eigen's allocator (most likely one exported by a shared library) and freed by the sanitised
      // one (heap-buffer-overflow in `bodymodel generate`); this solve allocates no permutation.
      Eigen::SimplicialLDLT<SparseMatrixd, Eigen::Lower, Eigen::NaturalOrdering<int>> ldlt(A);
      Eigen::MatrixX3d X;
      if (ldlt.info() == Eigen::Success) X = ldlt.solve(b);
      ++summary.regions_solved;
      if (ldlt.info() == Eigen::Success && X.allFinite()) {
        // Keep the solve only if the triangles it touches have fewer flips.
        std::vector<int> touched;
        for (int i : region)
          for (int f : vf[i]) touched.push_back(f);
        std::sort(touched.begin(), touched.end());
        touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
        int before = 0, after = 0;
        for (int f : touched) before += flipped(V, V_ref, F, f);
        // Largest edge ratio to V_ref over the touched triangles (only with max_edge_ratio).
        auto worst_ratio = [&]() {
          double w = 0;
          for (int f : touched)
            for (int c = 0; c < 3; ++c) {
              const int a = F(f, c), b2 = F(f, (c + 1) % 3);
              const double r0 = (V_ref.row(a) - V_ref.row(b2)).norm();
              if (r0 > 0) w = std::max(w, (V.row(a) - V.row(b2)).norm() / r0);
            }
          return w;
        };
        const double ratio_before = o.max_edge_ratio > 0 ? worst_ratio() : 0;
        Eigen::MatrixX3d old(m, 3);
        for (int k = 0; k < m; ++k) old.row(k) = V.row(region[k]), V.row(region[k]) = X.row(k);
        for (int f : touched) after += flipped(V, V_ref, F, f);
        const bool stretched = o.max_edge_ratio > 0 && after < before &&
                               worst_ratio() > std::max(o.max_edge_ratio, ratio_before);
        double moved_most = 0;
        for (int k = 0; k < m; ++k) moved_most = std::max(moved_most, (X.row(k) - old.row(k)).norm());
        if (((after < before && !stretched) || !o.keep_only_improving) && moved_most <= o.max_displacement) {
          ++summary.regions_kept;
          for (int i : region) moved[i] = 1;
        } else {
          for (int k = 0; k < m; ++k) V.row(region[k]) = old.row(k);
        }
      }
      for (int i : region) id[i] = -1;
    }
    bad.clear();
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      if (flipped(V, V_ref, F, f)) bad.push_back(int(f));
  }
  smooth_remaining_folds(V, F, nbr, o, flipped_in, bad, moved, summary);
  summary.flipped_after = int(bad.size());
  summary.vertices_moved = int(std::count(moved.begin(), moved.end(), 1));
  return summary;
}

}  // namespace

FoldRepairSummary repair_folds(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref, const Eigen::MatrixX3i& F,
                               const FoldRepairOptions& o) {
  check_input(V, V_ref, F);
  return repair_folds_impl(V, V_ref, F, o,
                           [&](const Eigen::MatrixX3d& X, Eigen::Index f) { return flipped(X, V_ref, F, f); });
}

namespace {

void check_normals(const Eigen::MatrixX3d& N_ref, const Eigen::MatrixX3i& F) {
  if (N_ref.rows() != F.rows())
    throw InputError("fold repair: " + std::to_string(N_ref.rows()) + " reference normals for " +
                     std::to_string(F.rows()) + " triangles");
}

}  // namespace

FoldRepairSummary repair_folds_against_normals(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref,
                                               const Eigen::MatrixX3d& N_ref, const Eigen::MatrixX3i& F,
                                               const FoldRepairOptions& o) {
  check_input(V, V_ref, F);
  check_normals(N_ref, F);
  return repair_folds_impl(V, V_ref, F, o, [&](const Eigen::MatrixX3d& X, Eigen::Index f) {
    return cross_of(X, F, f).dot(N_ref.row(f).transpose()) < 0;
  });
}

FoldRepairSummary repair_folds_against_normals(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref,
                                               const Eigen::MatrixX3d& N_ref,
                                               const std::vector<Eigen::Matrix3d>& vertex_frames,
                                               const Eigen::MatrixX3i& F, const FoldRepairOptions& o) {
  check_input(V, V_ref, F);
  check_normals(N_ref, F);
  if (vertex_frames.size() != static_cast<size_t>(V.rows()))
    throw InputError("fold repair: " + std::to_string(vertex_frames.size()) + " vertex frames for " +
                     std::to_string(V.rows()) + " vertices");
  for (const auto& R : vertex_frames)
    if (!R.allFinite()) throw InputError("fold repair: a vertex frame is not finite");
  return repair_folds_impl(
      V, V_ref, F, o,
      [&](const Eigen::MatrixX3d& X, Eigen::Index f) { return cross_of(X, F, f).dot(N_ref.row(f).transpose()) < 0; },
      &vertex_frames);
}

int count_flipped_triangles_against_normals(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& N_ref,
                                            const Eigen::MatrixX3i& F) {
  check_input(V, V, F);
  check_normals(N_ref, F);
  int count = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (cross_of(V, F, f).dot(N_ref.row(f).transpose()) < 0) ++count;
  return count;
}

}  // namespace bodymodel
