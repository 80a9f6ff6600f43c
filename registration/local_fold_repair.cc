#include "registration/local_fold_repair.h"

#include <vector>

#include "core/geometry.h"
#include "registration/metrics.h"

namespace bodymodel {

namespace {

// Area-weighted normal of the triangles within `rings` vertex rings of each triangle.
Eigen::MatrixX3d ring_normals(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, int rings) {
  std::vector<std::vector<int>> vertex_faces(V.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int c = 0; c < 3; ++c) vertex_faces[F(f, c)].push_back(int(f));
  Eigen::MatrixX3d N(F.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    N.row(f) = (V.row(F(f, 1)) - V.row(F(f, 0))).cross(V.row(F(f, 2)) - V.row(F(f, 0)));
  Eigen::MatrixX3d S(F.rows(), 3);
  std::vector<int> stamp(F.rows(), -1), front, next;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
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

int count(const std::vector<char>& v) {
  int n = 0;
  for (char c : v) n += c != 0;
  return n;
}

}  // namespace

LocalFoldRepairSummary repair_local_folds(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& rest_V,
                                          const Eigen::MatrixX3i& F,
                                          const LocalFoldRepairOptions& o) {
  LocalFoldRepairSummary s;
  std::vector<char> folded = locally_folded_triangles(V, rest_V, F, o.rings);
  s.folded_before = s.folded_after = count(folded);
  for (int round = 0; round < o.rounds && s.folded_after > 0; ++round) {
    // Reference normals: a folded triangle should face with its neighbourhood; every other
    // triangle with itself (never "flipped"), so only the folds seed regions.
    const Eigen::MatrixX3d ring = ring_normals(V, F, o.rings);
    const Eigen::MatrixX3d own = face_normals(V, F);
    Eigen::MatrixX3d N_ref = own;
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      if (folded[f]) N_ref.row(f) = ring.row(f);
    FoldRepairOptions fo;
    fo.rings = o.repair_rings;
    fo.passes = o.passes;
    fo.local_similarity = true;
    fo.max_displacement = o.max_displacement;
    repair_folds_against_normals(V, rest_V, N_ref, F, fo);
    folded = locally_folded_triangles(V, rest_V, F, o.rings);
    const int now = count(folded);
    if (now >= s.folded_after) {
      s.folded_after = now;
      break;
    }
    s.folded_after = now;
  }
  return s;
}

}  // namespace bodymodel
