#include "core/intersection_repair.h"

#include <algorithm>
#include <tuple>
#include <utility>

#include "core/error.h"
#include "core/plausibility.h"

namespace bodymodel {

namespace {

std::vector<std::pair<int, int>> flagged_pairs(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                                               const std::vector<char>& faces) {
  std::vector<std::pair<int, int>> pairs = self_intersecting_triangle_pair_list(V, F);
  if (!faces.empty())
    std::erase_if(pairs, [&](const auto& p) { return !faces[p.first] || !faces[p.second]; });
  return pairs;
}

// One round's push per vertex: each crossing triangle's vertices behind the other's plane move
// out along its normal by half their depth plus half the margin (averaged over the pairs).
Eigen::MatrixX3d crossing_push(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                               const std::vector<std::pair<int, int>>& pairs, double margin) {
  Eigen::MatrixX3d push = Eigen::MatrixX3d::Zero(V.rows(), 3);
  Eigen::VectorXd count = Eigen::VectorXd::Zero(V.rows());
  auto plane = [&](int f, Eigen::RowVector3d& n, Eigen::RowVector3d& c) {
    const Eigen::RowVector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), d = V.row(F(f, 2));
    n = (b - a).cross(d - a).normalized();
    c = (a + b + d) / 3.0;
  };
  for (const auto& [fa, fb] : pairs) {
    Eigen::RowVector3d na, ca, nb, cb;
    plane(fa, na, ca);
    plane(fb, nb, cb);
    if (!na.allFinite() || !nb.allFinite()) continue;
    for (const auto& [f, n, c] : {std::tuple{fa, nb, cb}, std::tuple{fb, na, ca}})
      for (int k = 0; k < 3; ++k) {
        const int v = F(f, k);
        const double depth = -n.dot(V.row(v) - c);
        if (depth <= -0.5 * margin) continue;  // already outside, with half the gap
        push.row(v) += (0.5 * (depth + margin)) * n;
        count(v) += 1;
      }
  }
  for (Eigen::Index v = 0; v < V.rows(); ++v)
    if (count(v) > 0) push.row(v) /= count(v);
  return push;
}

// Spreads the pushes over `rings` rings: a vertex without its own push takes half the mean push
// of its neighbours one ring closer.
void fade(Eigen::MatrixX3d& push, const std::vector<std::vector<int>>& neighbours, int rings) {
  std::vector<int> ring(push.rows(), -1);
  std::vector<int> front;
  for (Eigen::Index v = 0; v < push.rows(); ++v)
    if (push.row(v).squaredNorm() > 0) ring[v] = 0, front.push_back(static_cast<int>(v));
  for (int r = 1; r <= rings && !front.empty(); ++r) {
    std::vector<int> next;
    for (int v : front)
      for (int u : neighbours[v])
        if (ring[u] < 0) ring[u] = r, next.push_back(u);
    for (int u : next) {
      Eigen::RowVector3d sum = Eigen::RowVector3d::Zero();
      int n = 0;
      for (int w : neighbours[u])
        if (ring[w] == r - 1) sum += push.row(w), ++n;
      push.row(u) = 0.5 * sum / std::max(n, 1);
    }
    front = std::move(next);
  }
}

}  // namespace

IntersectionRepairSummary repair_self_intersections(Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                                                    const std::vector<char>& faces,
                                                    const IntersectionRepairOptions& options) {
  if (!faces.empty() && faces.size() != static_cast<size_t>(F.rows()))
    throw InputError("repair_self_intersections: the face flags do not match the faces");
  if (F.size() > 0 && (F.minCoeff() < 0 || F.maxCoeff() >= V.rows()))
    throw InputError("repair_self_intersections: a face indexes outside the vertices");
  std::vector<std::vector<int>> neighbours(V.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      neighbours[F(f, k)].push_back(F(f, (k + 1) % 3));
      neighbours[F(f, (k + 1) % 3)].push_back(F(f, k));
    }
  for (auto& n : neighbours) {
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
  }
  IntersectionRepairSummary summary;
  const Eigen::MatrixX3d start = V;
  std::vector<std::pair<int, int>> pairs = flagged_pairs(V, F, faces);
  summary.pairs_before = static_cast<int>(pairs.size());
  for (int round = 0; round < options.iterations && !pairs.empty(); ++round) {
    Eigen::MatrixX3d push = crossing_push(V, F, pairs, options.margin);
    fade(push, neighbours, options.falloff_rings);
    const Eigen::MatrixX3d moved = V + push;
    if ((moved - start).rowwise().norm().maxCoeff() > options.max_displacement) break;
    V = moved;
    summary.rounds = round + 1;
    pairs = flagged_pairs(V, F, faces);
  }
  summary.pairs_after = static_cast<int>(pairs.size());
  const Eigen::VectorXd moved = (V - start).rowwise().norm();
  summary.vertices_moved = static_cast<int>((moved.array() > 0).count());
  summary.max_displacement = moved.size() ? moved.maxCoeff() : 0.0;
  return summary;
}

}  // namespace bodymodel
