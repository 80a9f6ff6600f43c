#include "registration/fold_untangle.h"

#include <ceres/ceres.h>
#include <ceres/dynamic_autodiff_cost_function.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "core/error.h"
#include "registration/metrics.h"

namespace bodymodel {

namespace {

int count(const std::vector<char>& flags) {
  return static_cast<int>(std::ranges::count_if(flags, [](char c) { return c != 0; }));
}

// A vertex's motion from x0: along its normal n at weight wn, any direction at weight wt.
struct AnchorResidual {
  Eigen::Vector3d x0, n;
  double wn, wt;
  template <typename T>
  bool operator()(const T* x, T* r) const {
    const T d[3] = {x[0] - x0(0), x[1] - x0(1), x[2] - x0(2)};
    r[0] = std::sqrt(wn) * (d[0] * n(0) + d[1] * n(1) + d[2] * n(2));
    for (int k = 0; k < 3; ++k) r[k + 1] = std::sqrt(wt) * d[k];
    return true;
  }
};

// Triangle f of a small patch (the triangles within the fold test's rings of it, over the patch's
// vertices) whose normal has less than `target` along the patch's area-weighted normal, the
// direction the fold test compares with: the shortfall, scaled to a length. Both normals move
// with the vertices, so a solve cannot satisfy the penalty by turning the reference instead.
struct OrientationResidual {
  std::vector<std::array<int, 3>> faces;  // the patch's triangles, indices into its vertices
  double target, scale;                   // faces[0] is f
  template <typename T>
  bool operator()(T const* const* x, T* r) const {
    T S[3] = {T(0), T(0), T(0)}, n0[3];
    for (size_t g = 0; g < faces.size(); ++g) {
      const T* a = x[faces[g][0]];
      const T* b = x[faces[g][1]];
      const T* c = x[faces[g][2]];
      const T e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
      const T e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
      const T n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                      e1[0] * e2[1] - e1[1] * e2[0]};
      for (int k = 0; k < 3; ++k) {
        S[k] += n[k];
        if (g == 0) n0[k] = n[k];
      }
    }
    using std::sqrt;
    const T len = sqrt(S[0] * S[0] + S[1] * S[1] + S[2] * S[2] + T(1e-30));
    const T d = (n0[0] * S[0] + n0[1] * S[1] + n0[2] * S[2]) / len;
    r[0] = d < T(target) ? scale * (T(target) - d) : T(0);
    return true;
  }
};

double total_area2(const Eigen::MatrixX3d& X, const Eigen::MatrixX3i& F) {
  double a = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    a += (X.row(F(f, 1)) - X.row(F(f, 0))).cross(X.row(F(f, 2)) - X.row(F(f, 0))).norm();
  return a;
}

struct Topology {
  std::vector<std::vector<int>> vertex_faces;
  std::vector<char> exempt;  // the rest template's own folds (its sharp features)
  Eigen::VectorXd target;    // #F: the least normal along the ring normal a triangle must keep
  Eigen::VectorXd area2;     // #F: twice its rest area scaled by the body's area ratio
  double edge = 1;           // mean edge length of V
};

// Cosine of each triangle's normal with its ring normal in X.   #F
Eigen::VectorXd ring_cosines(const Eigen::MatrixX3d& X, const Eigen::MatrixX3i& F, int rings) {
  const Eigen::MatrixX3d S = ring_normals(X, F, rings);
  Eigen::VectorXd c(F.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::RowVector3d n = (X.row(F(f, 1)) - X.row(F(f, 0))).cross(X.row(F(f, 2)) - X.row(F(f, 0)));
    c(f) = n.normalized().dot(S.row(f).normalized());
  }
  return c;
}

Topology topology(const Eigen::MatrixX3d& V, const std::vector<Eigen::MatrixX3d>& rests, const Eigen::MatrixX3i& F,
                  const UntangleOptions& o) {
  Topology t;
  t.vertex_faces.resize(V.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int c = 0; c < 3; ++c) t.vertex_faces[F(f, c)].push_back(int(f));
  // Exempt only where every rest shape has the triangle facing clearly against its ring: a fold
  // one shaped body has and another not (a blend of MakeHuman's targets) is not a feature.
  Eigen::VectorXd least = Eigen::VectorXd::Constant(F.rows(), 1.0), most = -least;
  for (const Eigen::MatrixX3d& R : rests) {
    const Eigen::VectorXd c =
        ring_cosines(R, F, o.rings).unaryExpr([](double x) { return std::isfinite(x) ? x : 0.0; });
    least = least.cwiseMin(c);
    most = most.cwiseMax(c);
  }
  const Eigen::MatrixX3d& rest_V = rests.front();
  const double ratio = total_area2(V, F) / std::max(total_area2(rest_V, F), 1e-300);
  t.exempt.assign(F.rows(), 0);
  t.target.resize(F.rows());
  t.area2.resize(F.rows());
  double edges = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    t.exempt[f] = most(f) < -o.rest_fold_cos;
    // A triangle nearly perpendicular to its ring at rest (an eyelid's edge) need only keep
    // facing along it, not the full margin; one a rest shape has past perpendicular is counted
    // folded against another rest shape (the default body, the fitted one) and is turned back.
    const Eigen::RowVector3d e1 = rest_V.row(F(f, 1)) - rest_V.row(F(f, 0));
    t.area2(f) = e1.cross(rest_V.row(F(f, 2)) - rest_V.row(F(f, 0))).norm() * ratio;
    t.target(f) = std::clamp(least(f), std::min(0.05, o.margin), o.margin) * t.area2(f);
    edges += (V.row(F(f, 1)) - V.row(F(f, 0))).norm();
  }
  t.edge = F.rows() ? edges / double(F.rows()) : 1.0;
  return t;
}

// Vertices marked in `in` grown by `rings` vertex rings (in place).
void grow(std::vector<char>& in, const Eigen::MatrixX3i& F, const Topology& t, int rings) {
  std::vector<int> front;
  for (size_t v = 0; v < in.size(); ++v)
    if (in[v]) front.push_back(int(v));
  for (int r = 0; r < rings; ++r) {
    std::vector<int> next;
    for (int v : front)
      for (int f : t.vertex_faces[v])
        for (int c = 0; c < 3; ++c)
          if (!in[F(f, c)]) in[F(f, c)] = 1, next.push_back(F(f, c));
    front.swap(next);
  }
}

// The folded triangles' vertices grown by `rings` vertex rings.
std::vector<char> grow_region(const std::vector<char>& folded, const Eigen::MatrixX3i& F,
                              const Topology& t, int rings) {
  std::vector<char> in(t.vertex_faces.size(), 0);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (folded[f])
      for (int c = 0; c < 3; ++c) in[F(f, c)] = 1;
  grow(in, F, t, rings);
  return in;
}

// Triangle f and the triangles within `rings` vertex rings of it (f first), as ring_normals sums.
std::vector<int> patch_faces(int f, const Eigen::MatrixX3i& F, const Topology& t, int rings) {
  std::vector<int> out{f}, front{f};
  for (int r = 0; r < rings; ++r) {
    std::vector<int> next;
    for (int g : front)
      for (int c = 0; c < 3; ++c)
        for (int h : t.vertex_faces[F(g, c)])
          if (std::find(out.begin(), out.end(), h) == out.end()) out.push_back(h), next.push_back(h);
    front.swap(next);
  }
  return out;
}

// The orientation penalty of triangle f over its patch's vertices (blocks made constant outside
// the region).
void add_orientation(ceres::Problem& problem, std::vector<std::array<double, 3>>& P, std::vector<char>& used,
                     const Eigen::MatrixX3d& X, int f, const Eigen::MatrixX3i& F, const Topology& t,
                     const UntangleOptions& o) {
  auto* functor = new OrientationResidual;
  std::vector<int> verts;
  for (int g : patch_faces(f, F, t, o.rings)) {
    std::array<int, 3> local{};
    for (int c = 0; c < 3; ++c) {
      const auto it = std::find(verts.begin(), verts.end(), F(g, c));
      local[c] = int(it - verts.begin());
      if (it == verts.end()) verts.push_back(F(g, c));
    }
    functor->faces.push_back(local);
  }
  functor->target = t.target(f);
  // The shortfall in units of the triangle's (twice-)area, times the mean edge: a length.
  functor->scale = std::sqrt(o.orientation_weight) * t.edge / t.area2(f);
  auto* cost = new ceres::DynamicAutoDiffCostFunction<OrientationResidual, 4>(functor);
  std::vector<double*> blocks;
  for (int v : verts) {
    if (!used[v]) {
      P[v] = {X(v, 0), X(v, 1), X(v, 2)};
      used[v] = 2;
      problem.AddParameterBlock(P[v].data(), 3);
      problem.SetParameterBlockConstant(P[v].data());
    }
    cost->AddParameterBlock(3);
    blocks.push_back(P[v].data());
  }
  cost->SetNumResiduals(1);
  problem.AddResidualBlock(cost, nullptr, blocks);
}

// One solve: the region's vertices move; every triangle whose fold test they change is held to
// face along its ring normal.
void solve_region(Eigen::MatrixX3d& X, const Eigen::MatrixX3d& X0, const std::vector<char>& region,
                  const Eigen::MatrixX3i& F, const Topology& t, const UntangleOptions& o) {
  Eigen::MatrixX3d S = ring_normals(X, F, o.rings);
  S.rowwise().normalize();
  std::vector<std::array<double, 3>> P(X.rows());
  std::vector<char> used(X.rows(), 0);
  ceres::Problem problem;
  for (Eigen::Index v = 0; v < X.rows(); ++v) {
    if (!region[v]) continue;
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    for (int f : t.vertex_faces[v]) n += S.row(f).transpose();
    n.normalize();
    P[v] = {X(v, 0), X(v, 1), X(v, 2)};
    used[v] = 1;
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<AnchorResidual, 4, 3>(new AnchorResidual{
                                 X0.row(v).transpose(), n, o.normal_weight, o.tangent_weight}),
                             nullptr, P[v].data());
  }
  std::vector<char> reach = region;
  grow(reach, F, t, o.rings);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (!t.exempt[f] && t.area2(f) > 0 && (reach[F(f, 0)] || reach[F(f, 1)] || reach[F(f, 2)]))
      add_orientation(problem, P, used, X, int(f), F, t, o);
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.max_num_iterations = 50;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  for (Eigen::Index v = 0; v < X.rows(); ++v)
    if (used[v] == 1) X.row(v) << P[v][0], P[v][1], P[v][2];
}

// Triangles facing against their ring normal in X that the rest template does not have so (the
// fold test with the stricter exemption of Topology::exempt).
std::vector<char> folded_now(const Eigen::MatrixX3d& X, const Eigen::MatrixX3i& F, const Topology& t, int rings) {
  const Eigen::MatrixX3d S = ring_normals(X, F, rings);
  std::vector<char> out(F.rows(), 0);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::RowVector3d n = (X.row(F(f, 1)) - X.row(F(f, 0))).cross(X.row(F(f, 2)) - X.row(F(f, 0)));
    out[f] = !t.exempt[f] && n.dot(S.row(f)) < 0;
  }
  return out;
}

}  // namespace

UntangleSummary untangle_local_folds(Eigen::MatrixX3d& V, const std::vector<Eigen::MatrixX3d>& rests,
                                     const Eigen::MatrixX3i& F, const UntangleOptions& o) {
  bool sizes = !rests.empty() && (F.size() == 0 || (F.maxCoeff() < V.rows() && F.minCoeff() >= 0));
  for (const auto& R : rests) sizes = sizes && R.rows() == V.rows();
  if (!sizes)
    throw InputError("untangle_local_folds: V (" + std::to_string(V.rows()) + " rows) and " +
                     std::to_string(rests.size()) +
                     " rest shapes differ in size, none given, or F indexes outside them");
  const Eigen::MatrixX3d& rest_V = rests.front();
  UntangleSummary s;
  s.folded_before = count(locally_folded_triangles(V, rest_V, F, o.rings));
  const Topology t = topology(V, rests, F, o);
  std::vector<char> folded = folded_now(V, F, t, o.rings);
  int left = count(folded);
  const Eigen::MatrixX3d V0 = V;
  for (int round = 0; round < o.rounds && left > 0; ++round) {
    ++s.rounds;
    const std::vector<char> region = grow_region(folded, F, t, o.region_rings + round);
    if (count(region) > o.max_region_vertices) break;
    Eigen::MatrixX3d X = V;
    for (int k = 0; k < o.solves; ++k) solve_region(X, V0, region, F, t, o);
    std::vector<char> now = folded_now(X, F, t, o.rings);
    const double farthest = (X - V0).rowwise().norm().maxCoeff();
    if (count(now) < left && farthest <= o.max_displacement) {
      V = X;
      folded = std::move(now);
      left = count(folded);
    }
  }
  s.folded_after = count(locally_folded_triangles(V, rest_V, F, o.rings));
  const Eigen::VectorXd d = (V - V0).rowwise().norm();
  for (Eigen::Index v = 0; v < d.size(); ++v)
    if (d(v) > 0) ++s.vertices_moved, s.mean_displacement += d(v);
  if (s.vertices_moved) s.mean_displacement /= s.vertices_moved;
  s.max_displacement = d.size() ? d.maxCoeff() : 0.0;
  return s;
}

UntangleSummary untangle_local_folds(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& rest_V,
                                     const Eigen::MatrixX3i& F, const UntangleOptions& o) {
  return untangle_local_folds(V, std::vector<Eigen::MatrixX3d>{rest_V}, F, o);
}

}  // namespace bodymodel
