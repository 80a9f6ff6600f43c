#include "markers/simulate.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/geometry.h"
#include "core/point_index.h"

namespace bodymodel {
namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Triangle = Kernel::Triangle_3;
using Iterator = std::vector<Triangle>::const_iterator;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, CGAL::AABB_triangle_primitive<Kernel, Iterator>>>;

struct Placement {
  Eigen::VectorXi face;
  Eigen::MatrixX3d bary;
};

// Farthest-point sampling of dense area-uniform surface samples: markers about evenly spread.
Placement place_markers(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, int n, unsigned seed) {
  SurfaceSamples all = sample_surface(V, F, std::max(20000, 40 * n), seed);
  // No markers on surfaces facing the floor (soles): no capture puts them there, no camera sees them.
  const Eigen::MatrixX3d FN = face_normals(V, F);
  SurfaceSamples s;
  std::vector<int> keep;
  for (int k = 0; k < all.P.rows(); ++k)
    if (FN(all.face(k), 1) > -0.7) keep.push_back(k);
  s.P = all.P(keep, Eigen::all);
  s.face = all.face(keep);
  s.bary = all.bary(keep, Eigen::all);
  const int S = static_cast<int>(s.P.rows());
  if (n > S) throw InputError("markers simulate: more markers than surface samples");
  Eigen::VectorXd d = Eigen::VectorXd::Constant(S, std::numeric_limits<double>::infinity());
  Placement p{Eigen::VectorXi(n), Eigen::MatrixX3d(n, 3)};
  int next = 0;
  for (int k = 0; k < n; ++k) {
    p.face(k) = s.face(next);
    p.bary.row(k) = s.bary.row(next);
    d = d.cwiseMin((s.P.rowwise() - s.P.row(next)).rowwise().squaredNorm());
    d.maxCoeff(&next);
  }
  return p;
}

// The mesh at time s (in mesh frames), Catmull-Rom between the frames, in mm.
Eigen::MatrixX3d mesh_at(const std::vector<Eigen::MatrixX3d>& frames, double s, double mm) {
  const int n = static_cast<int>(frames.size());
  const int i = std::min(static_cast<int>(std::floor(s)), n - 1);
  const double u = s - i;
  auto at = [&](int k) -> const Eigen::MatrixX3d& { return frames[std::clamp(k, 0, n - 1)]; };
  if (u <= 0) return at(i) * mm;
  const double u2 = u * u, u3 = u2 * u;
  return mm * (at(i - 1) * (-0.5 * u3 + u2 - 0.5 * u) + at(i) * (1.5 * u3 - 2.5 * u2 + 1) +
               at(i + 1) * (-1.5 * u3 + 2 * u2 + 0.5 * u) + at(i + 2) * (0.5 * u3 - 0.5 * u2));
}

struct FrameMarkers {
  Eigen::MatrixX3d P, N;  // marker centres (offset by the radius) and surface normals
};

FrameMarkers markers_on(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const Placement& pl, double radius) {
  const Eigen::MatrixX3d VN = vertex_normals(V, F);
  const int n = static_cast<int>(pl.face.size());
  FrameMarkers m{Eigen::MatrixX3d(n, 3), Eigen::MatrixX3d(n, 3)};
  for (int k = 0; k < n; ++k) {
    Eigen::RowVector3d p = Eigen::RowVector3d::Zero(), nn = Eigen::RowVector3d::Zero();
    for (int c = 0; c < 3; ++c) {
      p += pl.bary(k, c) * V.row(F(pl.face(k), c));
      nn += pl.bary(k, c) * VN.row(F(pl.face(k), c));
    }
    m.N.row(k) = nn.normalized();
    m.P.row(k) = p + radius * m.N.row(k);
  }
  return m;
}

// Seen by at least two cameras it faces, with a clear line of sight past the body.
std::vector<char> visible(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const FrameMarkers& m,
                          const std::vector<Eigen::Vector3d>& cameras, double cos_max) {
  std::vector<Triangle> tris;
  tris.reserve(F.rows());
  auto pt = [&](int v) { return Kernel::Point_3(V(v, 0), V(v, 1), V(v, 2)); };
  for (int f = 0; f < F.rows(); ++f) tris.emplace_back(pt(F(f, 0)), pt(F(f, 1)), pt(F(f, 2)));
  Tree tree(tris.begin(), tris.end());
  std::vector<char> seen(m.P.rows(), 0);
  tbb::parallel_for(0, static_cast<int>(m.P.rows()), [&](int k) {
    int count = 0;
    const Eigen::Vector3d p = m.P.row(k).transpose(), n = m.N.row(k).transpose();
    for (const auto& c : cameras) {
      const Eigen::Vector3d d = (c - p).normalized();
      if (n.dot(d) < cos_max) continue;
      const Eigen::Vector3d a = p + n * 0.5;  // just off the marker, so its own patch is not a hit
      if (tree.do_intersect(Kernel::Segment_3(Kernel::Point_3(a.x(), a.y(), a.z()), Kernel::Point_3(c.x(), c.y(), c.z()))))
        continue;
      if (++count >= 2) break;
    }
    seen[k] = count >= 2;
  });
  return seen;
}

std::vector<Eigen::Vector3d> camera_ring(const Eigen::MatrixX3d& V0, const SimulateOptions& o) {
  const Eigen::RowVector3d centre = V0.colwise().mean();
  const double floor = V0.col(1).minCoeff();
  std::vector<Eigen::Vector3d> cams;
  for (int c = 0; c < o.cameras; ++c) {
    const double a = 2 * M_PI * c / o.cameras;
    cams.emplace_back(centre.x() + o.camera_distance_mm * std::cos(a), floor + o.camera_height_mm,
                      centre.z() + o.camera_distance_mm * std::sin(a));
  }
  return cams;
}

void check_options(const std::vector<Eigen::MatrixX3d>& frames, const Eigen::MatrixX3i& F, const SimulateOptions& o) {
  if (frames.size() < 2) throw InputError("markers simulate: needs at least 2 mesh frames");
  for (const auto& V : frames)
    if (V.rows() != frames[0].rows()) throw InputError("markers simulate: the mesh frames differ in vertex count");
  check_triangle_mesh(frames[0], F, "markers simulate: first frame");
  if (o.markers < 4 || o.markers > 5000) throw InputError("markers simulate: --markers must be 4…5000");
  if (!(o.rate > 0 && o.mesh_rate > 0 && o.rate >= o.mesh_rate)) throw InputError("markers simulate: needs rate ≥ mesh rate > 0");
  if (o.cameras < 2) throw InputError("markers simulate: needs at least 2 cameras");
  const double frames_out = (frames.size() - 1) * o.rate / o.mesh_rate + 1;
  if (frames_out > 65535 || frames_out * o.markers > 2e7)
    throw InputError("markers simulate: " + std::to_string(static_cast<long>(frames_out)) + " frames of " +
                     std::to_string(o.markers) + " markers is too large (at most 65 535 frames, 20 million samples)");
  if (!(o.missing >= 0 && o.missing < 0.9)) throw InputError("markers simulate: --missing must be in [0, 0.9)");
  if (o.gap_min < 1 || o.gap_max < o.gap_min) throw InputError("markers simulate: needs 1 ≤ gap-min ≤ gap-max");
  if (!(o.broken >= 0 && o.broken <= 1) || o.ghosts < 0) throw InputError("markers simulate: --broken in [0, 1], --ghosts ≥ 0");
}

// Random gaps of gap_min…gap_max frames (never in frame 0) until `target` of the samples are missing.
int add_gaps(std::vector<std::vector<char>>& seen, double target, int gmin, int gmax, std::mt19937& rng) {
  const int T = static_cast<int>(seen.size()), M = static_cast<int>(seen[0].size());
  long missing = 0;
  for (const auto& row : seen) missing += std::count(row.begin(), row.end(), 0);
  const long want = static_cast<long>(std::ceil(target * double(T) * M));
  int gaps = 0;
  if (T < gmin + 2) return 0;
  std::uniform_int_distribution<int> marker(0, M - 1), length(gmin, std::min(gmax, T - 2));
  for (int tries = 0; missing < want && tries < 1000000; ++tries) {
    const int m = marker(rng), len = length(rng);
    const int start = std::uniform_int_distribution<int>(1, T - len)(rng);
    for (int t = start; t < start + len; ++t)
      if (seen[t][m]) seen[t][m] = 0, ++missing;
    ++gaps;
  }
  return gaps;
}

}  // namespace

namespace {

// The truth at every capture frame and what the cameras saw (frame 0 complete).
void trace(const std::vector<Eigen::MatrixX3d>& frames, const Eigen::MatrixX3i& F, const SimulateOptions& o,
           const Placement& pl, SimulatedCapture& out, std::vector<std::vector<char>>& seen,
           const std::function<void(double)>& progress) {
  const double step = o.mesh_rate / o.rate;
  const int T = static_cast<int>(std::floor((frames.size() - 1) / step + 1e-9)) + 1;
  const int M = o.markers;
  const auto cams = camera_ring(frames[0] * o.mm_per_unit, o);
  out.truth.xyz.resize(T, 3 * M);
  seen.assign(T, std::vector<char>(M, 1));
  long occluded = 0;
  for (int t = 0; t < T; ++t) {
    const Eigen::MatrixX3d V = mesh_at(frames, t * step, o.mm_per_unit);
    const FrameMarkers m = markers_on(V, F, pl, o.marker_radius_mm);
    for (int k = 0; k < M; ++k) out.truth.set(t, k, m.P.row(k).transpose());
    if (t > 0) seen[t] = visible(V, F, m, cams, std::cos(o.max_view_angle_deg * M_PI / 180));
    occluded += std::count(seen[t].begin(), seen[t].end(), 0);
    if (progress) progress(double(t + 1) / T);
  }
  out.occluded = double(occluded) / (double(T) * M);
}

// The seen samples with noise, cut into pieces: a marker keeps its label until its first gap
// (or break); every later run of samples is an unlabelled piece.
void cut_pieces(const SimulateOptions& o, const std::vector<std::vector<char>>& seen, const std::vector<int>& break_at,
                std::mt19937& rng, SimulatedCapture& out) {
  const int T = out.truth.frame_count(), M = out.truth.marker_count();
  std::normal_distribution<double> noise(0, o.noise_mm);
  std::vector<std::pair<int, std::vector<Eigen::Vector3d>>> extra;  // (marker, samples) of later pieces
  Eigen::MatrixXd first = Eigen::MatrixXd::Constant(T, 3 * M, std::numeric_limits<double>::quiet_NaN());
  for (int m = 0; m < M; ++m) {
    int run = 0;
    for (int t = 0; t < T; ++t) {
      if (!seen[t][m]) continue;
      if (t > 0 && (!seen[t - 1][m] || t == break_at[m])) {
        ++run;
        out.pieces.push_back({"", m, t, t});
        extra.emplace_back(m, std::vector<Eigen::Vector3d>(T, Eigen::Vector3d::Constant(std::nan(""))));
      }
      const Eigen::Vector3d p = out.truth.at(t, m) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      if (run == 0) first.block<1, 3>(t, 3 * m) = p.transpose();
      else extra.back().second[t] = p, out.pieces.back().last = t;
    }
  }
  MarkerData& c = out.capture;
  c.labels = out.truth.labels;
  c.rate = o.rate;
  const int P = static_cast<int>(extra.size());
  c.xyz.resize(T, 3 * (M + P + o.ghosts));
  c.xyz.leftCols(3 * M) = first;
  for (int p = 0; p < P; ++p) {
    out.pieces[p].label = "*" + std::to_string(p + 1);
    c.labels.push_back(out.pieces[p].label);
    for (int t = 0; t < T; ++t) c.set(t, M + p, extra[p].second[t]);
  }
}

// Ghosts: a few frames of a reflection 50–150 mm off a random marker, in random frames.
void add_ghosts(const SimulateOptions& o, std::mt19937& rng, SimulatedCapture& out) {
  MarkerData& c = out.capture;
  const int T = c.frame_count(), M = out.truth.marker_count();
  std::uniform_int_distribution<int> marker(0, M - 1), len(2, 15);
  std::uniform_real_distribution<double> u(-1, 1), dist(50, 150);
  for (int g = 0; g < o.ghosts; ++g) {
    const int col = c.marker_count();
    c.labels.push_back("*" + std::to_string(out.pieces.size() + 1));
    const int l = std::min(len(rng), T - 1), start = std::uniform_int_distribution<int>(1, T - l)(rng);
    const Eigen::Vector3d off = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized() * dist(rng);
    const int m = marker(rng);
    for (int t = 0; t < T; ++t)
      if (t >= start && t < start + l) c.set(t, col, out.truth.at(t, m) + off);
      else c.clear(t, col);
    out.pieces.push_back({c.labels.back(), -1, start, start + l - 1});
  }
}

}  // namespace

SimulatedCapture simulate_capture(const std::vector<Eigen::MatrixX3d>& frames, const Eigen::MatrixX3i& F,
                                  const SimulateOptions& o, const std::function<void(double)>& progress) {
  check_options(frames, F, o);
  std::mt19937 rng(o.seed);
  const Placement pl = place_markers(frames[0], F, o.markers, o.seed);
  SimulatedCapture out;
  for (int m = 0; m < o.markers; ++m) out.truth.labels.push_back("M" + std::to_string(m + 1));
  out.truth.rate = o.rate;
  std::vector<std::vector<char>> seen;
  trace(frames, F, o, pl, out, seen, progress);
  const int T = out.truth.frame_count(), M = o.markers;
  out.random_gaps = add_gaps(seen, o.missing, o.gap_min, o.gap_max, rng);
  // Breaks: the markers whose closest approach to another marker is smallest, broken there.
  std::vector<std::pair<double, std::pair<int, int>>> closest(M, {1e300, {0, -1}});
  for (int t = 1; t < T; ++t) {
    Eigen::MatrixX3d P(M, 3);
    for (int m = 0; m < M; ++m) P.row(m) = out.truth.at(t, m).transpose();
    const PointIndex index(P);
    std::vector<double> d2;
    for (int m = 0; m < M; ++m) {
      index.knn(P.row(m).transpose(), 2, &d2);
      if (seen[t][m] && d2.size() == 2 && d2[1] < closest[m].first) closest[m] = {d2[1], {m, t}};
    }
  }
  std::sort(closest.begin(), closest.end());
  std::vector<int> break_at(M, -1);
  out.broken = static_cast<int>(std::round(o.broken * M));
  for (int k = 0; k < out.broken; ++k) break_at[closest[k].second.first] = closest[k].second.second;
  cut_pieces(o, seen, break_at, rng, out);
  add_ghosts(o, rng, out);
  long missing = 0;
  for (int t = 0; t < T; ++t) missing += std::count(seen[t].begin(), seen[t].end(), 0);
  out.missing = double(missing) / (double(T) * M);
  std::vector<double> nn;
  Eigen::MatrixX3d P0(M, 3);
  for (int m = 0; m < M; ++m) P0.row(m) = out.truth.at(0, m).transpose();
  const PointIndex ref(P0);
  for (int m = 0; m < M; ++m) {
    std::vector<double> d2;
    ref.knn(out.truth.at(0, m), 2, &d2);
    nn.push_back(std::sqrt(d2.back()));
  }
  std::nth_element(nn.begin(), nn.begin() + M / 2, nn.end());
  out.spacing_mm = nn[M / 2];
  return out;
}

}  // namespace bodymodel
