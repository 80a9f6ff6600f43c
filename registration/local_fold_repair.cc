#include "registration/local_fold_repair.h"

#include <vector>

#include "core/geometry.h"
#include "registration/metrics.h"

namespace bodymodel {

namespace {

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
