#include "assets/penetration.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/error.h"
#include "assets/fit.h"
#include "core/geometry.h"
#include "registration/correspondence.h"

namespace bodymodel {

namespace {

// Generalised winding number of point p with respect to the triangles F of V (solid angles summed
// over 4π, Van Oosterom–Strackee): about 1 inside a closed outward-wound region, 0 outside, and
// in between near an opening of an open surface.
double winding_number(const Eigen::RowVector3d& p, const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  double sum = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3d a = (V.row(F(f, 0)) - p).transpose(), b = (V.row(F(f, 1)) - p).transpose(),
                          c = (V.row(F(f, 2)) - p).transpose();
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double num = a.dot(b.cross(c));
    const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    sum += 2 * std::atan2(num, den);
  }
  return sum / (4 * M_PI);
}

}  // namespace

void inside_visible_skin(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& body_V, const Eigen::MatrixX3i& body_F,
                         const std::vector<char>& hidden, const Eigen::MatrixX3d& vn, BodyDistance& out) {
  constexpr double kReach = 40;   // mm: a limb's radius and some
  std::vector<Eigen::Index> ask;
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    if (!out.visible[i]) ask.push_back(i);
  const Eigen::MatrixX3i vis = visible_faces(body_F, hidden);
  if (ask.empty() || vis.rows() == 0) return;
  Eigen::MatrixX3d P(static_cast<Eigen::Index>(ask.size()), 3);
  for (size_t k = 0; k < ask.size(); ++k) P.row(static_cast<Eigen::Index>(k)) = points.row(ask[k]);
  const std::vector<SurfaceLocation> loc = locate_on_surface(P, body_V, vis);
  for (size_t k = 0; k < ask.size(); ++k) {
    const SurfaceLocation& l = loc[k];
    if (l.distance > kReach) continue;
    Eigen::RowVector3d p = Eigen::RowVector3d::Zero(), n = Eigen::RowVector3d::Zero();
    for (int j = 0; j < 3; ++j) p += l.bary[j] * body_V.row(vis(l.face, j)), n += l.bary[j] * vn.row(vis(l.face, j));
    if (n.norm() > 0) n.normalize();
    const Eigen::RowVector3d x = P.row(static_cast<Eigen::Index>(k));
    if ((x - p).dot(n) >= 0 || winding_number(x, body_V, vis) < 0.5) continue;
    out.signed_distance[ask[k]] = -l.distance;
    out.normal.row(ask[k]) = n;
    out.visible[ask[k]] = 1;
  }
}

BodyDistance body_distance(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& body_V,
                           const Eigen::MatrixX3i& body_F, const std::vector<char>& hidden) {
  if (!hidden.empty() && static_cast<Eigen::Index>(hidden.size()) != body_V.rows())
    throw InputError("body_distance: " + std::to_string(hidden.size()) + " hidden flags for " +
                     std::to_string(body_V.rows()) + " body vertices");
  BodyDistance out;
  out.signed_distance.resize(points.rows());
  out.normal.resize(points.rows(), 3);
  out.visible.assign(points.rows(), 1);
  if (points.rows() == 0) return out;
  const std::vector<SurfaceLocation> loc = locate_on_surface(points, body_V, body_F);
  const Eigen::MatrixX3d vn = vertex_normals(body_V, body_F);
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const SurfaceLocation& l = loc[i];
    Eigen::RowVector3d p = Eigen::RowVector3d::Zero(), n = Eigen::RowVector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      const int v = body_F(l.face, k);
      p += l.bary[k] * body_V.row(v);
      n += l.bary[k] * vn.row(v);
      if (!hidden.empty() && hidden[v]) out.visible[i] = 0;
    }
    if (n.norm() > 0) n.normalize();
    out.signed_distance[i] = (points.row(i) - p).dot(n) < 0 ? -l.distance : l.distance;
    out.normal.row(i) = n;
  }
  if (!hidden.empty()) inside_visible_skin(points, body_V, body_F, hidden, vn, out);
  return out;
}

Penetration penetration_of(const BodyDistance& d, double depth_mm) {
  Penetration p;
  p.vertices = static_cast<int>(d.signed_distance.size());
  for (Eigen::Index i = 0; i < d.signed_distance.size(); ++i) {
    if (!d.visible[i]) continue;
    if (d.signed_distance[i] < -depth_mm) ++p.penetrating;
    p.max_depth = std::max(p.max_depth, -d.signed_distance[i]);
  }
  p.fraction = p.vertices ? double(p.penetrating) / p.vertices : 0.0;
  return p;
}

namespace {

std::vector<std::vector<int>> neighbours(const Eigen::MatrixX3i& F, Eigen::Index n) {
  std::vector<std::vector<int>> nb(n);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = F(f, k), b = F(f, (k + 1) % 3);
      if (a < 0 || b < 0 || a >= n || b >= n)
        throw InputError("push_garment_out: garment face " + std::to_string(f) + " refers to a vertex outside 0.." +
                         std::to_string(n - 1));
      nb[a].push_back(b);
      nb[b].push_back(a);
    }
  for (auto& v : nb) {
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
  }
  return nb;
}

// Spreads each displacement to its neighbours at half strength per ring, keeping at every
// vertex the largest displacement offered, so the pushed patch tapers into the cloth around it.
void spread(Eigen::MatrixX3d& D, const std::vector<std::vector<int>>& nb, int rings) {
  for (int r = 0; r < rings; ++r) {
    Eigen::MatrixX3d next = D;
    for (size_t i = 0; i < nb.size(); ++i)
      for (int j : nb[i])
        if (0.5 * D.row(j).norm() > next.row(i).norm()) next.row(i) = 0.5 * D.row(j);
    D.swap(next);
  }
}

// options.faces: the centroid and edge midpoints of every face with a corner over visible skin and
// a corner nearer the body than its longest edge (faces wholly over hidden skin are skipped: their
// samples would mostly take body_distance's costly visible-skin pass). A sample deeper than
// face_depth inside visible skin pushes the corners it lies between (barycentric weight > 0) along
// each corner's OWN body normal, as the vertex push does, far enough that the sample reaches the
// clearance along its normal (capped at 3× that depth where a corner's normal turns away). Along
// the corners' own normals the pushes of neighbouring frames point the same way, so a player's
// blend of two frames' corrections stays out (a push along the sample's normal moved corners
// sideways and the blend sagged back in: docs/assets.md#penetration). Writes F (not spread).
// Returns the samples pushed.
int push_face_samples(const Eigen::MatrixX3d& X, const Eigen::MatrixX3i& GF, const BodyDistance& d,
                      const Eigen::MatrixX3d& body_V, const Eigen::MatrixX3i& body_F, const std::vector<char>& hidden,
                      double clearance, double face_depth, Eigen::MatrixX3d& F) {
  static const double kAt[4][3] = {{1 / 3., 1 / 3., 1 / 3.}, {.5, .5, 0}, {0, .5, .5}, {.5, 0, .5}};
  std::vector<Eigen::Index> faces;
  for (Eigen::Index f = 0; f < GF.rows(); ++f) {
    double edge = 0, near = 1e300;
    bool visible = false;
    for (int k = 0; k < 3; ++k) {
      edge = std::max(edge, (X.row(GF(f, k)) - X.row(GF(f, (k + 1) % 3))).norm());
      near = std::min(near, std::abs(d.signed_distance[GF(f, k)]));
      visible |= d.visible[GF(f, k)] != 0;
    }
    if (visible && near < edge + clearance) faces.push_back(f);
  }
  Eigen::MatrixX3d S(static_cast<Eigen::Index>(4 * faces.size()), 3);
  for (size_t i = 0; i < faces.size(); ++i)
    for (int s = 0; s < 4; ++s) {
      Eigen::RowVector3d p = Eigen::RowVector3d::Zero();
      for (int k = 0; k < 3; ++k) p += kAt[s][k] * X.row(GF(faces[i], k));
      S.row(static_cast<Eigen::Index>(4 * i + s)) = p;
    }
  const BodyDistance ds = body_distance(S, body_V, body_F, hidden);
  int pushed = 0;
  for (Eigen::Index j = 0; j < S.rows(); ++j) {
    if (!ds.visible[j] || ds.signed_distance[j] >= -face_depth) continue;
    const double need = clearance - ds.signed_distance[j];
    const double* b = kAt[j % 4];
    const Eigen::Index f = faces[static_cast<size_t>(j / 4)];
    double along = 0;  // how far the sample moves along its normal per mm of every corner's push
    for (int k = 0; k < 3; ++k)
      if (b[k] > 0) along += b[k] * std::max(0.0, d.normal.row(GF(f, k)).dot(ds.normal.row(j)));
    const double m = std::min(need / std::max(along, 1e-9), 3.0 * need);
    for (int k = 0; k < 3; ++k) {
      const int c = GF(f, k);
      if (b[k] > 0 && m > F.row(c).norm()) F.row(c) = m * d.normal.row(c);
    }
    ++pushed;
  }
  return pushed;
}

}  // namespace

PushOutResult push_garment_out(const Eigen::MatrixX3d& G, const Eigen::MatrixX3i& GF,
                               const Eigen::MatrixX3d& body_V, const Eigen::MatrixX3i& body_F,
                               const std::vector<char>& hidden, const PushOutOptions& options,
                               double depth_mm) {
  if (!(options.clearance >= 0) || options.iterations < 1 || options.spread_rings < 0)
    throw InputError("push_garment_out: clearance must be >= 0, iterations >= 1, spread_rings >= 0");
  const auto nb = neighbours(GF, G.rows());
  PushOutResult out;
  out.V = G;
  BodyDistance d = body_distance(out.V, body_V, body_F, hidden);
  out.before = penetration_of(d, depth_mm);
  Eigen::MatrixX3d total = Eigen::MatrixX3d::Zero(G.rows(), 3);
  // With faces: `iterations` rounds with the face samples, then as many with the vertices alone (a
  // face's push moves its corners along the normal at the sample, which can leave a corner inside
  // elsewhere; the vertex rounds take it out again).
  const int rounds = options.faces ? 2 * options.iterations : options.iterations;
  for (int it = 0; it < rounds; ++it) {
    Eigen::MatrixX3d D = Eigen::MatrixX3d::Zero(G.rows(), 3);
    int pushed = 0;
    for (Eigen::Index i = 0; i < G.rows(); ++i)
      if (d.visible[i] && d.signed_distance[i] < options.clearance) {
        D.row(i) = (options.clearance - d.signed_distance[i]) * d.normal.row(i);
        ++pushed;
      }
    Eigen::MatrixX3d F = Eigen::MatrixX3d::Zero(G.rows(), 3);
    if (options.faces && it < options.iterations)
      pushed += push_face_samples(out.V, GF, d, body_V, body_F, hidden, options.clearance, options.face_depth, F);
    if (pushed == 0) break;
    spread(D, nb, options.spread_rings);
    for (Eigen::Index i = 0; i < G.rows(); ++i)  // the faces' pushes are not spread: they are local
      if (F.row(i).squaredNorm() > D.row(i).squaredNorm()) D.row(i) = F.row(i);
    out.V += D;
    total += D;
    d = body_distance(out.V, body_V, body_F, hidden);
  }
  out.after = penetration_of(d, depth_mm);
  for (Eigen::Index i = 0; i < G.rows(); ++i) {
    const double m = total.row(i).norm();
    if (m > 0) ++out.moved;
    out.max_move = std::max(out.max_move, m);
  }
  return out;
}

}  // namespace bodymodel
