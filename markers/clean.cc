#include "markers/clean.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <tbb/parallel_for.h>
#include <tuple>
#include <utility>

#include "core/error.h"
#include "core/geometry.h"
#include "core/point_index.h"

namespace bodymodel {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool is_piece(const std::string& label) { return !label.empty() && label[0] == '*'; }

// The marker surface of the reference frame: labelled markers, their neighbours, spacing.
struct Surface {
  std::vector<int> columns;  // capture columns of the labelled markers
  Eigen::MatrixX3d X0;       // reference positions
  std::vector<std::vector<int>> nbr;
  std::vector<std::vector<int>> wide;  // the 2·k nearest, for estimates when neighbours are missing
  std::vector<std::vector<int>> part;  // markers rigid with it (find_parts), steadiest first; may be empty
  std::vector<std::vector<double>> part_distance;  // its mean distance to each, over the frames both were seen
  Eigen::VectorXd spacing;   // mean distance to the neighbours (eq. 3)
  int size() const { return static_cast<int>(columns.size()); }
};

Surface build_surface(const MarkerData& c, const CleanOptions& o) {
  Surface s;
  if (o.reference_frame < 0 || o.reference_frame >= c.frame_count())
    throw InputError("markers clean: reference frame " + std::to_string(o.reference_frame) + " is not in the capture");
  for (int m = 0; m < c.marker_count(); ++m)
    if (!is_piece(c.labels[m])) {
      if (!c.present(o.reference_frame, m))
        throw InputError("markers clean: labelled marker '" + c.labels[m] + "' is missing in the reference frame " +
                         std::to_string(o.reference_frame) + " (the marker surface needs every marker there)");
      s.columns.push_back(m);
    }
  if (o.neighbours < 3) throw InputError("markers clean: --neighbours must be at least 3");
  if (s.size() < o.neighbours + 1)
    throw InputError("markers clean: " + std::to_string(s.size()) + " labelled markers (names not starting with '*'), need at least " +
                     std::to_string(o.neighbours + 1));
  s.X0.resize(s.size(), 3);
  for (int i = 0; i < s.size(); ++i) s.X0.row(i) = c.at(o.reference_frame, s.columns[i]).transpose();
  const PointIndex index(s.X0);
  s.spacing.resize(s.size());
  for (int i = 0; i < s.size(); ++i) {
    // The one-ring: the k nearest in the reference frame of the 3·k nearest whose distance to
    // the marker stays within `rigidity` of itself while both are seen (then the steadiest). This
    // keeps a hand's markers off the hip it rests against in the reference pose, as the paper's
    // neighbours along the skin do.
    std::vector<double> d2;
    const auto near = index.knn(s.X0.row(i).transpose(), 3 * o.neighbours + 1, &d2);
    std::vector<std::pair<double, int>> steady, loose;  // (reference distance or spread, marker)
    for (size_t k = 0; k < near.size(); ++k) {
      if (near[k] == i) continue;
      const double ref = std::sqrt(d2[k]);
      double sum = 0, sum2 = 0;
      int n = 0;
      for (int t = 0; t < c.frame_count(); ++t) {
        if (!c.present(t, s.columns[i]) || !c.present(t, s.columns[near[k]])) continue;
        const double d = (c.at(t, s.columns[i]) - c.at(t, s.columns[near[k]])).norm();
        sum += d, sum2 += d * d, ++n;
      }
      const double spread = n > 1 ? std::sqrt(std::max(0.0, sum2 / n - (sum / n) * (sum / n))) : 0;
      if (spread <= std::max(3.0, o.rigidity * ref)) steady.emplace_back(ref, near[k]);
      else loose.emplace_back(spread / ref, near[k]);
    }
    std::sort(steady.begin(), steady.end());
    std::sort(loose.begin(), loose.end());
    steady.insert(steady.end(), loose.begin(), loose.end());
    std::vector<int> n, w;
    double sum = 0;
    for (size_t k = 0; k < steady.size(); ++k) {
      if (static_cast<int>(k) < o.neighbours) n.push_back(steady[k].second), sum += (s.X0.row(steady[k].second) - s.X0.row(i)).norm();
      if (static_cast<int>(k) < 2 * o.neighbours) w.push_back(steady[k].second);
    }
    s.nbr.push_back(n);
    s.wide.push_back(w);
    s.spacing(i) = sum / std::max<size_t>(1, n.size());
  }
  // Where markers are sparse the tolerances would grow without bound: capped at the median.
  Eigen::VectorXd sorted = s.spacing;
  std::sort(sorted.data(), sorted.data() + sorted.size());
  s.spacing = s.spacing.cwiseMin(sorted(sorted.size() / 2));
  return s;
}

bool present(const Eigen::MatrixXd& X, int t, int i) { return !std::isnan(X(t, 3 * i)); }
Eigen::Vector3d at(const Eigen::MatrixXd& X, int t, int i) { return X.block<1, 3>(t, 3 * i).transpose(); }

// Points that fix a rotation: not (nearly) on one line.
bool well_spread(const Eigen::MatrixX3d& A) {
  if (A.rows() < 3) return false;
  const Eigen::MatrixX3d C = A.rowwise() - A.colwise().mean();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(C.transpose() * C, Eigen::EigenvaluesOnly);
  const Eigen::Vector3d ev = es.eigenvalues().cwiseMax(0);  // ascending: squared singular values
  return ev(1) > 0.0625 * ev(2);                             // second singular value > 1/4 of the first
}

// Marker i at frame t from its present neighbours, moved rigidly from the reference (eq. 2).
// When fewer than k of its one-ring are there, the next nearest markers stand in (up to 2·k), so
// that three or more points off one line fix the rotation.
bool estimate(const Surface& s, const Eigen::MatrixXd& X, int i, int t, Eigen::Vector3d& out) {
  std::vector<int> q;
  for (int j : s.wide[i])
    if (present(X, t, j) && q.size() < s.nbr[i].size()) q.push_back(j);
  if (q.size() < 3) return false;
  Eigen::MatrixX3d A(q.size(), 3), B(q.size(), 3);
  for (size_t k = 0; k < q.size(); ++k) A.row(k) = s.X0.row(q[k]), B.row(k) = at(X, t, q[k]).transpose();
  if (!well_spread(A)) return false;
  const RigidMotion m = fit_rigid_motion(A, B);
  out = m.R * s.X0.row(i).transpose() + m.t;
  return true;
}

// The std over the frames where both are seen of the distance between markers i and j of X, and
// how many frames that is.
double distance_spread(const Eigen::MatrixXd& X, int i, int j, int& n, double* mean = nullptr) {
  double sum = 0, sum2 = 0;
  n = 0;
  for (int t = 0; t < X.rows(); ++t) {
    if (!present(X, t, i) || !present(X, t, j)) continue;
    const double d = (at(X, t, i) - at(X, t, j)).norm();
    sum += d, sum2 += d * d, ++n;
  }
  if (mean) *mean = n ? sum / n : 0;
  return n > 1 ? std::sqrt(std::max(0.0, sum2 / n - (sum / n) * (sum / n))) : 1e300;
}

// Rigid parts from the capture itself (as Park & Hodgins and Kirk et al. segment markers): marker
// i's part is the markers among its 5·k nearest whose distance to it varies by at most
// part_rigidity (std over at least a tenth of the frames, both seen), the steadiest first. Unlike
// the one-ring, which must surround the marker, the part need only move with it: a hand's markers
// predict each other while the forearm and the hip move against them.
void find_parts(Surface& s, const CleanOptions& o, const Eigen::MatrixXd& X) {
  s.part.assign(s.size(), {});
  s.part_distance.assign(s.size(), {});
  if (o.part_rigidity <= 0) return;
  const PointIndex index(s.X0);
  const int min_frames = std::max(12, static_cast<int>(X.rows()) / 10);
  tbb::parallel_for(0, s.size(), [&](int i) {
    std::vector<std::tuple<double, int, double>> steady;  // (spread, marker, mean distance)
    for (int j : index.knn(s.X0.row(i).transpose(), 5 * o.neighbours + 1)) {
      int n = 0;
      double mean = 0;
      const double spread = j == i ? 1e300 : distance_spread(X, i, j, n, &mean);
      if (n >= min_frames && spread <= o.part_rigidity) steady.emplace_back(spread, j, mean);
    }
    std::sort(steady.begin(), steady.end());
    for (size_t k = 0; k < steady.size() && static_cast<int>(k) < o.part_size; ++k) {
      s.part[i].push_back(std::get<1>(steady[k]));
      s.part_distance[i].push_back(std::get<2>(steady[k]));
    }
  });
}

// The nearest frames before and after t where marker i is seen (−1 and the frame count when none).
std::pair<int, int> seen_around(const Eigen::MatrixXd& X, int i, int t) {
  const int T = static_cast<int>(X.rows());
  int before = t - 1, after = t + 1;
  while (before >= 0 && !present(X, before, i)) --before;
  while (after < T && !present(X, after, i)) ++after;
  return {before, after};
}

// Marker i at frame t moved rigidly with its neighbours from the nearest frames before and after
// where it was seen (weighted by closeness in time): the local shape of a recent frame is nearer
// the current one than the reference pose's. The reference-frame estimate when neither serves.
bool anchored_estimate(const Surface& s, const Eigen::MatrixXd& X, int i, int t, Eigen::Vector3d& out) {
  const int T = static_cast<int>(X.rows());
  int before = 0, after = 0;
  std::tie(before, after) = seen_around(X, i, t);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double wsum = 0;
  for (int a : {before, after}) {
    if (a < 0 || a >= T) continue;
    std::vector<int> q;
    for (int j : s.wide[i])
      if (present(X, t, j) && present(X, a, j) && q.size() < s.nbr[i].size()) q.push_back(j);
    if (q.size() < 3) continue;
    Eigen::MatrixX3d A(q.size(), 3), B(q.size(), 3);
    for (size_t k = 0; k < q.size(); ++k) A.row(k) = at(X, a, q[k]).transpose(), B.row(k) = at(X, t, q[k]).transpose();
    if (!well_spread(A)) continue;
    const RigidMotion m = fit_rigid_motion(A, B);
    const double w = 1.0 / std::abs(t - a);
    sum += w * (m.R * at(X, a, i) + m.t), wsum += w;
  }
  if (wsum == 0) return estimate(s, X, i, t, out);
  out = sum / wsum;
  return true;
}

// Marker i at frame t moved with its rigid part (at least 3 members seen at t, not on one line)
// from the nearest frames before and after where it was seen, else from the reference frame
// (false: the part cannot say).
bool part_estimate(const Surface& s, const Eigen::MatrixXd& X, int i, int t, Eigen::Vector3d& out) {
  const int T = static_cast<int>(X.rows());
  int before = 0, after = 0;
  std::tie(before, after) = seen_around(X, i, t);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double wsum = 0;
  auto from = [&](int a) {  // a < 0: the reference frame
    std::vector<int> q;
    for (int j : s.part[i])
      if (present(X, t, j) && (a < 0 || present(X, a, j))) q.push_back(j);
    if (q.size() < 3) return;
    Eigen::MatrixX3d A(q.size(), 3), B(q.size(), 3);
    for (size_t k = 0; k < q.size(); ++k) {
      A.row(k) = a < 0 ? Eigen::RowVector3d(s.X0.row(q[k])) : Eigen::RowVector3d(at(X, a, q[k]).transpose());
      B.row(k) = at(X, t, q[k]).transpose();
    }
    if (!well_spread(A)) return;
    const RigidMotion m = fit_rigid_motion(A, B);
    const Eigen::Vector3d x = a < 0 ? Eigen::Vector3d(s.X0.row(i).transpose()) : at(X, a, i);
    const double w = a < 0 ? 1.0 : 1.0 / std::abs(t - a);
    sum += w * (m.R * x + m.t), wsum += w;
  };
  if (before >= 0) from(before);
  if (after < T) from(after);
  if (wsum == 0) from(-1);
  if (wsum == 0) return false;
  out = sum / wsum;
  return true;
}

struct Piece {
  int column;
  std::vector<int> frames;
  std::vector<int> refused;  // markers its merge into was undone (the neighbourhood models disagreed)
};

// The median over piece p's frames and marker i's part members seen then of how far the piece's
// distance to the member strays from marker i's own mean distance to it (-1: no verdict, a part of
// fewer than 2 or fewer than 3 such samples). A piece of marker i keeps its part's distances within
// their spread (at most part_rigidity); another marker's piece, or a ghost, does not.
double part_misfit(const Surface& s, const MarkerData& c, const Eigen::MatrixXd& X, int i, const Piece& p) {
  std::vector<double> e;
  if (s.part[i].size() < 2) return -1;  // one marker's distance says little about where it sits
  for (size_t k = 0; k < s.part[i].size(); ++k) {
    const int j = s.part[i][k];
    for (int t : p.frames)
      if (present(X, t, j)) e.push_back(std::abs((c.at(t, p.column) - at(X, t, j)).norm() - s.part_distance[i][k]));
  }
  if (e.size() < 3) return -1;
  std::nth_element(e.begin(), e.begin() + e.size() / 2, e.end());
  return e[e.size() / 2];
}

// Our addition, a check of every merge before it is made (all rounds): piece p is not marker i's when
// it strays from the distances of i's rigid part by more than part_rigidity and `ambiguity` times more
// than from those of another marker's part near i (within 2.5 spacings in the reference frame) that is
// missing over the whole piece, refused by it or not. Near hands and hips the predictions that merge
// a piece (rigid, filled trajectory, models, the piece's own part) are tens of millimetres off for the
// right marker and its neighbour alike; the distances within a part are not.
bool part_refuses(const Surface& s, const CleanOptions& o, const MarkerData& c, const Eigen::MatrixXd& X, int i, const Piece& p) {
  if (o.part_check <= 0 || o.part_rigidity <= 0) return false;
  const double e = part_misfit(s, c, X, i, p);
  if (e <= o.part_rigidity) return false;  // fits, or no verdict (-1)
  for (int j = 0; j < s.size(); ++j) {
    if (j == i || (s.X0.row(j) - s.X0.row(i)).norm() > 2.5 * s.spacing(i)) continue;
    bool missing = true;
    for (int t : p.frames) missing = missing && !present(X, t, j);
    if (!missing) continue;
    const double ej = part_misfit(s, c, X, j, p);
    if (ej >= 0 && o.ambiguity * ej < e) return true;
  }
  return false;
}

// A short merged piece (under 12 frames, as the part rounds' minimum) straying from marker i's part
// distances by more than part_check · part_rigidity: a ghost, which no marker explains better, so
// part_refuses lets it through. Taken out by undo_disagreeing.
bool is_ghost(const Surface& s, const CleanOptions& o, const MarkerData& c, const Eigen::MatrixXd& X, int i, const Piece& p) {
  if (o.part_check <= 0 || o.part_rigidity <= 0 || p.frames.size() >= 12) return false;
  return part_misfit(s, c, X, i, p) > o.part_check * o.part_rigidity;
}

// Where marker i should be at frame t (false: no prediction).
using Predictor = std::function<bool(int i, int t, Eigen::Vector3d& out)>;

// The mean distance of a piece to marker i's predictions over the piece (false if it overlaps
// the marker's samples or has no prediction); `worst` the largest ratio distance / tolerance.
bool piece_distance(const MarkerData& c, const Eigen::MatrixXd& X, const Piece& p, int i, const Predictor& predict,
                    double tolerance, double& mean, double& worst) {
  double sum = 0;
  int n = 0;
  worst = 0;
  for (int t : p.frames) {
    Eigen::Vector3d e;
    if (present(X, t, i)) return false;  // overlaps the marker's own samples
    if (!predict(i, t, e)) continue;
    const double d = (e - c.at(t, p.column)).norm();
    worst = std::max(worst, d / tolerance);
    sum += d, ++n;
  }
  mean = n ? sum / n : 0;
  return n > 0;
}

// The marker a piece belongs to (-1: none): within a1 · spacing of the prediction at the piece's
// first predicted frame and a2 · spacing over the whole piece (eq. 3), and unambiguous: no other
// marker's predictions within `ambiguity` times its mean distance.
int match_piece(const Surface& s, const CleanOptions& o, const MarkerData& c, const Eigen::MatrixXd& X, const Piece& p,
                const Predictor& predict, double& best_mean) {
  std::vector<std::pair<int, bool>> contenders;  // (marker, within a1 at the first frame)
  for (size_t k = 0; k < p.frames.size() && contenders.empty(); ++k) {
    const int f = p.frames[k];
    for (int i = 0; i < s.size(); ++i) {
      Eigen::Vector3d e;
      if (present(X, f, i) || !predict(i, f, e)) continue;
      const double d = (e - c.at(f, p.column)).norm();
      if (d < std::max(1.0, 2 * o.merge_tolerance) * s.spacing(i)) contenders.emplace_back(i, d < o.merge_tolerance * s.spacing(i));
    }
  }
  int best = -1;
  best_mean = 1e300;
  double runner_up = 1e300;
  for (const auto& [i, close] : contenders) {
    double mean = 0, worst = 0;
    if (std::find(p.refused.begin(), p.refused.end(), i) != p.refused.end()) continue;
    if (!piece_distance(c, X, p, i, predict, o.piece_tolerance * s.spacing(i), mean, worst)) continue;
    if (close && worst <= 1 && mean < best_mean) {
      if (best >= 0) runner_up = std::min(runner_up, best_mean);
      best = i, best_mean = mean;
    } else {
      runner_up = std::min(runner_up, mean);
    }
  }
  if (best >= 0 && runner_up < o.ambiguity * best_mean) return -1;  // two markers explain it: leave it
  if (best >= 0 && part_refuses(s, o, c, X, best, p)) return -1;
  return best;
}

struct Pieces {
  std::vector<Piece> list;  // in order of their first frame
  std::vector<char> done;
  std::vector<int> marker;  // the marker each merged piece went to (-1: not merged)
};

Pieces collect_pieces(const MarkerData& c) {
  Pieces ps;
  for (int m = 0; m < c.marker_count(); ++m) {
    if (!is_piece(c.labels[m])) continue;
    Piece p{m, {}, {}};
    for (int t = 0; t < c.frame_count(); ++t)
      if (c.present(t, m)) p.frames.push_back(t);
    if (!p.frames.empty()) ps.list.push_back(std::move(p));
  }
  std::stable_sort(ps.list.begin(), ps.list.end(), [](const Piece& a, const Piece& b) { return a.frames[0] < b.frames[0]; });
  ps.done.assign(ps.list.size(), 0);
  ps.marker.assign(ps.list.size(), -1);
  return ps;
}

// Section 4.2: the pieces not merged yet, in order of their first frame (each merge may give a
// later piece the neighbours it needs). Returns the number merged.
int merge_round(const MarkerData& c, const Surface& s, const CleanOptions& o, const Predictor& predict, Pieces& ps,
                Eigen::MatrixXd& X, CleanReport& r) {
  int merged = 0;
  for (size_t k = 0; k < ps.list.size(); ++k) {
    if (ps.done[k] || static_cast<int>(ps.list[k].frames.size()) < o.min_piece) continue;
    double mean = 0;
    const Piece& p = ps.list[k];
    const int i = match_piece(s, o, c, X, p, predict, mean);
    if (i < 0) continue;
    for (int t : p.frames) X.block<1, 3>(t, 3 * i) = c.xyz.block<1, 3>(t, 3 * p.column);
    ps.done[k] = 1;
    ps.marker[k] = i;
    ++merged;
    r.merges.push_back({c.labels[p.column], c.labels[s.columns[i]], p.frames.front(), p.frames.back(), mean});
  }
  return merged;
}

// Section 4.3: a PCA model of a marker's neighbourhood in its local frame.
struct Model {
  std::vector<int> group;  // the marker, then its neighbours
  Eigen::MatrixX3d mean;   // local positions
  Eigen::MatrixXd U;       // 3·group × r, row-major coordinates
  Eigen::VectorXd prior;   // noise variance / component variance, per component
};

Eigen::MatrixX3d rows_of(const Eigen::MatrixXd& X, int t, const std::vector<int>& idx) {
  Eigen::MatrixX3d P(idx.size(), 3);
  for (size_t k = 0; k < idx.size(); ++k) P.row(k) = X.block<1, 3>(t, 3 * idx[k]);
  return P;
}

Model fit_model(const Surface& s, const Eigen::MatrixXd& X, int i, double energy) {
  Model md;
  md.group.push_back(i);
  for (int j : s.nbr[i]) md.group.push_back(j);
  const int g = static_cast<int>(md.group.size());
  Eigen::MatrixX3d ref(g, 3);
  for (int k = 0; k < g; ++k) ref.row(k) = s.X0.row(md.group[k]);
  ref.rowwise() -= ref.colwise().mean();
  std::vector<int> full;
  for (int t = 0; t < X.rows(); ++t) {
    bool all = true;
    for (int j : md.group) all = all && present(X, t, j);
    if (all) full.push_back(t);
  }
  const size_t stride = std::max<size_t>(1, full.size() / 400);  // enough frames for a 3g-dimensional model
  Eigen::MatrixXd D(0, 3 * g);
  for (size_t k = 0; k < full.size(); k += stride) {
    const Eigen::MatrixX3d cur = rows_of(X, full[k], md.group);
    const Eigen::MatrixX3d local = apply(fit_rigid_motion(cur, ref), cur);
    D.conservativeResize(D.rows() + 1, Eigen::NoChange);
    for (int q = 0; q < g; ++q) D.block<1, 3>(D.rows() - 1, 3 * q) = local.row(q);
  }
  md.mean = ref;
  if (D.rows() < 8) return md;  // too few complete frames: the rigid reference shape alone
  const Eigen::RowVectorXd mu = D.colwise().mean();
  for (int q = 0; q < g; ++q) md.mean.row(q) = mu.segment<3>(3 * q);
  const Eigen::MatrixXd C = (D.rowwise() - mu).transpose() * (D.rowwise() - mu) / double(D.rows() - 1);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(C);
  const Eigen::VectorXd ev = es.eigenvalues().reverse().cwiseMax(0);
  const double total = ev.sum();
  int r = 0;
  for (double acc = 0; r < ev.size() && acc < energy * total && r < static_cast<int>(D.rows()) - 2; ++r) acc += ev(r);
  md.U = es.eigenvectors().rowwise().reverse().leftCols(r);
  md.prior = (1.0 / ev.head(r).array().max(1e-6)).matrix();  // 1 mm² of noise against each component
  return md;
}

// The model's shape and its rigid placement at frame t from the members present in Y other than
// `target`: alternately the rigid placement of the model shape and its PCA coefficients.
bool place_model(const Model& md, const Eigen::MatrixXd& Y, int t, int target, Eigen::MatrixX3d& shape, RigidMotion& m) {
  std::vector<int> q;
  for (int k = 0; k < static_cast<int>(md.group.size()); ++k)
    if (k != target && present(Y, t, md.group[k])) q.push_back(k);
  if (q.size() < 3) return false;
  Eigen::MatrixX3d cur(q.size(), 3);
  shape = md.mean;
  for (size_t k = 0; k < q.size(); ++k) cur.row(k) = at(Y, t, md.group[q[k]]).transpose();
  if (!well_spread(cur)) return false;
  for (int it = 0; it < 2; ++it) {
    Eigen::MatrixX3d sq(q.size(), 3);
    for (size_t k = 0; k < q.size(); ++k) sq.row(k) = shape.row(q[k]);
    m = fit_rigid_motion(sq, cur);
    if (md.U.cols() == 0) break;
    const Eigen::MatrixX3d local = (cur.rowwise() - m.t.transpose()) * m.R;  // R^T (b − t), row-wise
    Eigen::MatrixXd A(3 * q.size(), md.U.cols());
    Eigen::VectorXd b(3 * q.size());
    for (size_t k = 0; k < q.size(); ++k) {
      A.middleRows(3 * k, 3) = md.U.middleRows(3 * q[k], 3);
      b.segment<3>(3 * k) = (local.row(k) - md.mean.row(q[k])).transpose();
    }
    Eigen::MatrixXd N = A.transpose() * A;
    N.diagonal() += md.prior;
    const Eigen::VectorXd coef = N.ldlt().solve(A.transpose() * b);
    const Eigen::VectorXd flat = md.U * coef;
    for (int k = 0; k < static_cast<int>(md.group.size()); ++k) shape.row(k) = md.mean.row(k) + flat.segment<3>(3 * k).transpose();
  }
  if (md.U.cols() > 0) {  // the rigid placement of the final shape
    Eigen::MatrixX3d sq(q.size(), 3);
    for (size_t k = 0; k < q.size(); ++k) sq.row(k) = shape.row(q[k]);
    m = fit_rigid_motion(sq, cur);
  }
  return true;
}

// The model's estimate of group member `target` at frame t from the other members present in Y.
bool reconstruct(const Model& md, const Eigen::MatrixXd& Y, int t, int target, Eigen::Vector3d& out) {
  Eigen::MatrixX3d shape;
  RigidMotion m;
  if (!place_model(md, Y, t, target, shape, m)) return false;
  out = m.R * shape.row(target).transpose() + m.t;
  return true;
}

// Every model's estimates of its members missing in Y, per model (frame, member, estimate) in frame
// then member order. The members present are the same for all of a frame's missing members, so one
// placement of the model serves them all (the same as reconstruct for each).
using MissingEstimates = std::vector<std::vector<std::tuple<int, int, Eigen::Vector3d>>>;
MissingEstimates estimate_missing(const std::vector<Model>& models, const Eigen::MatrixXd& Y) {
  MissingEstimates est(models.size());
  tbb::parallel_for(size_t(0), models.size(), [&](size_t j) {
    const Model& md = models[j];
    const int g = static_cast<int>(md.group.size());
    Eigen::MatrixX3d shape;
    RigidMotion m;
    for (int t = 0; t < Y.rows(); ++t) {
      int first = -1;
      for (int k = 0; k < g && first < 0; ++k)
        if (!present(Y, t, md.group[k])) first = k;
      if (first < 0 || !place_model(md, Y, t, first, shape, m)) continue;
      for (int k = first; k < g; ++k)
        if (!present(Y, t, md.group[k])) est[j].emplace_back(t, k, m.R * shape.row(k).transpose() + m.t);
    }
  });
  return est;
}

// Model `model`'s estimate of its member `member` at frame t from `est` (false: none).
bool find_estimate(const MissingEstimates& est, int model, int member, int t, Eigen::Vector3d& out) {
  const auto& e = est[model];
  const auto it = std::lower_bound(e.begin(), e.end(), std::make_pair(t, member), [](const auto& a, const std::pair<int, int>& key) {
    return std::make_pair(std::get<0>(a), std::get<1>(a)) < key;
  });
  if (it == e.end() || std::get<0>(*it) != t || std::get<1>(*it) != member) return false;
  out = std::get<2>(*it);
  return true;
}

// The holes of marker i at the frames in `todo`, averaged over the models holding i; the frames
// filled are cleared from `todo`.
long fill_from_models(const Surface& s, const std::vector<Model>& models, const std::vector<std::vector<std::pair<int, int>>>& holders,
                      const MissingEstimates* est, const Eigen::MatrixXd& from, Eigen::MatrixXd& to, int i, std::vector<int>& todo) {
  long filled = 0;
  std::vector<int> left;
  for (int t : todo) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero(), e;
    int n = 0;
    for (const auto& [model, member] : holders[i])
      if (est ? find_estimate(*est, model, member, t, e) : reconstruct(models[model], from, t, member, e)) sum += e, ++n;
    // A quarter the PCA models' estimate, three quarters the rigid motion from the nearest frames
    // where the marker was seen, of its rigid part where it has one, else of its one-ring (our
    // addition: it follows short gaps more closely, and near hands and hips the models, fitted on
    // frames where the whole one-ring is seen, are often far off; half and half filled worse).
    if (part_estimate(s, from, i, t, e) || anchored_estimate(s, from, i, t, e)) {
      sum = n == 0 ? e : Eigen::Vector3d(0.25 * (sum / n) + 0.75 * e);
      n = 1;
    }
    if (n == 0) {
      left.push_back(t);
      continue;
    }
    to.block<1, 3>(t, 3 * i) = (sum / n).transpose();
    ++filled;
  }
  todo = left;
  return filled;
}

struct Neighbourhoods {
  std::vector<Model> models;                              // one per marker
  std::vector<std::vector<std::pair<int, int>>> holders;  // (model, member) holding marker i
  Eigen::MatrixXd data;                                   // the merged trajectories they were fitted on
};

bool same_columns(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, int i) {  // bitwise: NaN == NaN
  return A.rows() == B.rows() && std::equal(A.col(3 * i).data(), A.col(3 * i).data() + 3 * A.rows(), B.col(3 * i).data(),
                                            [](double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; });
}

// The models of X's neighbourhoods. A model depends on its group's trajectories alone: those of `nb`
// whose group X leaves as they were are kept (the merge rounds change a few markers each), the rest
// refitted.
void fit_neighbourhoods(const Surface& s, const CleanOptions& o, const Eigen::MatrixXd& X, Neighbourhoods& nb) {
  const int L = s.size();
  const bool reuse = static_cast<int>(nb.models.size()) == L && nb.data.rows() == X.rows();
  std::vector<char> changed(L, 1);
  if (reuse)
    for (int i = 0; i < L; ++i) changed[i] = !same_columns(nb.data, X, i);
  nb.models.resize(L);
  tbb::parallel_for(0, L, [&](int i) {
    bool stale = !reuse;
    for (int j : nb.models[i].group) stale = stale || changed[j];
    if (stale || nb.models[i].group.empty()) nb.models[i] = fit_model(s, X, i, o.pca_energy);
  });
  nb.holders.assign(L, {});
  for (int j = 0; j < L; ++j)
    for (size_t k = 0; k < nb.models[j].group.size(); ++k) nb.holders[nb.models[j].group[k]].emplace_back(j, static_cast<int>(k));
  nb.data = X;
}

// The mean distance of piece p's samples to marker i's neighbourhood models' estimates from the
// other members (marker i's own sample is not used), over at most 16 of the piece's frames evenly
// spread (enough for a mean; all of them made the check slower than the cleaning); -1: none reached.
double model_distance(const Neighbourhoods& nb, const MarkerData& c, const Eigen::MatrixXd& X, int i, const Piece& p) {
  double sum = 0;
  int n = 0;
  const size_t step = std::max<size_t>(1, p.frames.size() / 16);
  for (size_t f = 0; f < p.frames.size(); f += step) {
    const int t = p.frames[f];
    Eigen::Vector3d acc = Eigen::Vector3d::Zero(), e;
    int k = 0;
    for (const auto& [model, member] : nb.holders[i])
      if (reconstruct(nb.models[model], X, t, member, e)) acc += e, ++k;
    if (k > 0) sum += (acc / k - c.at(t, p.column)).norm(), ++n;
  }
  return n ? sum / n : -1;
}

// Whether another marker near i, missing over the whole piece and not refused by it, has models that
// place the piece closer than `d` (a better explanation than marker i's).
bool better_explained(const Surface& s, const Neighbourhoods& nb, const MarkerData& c, const Eigen::MatrixXd& X, int i,
                      const Piece& p, double d) {
  for (int j : s.wide[i]) {
    if (std::find(p.refused.begin(), p.refused.end(), j) != p.refused.end()) continue;
    bool missing = true;
    for (int t : p.frames) missing = missing && !present(X, t, j);
    if (!missing) continue;
    const double dj = model_distance(nb, c, X, j, p);
    if (dj >= 0 && dj < d) return true;
  }
  return false;
}

// Linear interpolation in time between the nearest known samples (held at the ends).
void interpolate_rest(Eigen::MatrixXd& Y, int i, const std::vector<int>& todo) {
  const int T = static_cast<int>(Y.rows());
  for (int t : todo) {
    int a = t, b = t;
    while (a >= 0 && !present(Y, a, i)) --a;
    while (b < T && !present(Y, b, i)) ++b;
    if (a < 0 && b >= T) continue;  // never seen (cannot happen: the reference frame has it)
    if (a < 0) a = b;
    if (b >= T) b = a;
    const double u = a == b ? 0 : double(t - a) / (b - a);
    Y.block<1, 3>(t, 3 * i) = (1 - u) * Y.block<1, 3>(a, 3 * i) + u * Y.block<1, 3>(b, 3 * i);
  }
}

int count_gaps(const Eigen::MatrixXd& X, int L) {
  int gaps = 0;
  for (int i = 0; i < L; ++i)
    for (int t = 0; t < X.rows(); ++t) gaps += !present(X, t, i) && (t == 0 || present(X, t - 1, i));
  return gaps;
}

// Section 4.3, with the neighbours' models averaged in; then filled neighbours may count (second
// pass); then linear interpolation for what no model reaches.
Eigen::MatrixXd fill_holes(const Surface& s, const Neighbourhoods& nb, const Eigen::MatrixXd& X, CleanReport& r) {
  const int L = s.size();
  r.gaps_after_merge = count_gaps(X, L);
  r.samples_missing = r.filled_from_neighbours = r.filled_by_interpolation = 0;
  for (int i = 0; i < L; ++i)
    for (int t = 0; t < X.rows(); ++t) r.samples_missing += !present(X, t, i);
  const auto& models = nb.models;
  const auto& holders = nb.holders;
  std::vector<std::vector<int>> todo(L);
  for (int i = 0; i < L; ++i)
    for (int t = 0; t < X.rows(); ++t)
      if (!present(X, t, i)) todo[i].push_back(t);
  Eigen::MatrixXd Y = X;
  std::vector<long> filled(L, 0);
  const MissingEstimates est = estimate_missing(models, X);  // the first pass's model estimates, one placement per model and frame
  tbb::parallel_for(0, L, [&](int i) { filled[i] += fill_from_models(s, models, holders, &est, X, Y, i, todo[i]); });
  const Eigen::MatrixXd Y1 = Y;
  tbb::parallel_for(0, L, [&](int i) { filled[i] += fill_from_models(s, models, holders, nullptr, Y1, Y, i, todo[i]); });
  for (int i = 0; i < L; ++i) {
    r.filled_from_neighbours += filled[i];
    r.filled_by_interpolation += static_cast<long>(todo[i].size());
    interpolate_rest(Y, i, todo[i]);
  }
  r.gaps_left = count_gaps(Y, L);
  r.gaps_filled = r.gaps_after_merge - r.gaps_left;
  return Y;
}

// Our addition to section 4.2: a merged piece its marker's neighbourhood models place farther than
// model_tolerance · spacing (on average over the piece), and that another marker's models place
// closer, is taken out again and not offered to that marker again. The rigid prediction it was merged on can be tens of millimetres off near hands and
// hips, where a neighbour's piece is then as close as the marker's own; the models (section 4.3)
// know how the marker moves against its neighbours. Pieces checked once, after the round that
// merged them. Returns the number taken out.
int undo_disagreeing(const MarkerData& c, const Surface& s, const CleanOptions& o, const Neighbourhoods& nb, Pieces& ps,
                     std::vector<char>& checked, Eigen::MatrixXd& X, CleanReport& r) {
  if (o.model_tolerance <= 0) return 0;
  checked.resize(ps.list.size(), 0);
  std::vector<double> d(ps.list.size(), -1);
  tbb::parallel_for(size_t(0), ps.list.size(), [&](size_t k) {
    if (ps.marker[k] < 0 || checked[k]) return;
    const int i = ps.marker[k];
    const double dk = model_distance(nb, c, X, i, ps.list[k]);
    if (dk > o.model_tolerance * s.spacing(i) && better_explained(s, nb, c, X, i, ps.list[k], dk)) d[k] = dk;
    if (is_ghost(s, o, c, X, i, ps.list[k])) d[k] = std::max(0.0, dk);
  });
  int undone = 0;
  for (size_t k = 0; k < ps.list.size(); ++k) {
    if (ps.marker[k] < 0 || checked[k]) continue;
    const int i = ps.marker[k];
    if (d[k] < 0) {
      checked[k] = 1;
      continue;
    }
    Piece& p = ps.list[k];
    for (int t : p.frames) X.block<1, 3>(t, 3 * i).setConstant(kNaN);
    p.refused.push_back(i);
    ps.done[k] = 0, ps.marker[k] = -1;
    const std::string& label = c.labels[p.column];
    r.merges.erase(std::remove_if(r.merges.begin(), r.merges.end(), [&](const MergeRecord& m) { return m.piece == label; }), r.merges.end());
    r.undone.push_back({label, c.labels[s.columns[i]], p.frames.front(), p.frames.back(), d[k]});
    ++undone;
  }
  return undone;
}

// Merges piece k (in `order`) into marker choice[k] where the marker is missing over all of its
// frames; a piece whose marker an earlier one already filled there is left. Returns the merges.
int merge_chosen(const MarkerData& c, const Surface& s, const CleanOptions& o, const std::vector<size_t>& order, const std::vector<int>& choice,
                 const std::vector<double>& dist, Pieces& ps, Eigen::MatrixXd& X, CleanReport& r) {
  int merged = 0;
  for (size_t k : order) {
    const int i = choice[k];
    if (i < 0) continue;
    const Piece& p = ps.list[k];
    bool missing = true;
    for (int t : p.frames) missing = missing && !present(X, t, i);
    if (!missing || part_refuses(s, o, c, X, i, p)) continue;
    for (int t : p.frames) X.block<1, 3>(t, 3 * i) = c.xyz.block<1, 3>(t, 3 * p.column);
    ps.done[k] = 1, ps.marker[k] = i, ++merged;
    r.merges.push_back({c.labels[p.column], c.labels[s.columns[i]], p.frames.front(), p.frames.back(), dist[k]});
  }
  return merged;
}

// Our addition, after the rounds of step 4: the pieces left are matched by the neighbourhood models
// alone. A candidate is a marker missing over the whole piece, within one spacing of it at its first
// frame (filled trajectory) and not refused by it; the piece goes to the one whose models place it
// nearest, within model_tolerance · spacing, when no other's models are within `ambiguity` times
// that. Where the rigid prediction is off (near hands and hips) the models still know where the
// marker sits among its neighbours.
int model_round(const MarkerData& c, const Surface& s, const CleanOptions& o, const Neighbourhoods& nb, const Eigen::MatrixXd& Y,
                Pieces& ps, Eigen::MatrixXd& X, CleanReport& r) {
  std::vector<int> choice(ps.list.size(), -1);
  std::vector<double> dist(ps.list.size(), 0);
  tbb::parallel_for(size_t(0), ps.list.size(), [&](size_t k) {
    if (ps.done[k]) return;
    const Piece& p = ps.list[k];
    double best = 1e300, second = 1e300;
    int bi = -1;
    for (int i = 0; i < s.size(); ++i) {
      if ((at(Y, p.frames[0], i) - c.at(p.frames[0], p.column)).norm() > s.spacing(i)) continue;
      if (std::find(p.refused.begin(), p.refused.end(), i) != p.refused.end()) continue;
      bool missing = true;
      for (int t : p.frames) missing = missing && !present(X, t, i);
      if (!missing) continue;
      const double d = model_distance(nb, c, X, i, p);
      if (d < 0) continue;
      if (d < best) second = best, best = d, bi = i;
      else second = std::min(second, d);
    }
    if (bi >= 0 && best <= o.model_tolerance * s.spacing(bi) && second >= o.ambiguity * best) choice[k] = bi, dist[k] = best;
  });
  std::vector<size_t> order(ps.list.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  return merge_chosen(c, s, o, order, choice, dist, ps, X, r);
}

// Where piece p sits in the reference frame (false: it cannot say): its own rigid part, the markers
// of X whose distance to it varies least over the piece (std at most piece_rigidity, seen over most of
// it, at most part_size of those within 3 spacings of it at its first frame), carries it back rigidly
// to their reference positions (mean over at most 16 of its frames). Unlike a prediction of the
// missing marker, this needs no frame where the marker was seen.
bool piece_reference(const Surface& s, const CleanOptions& o, const MarkerData& c, const Eigen::MatrixXd& X, const Piece& p,
                     double reach, Eigen::Vector3d& q) {
  const int n = static_cast<int>(p.frames.size());
  std::vector<std::pair<double, int>> steady;
  for (int j = 0; j < s.size(); ++j) {
    const int t0 = p.frames[0];
    if (!present(X, t0, j) || (at(X, t0, j) - c.at(t0, p.column)).norm() > reach) continue;
    double sum = 0, sum2 = 0;
    int k = 0;
    for (int t : p.frames) {
      if (!present(X, t, j)) continue;
      const double d = (at(X, t, j) - c.at(t, p.column)).norm();
      sum += d, sum2 += d * d, ++k;
    }
    if (k < 0.8 * n) continue;
    const double spread = std::sqrt(std::max(0.0, sum2 / k - (sum / k) * (sum / k)));
    if (spread <= o.piece_rigidity) steady.emplace_back(spread, j);
  }
  std::sort(steady.begin(), steady.end());
  if (steady.size() > static_cast<size_t>(o.part_size)) steady.resize(o.part_size);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int m = 0;
  const int step = std::max(1, n / 16);
  for (int f = 0; f < n; f += step) {
    const int t = p.frames[f];
    std::vector<int> J;
    for (const auto& [spread, j] : steady)
      if (present(X, t, j)) J.push_back(j);
    if (J.size() < 3) continue;
    Eigen::MatrixX3d A(J.size(), 3), B(J.size(), 3);
    for (size_t k = 0; k < J.size(); ++k) A.row(k) = at(X, t, J[k]).transpose(), B.row(k) = s.X0.row(J[k]);
    if (!well_spread(B)) continue;
    const RigidMotion back = fit_rigid_motion(A, B);
    sum += back.R * c.at(t, p.column) + back.t, ++m;
  }
  if (m == 0) return false;
  q = sum / m;
  return true;
}

// Our addition: the pieces left of at least 12 frames (0.1 s at 120 Hz: enough to tell which
// markers move rigidly with it) go to the marker whose reference position is nearest the piece's
// (piece_reference), among the markers missing over the whole piece and not refused by it, when
// that is within model_tolerance · spacing and every other marker is `ambiguity` times farther.
// Near hands and hips the one-ring's motion, the filled trajectory and the models can all be far
// off over a long hole; the piece's own part is not.
int part_round(const MarkerData& c, const Surface& s, const CleanOptions& o, Pieces& ps, Eigen::MatrixXd& X, CleanReport& r) {
  if (o.part_rigidity <= 0) return 0;
  Eigen::VectorXd sorted = s.spacing;
  std::sort(sorted.data(), sorted.data() + sorted.size());
  const double reach = 3 * sorted(sorted.size() / 2);
  std::vector<int> choice(ps.list.size(), -1);
  std::vector<double> dist(ps.list.size(), 0);
  tbb::parallel_for(size_t(0), ps.list.size(), [&](size_t k) {
    const Piece& p = ps.list[k];
    Eigen::Vector3d q;
    if (ps.done[k] || p.frames.size() < 12 || !piece_reference(s, o, c, X, p, reach, q)) return;
    double best = 1e300, second = 1e300;
    int bi = -1;
    for (int i = 0; i < s.size(); ++i) {
      const double d = (s.X0.row(i).transpose() - q).norm();
      bool free = std::find(p.refused.begin(), p.refused.end(), i) == p.refused.end();
      for (int t : p.frames) free = free && !present(X, t, i);
      if (free && d < best) {
        second = std::min(second, best), best = d, bi = i;
      } else {
        second = std::min(second, d);
      }
    }
    if (bi >= 0 && best <= o.model_tolerance * s.spacing(bi) && second >= o.ambiguity * best) choice[k] = bi, dist[k] = best;
  });
  // The surest first: of two pieces that want one marker over the same frames, the nearer wins.
  std::vector<size_t> order(ps.list.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return dist[a] < dist[b]; });
  return merge_chosen(c, s, o, order, choice, dist, ps, X, r);
}

// The neighbourhood models of the merged trajectories (nb, updated), after taking out the merges they disagree with.
void checked_neighbourhoods(const MarkerData& c, const Surface& s, const CleanOptions& o, Neighbourhoods& nb, Pieces& ps,
                            std::vector<char>& checked, Eigen::MatrixXd& X, CleanReport& r) {
  fit_neighbourhoods(s, o, X, nb);
  if (undo_disagreeing(c, s, o, nb, ps, checked, X, r) > 0) fit_neighbourhoods(s, o, X, nb);
}

// Section 4.4: each trajectory smoothed in its local frame (the rigid motion of its neighbours
// from the reference), so the body's rigid motion is not filtered.
void smooth(const Surface& s, const CleanOptions& o, Eigen::MatrixXd& Y) {
  if (o.smooth_iterations <= 0) return;
  const int T = static_cast<int>(Y.rows());
  const Eigen::MatrixXd in = Y;
  tbb::parallel_for(0, s.size(), [&](int i) {
    std::vector<RigidMotion> m(T);
    Eigen::MatrixX3d l(T, 3), ref(s.nbr[i].size(), 3);
    for (size_t k = 0; k < s.nbr[i].size(); ++k) ref.row(k) = s.X0.row(s.nbr[i][k]);
    for (int t = 0; t < T; ++t) {
      m[t] = fit_rigid_motion(rows_of(in, t, s.nbr[i]), ref);
      l.row(t) = (m[t].R * at(in, t, i) + m[t].t).transpose();
    }
    for (int it = 0; it < o.smooth_iterations; ++it) {
      const Eigen::MatrixX3d prev = l;
      for (int t = 1; t + 1 < T; ++t) l.row(t) += o.smooth_lambda * (prev.row(t - 1) - 2 * prev.row(t) + prev.row(t + 1));
    }
    for (int t = 0; t < T; ++t) Y.block<1, 3>(t, 3 * i) = (m[t].R.transpose() * (l.row(t).transpose() - m[t].t)).transpose();
  });
}

}  // namespace

CleanResult clean_markers(const MarkerData& capture, const CleanOptions& o, const std::function<void(double)>& progress) {
  check_marker_data(capture, "markers clean input");
  Surface s = build_surface(capture, o);
  CleanResult out;
  CleanReport& r = out.report;
  r.markers = s.size();
  Eigen::MatrixXd X(capture.frame_count(), 3 * s.size());
  for (int i = 0; i < s.size(); ++i) X.middleCols(3 * i, 3) = capture.xyz.middleCols(3 * s.columns[i], 3);
  r.gaps_before = count_gaps(X, s.size());
  Pieces ps = collect_pieces(capture);
  r.pieces = static_cast<int>(ps.list.size());
  find_parts(s, o, X);  // from the labelled samples (each marker's first run)
  // Half the one-ring's motion, half the marker's rigid part's where it has one (either alone
  // misleads now and then: the average made the fewest wrong merges).
  const Predictor rigid = [&](int i, int t, Eigen::Vector3d& e) {
    Eigen::Vector3d ring, part;
    const bool has_ring = anchored_estimate(s, X, i, t, ring), has_part = part_estimate(s, X, i, t, part);
    e = has_ring && has_part ? Eigen::Vector3d(0.5 * (ring + part)) : has_ring ? ring : part;
    return has_ring || has_part;
  };
  for (int pass = 0; pass < 2; ++pass) {
    merge_round(capture, s, o, rigid, ps, X, r);
    find_parts(s, o, X);  // from the merged trajectories: more frames
  }
  std::vector<char> checked;
  Neighbourhoods nb;
  checked_neighbourhoods(capture, s, o, nb, ps, checked, X, r);
  Eigen::MatrixXd Y = fill_holes(s, nb, X, r);
  // The filled trajectories predict better than a rigid fit of the neighbours where the body
  // deforms: the pieces left are matched against them, and the holes filled again.
  const Predictor filled = [&](int i, int t, Eigen::Vector3d& e) {
    e = at(Y, t, i);
    return e.allFinite();
  };
  for (int round = 0; round < o.rounds; ++round) {
    if (progress) progress(0.2 + 0.6 * (round + 1) / (o.rounds + 1));
    if (merge_round(capture, s, o, filled, ps, X, r) == 0) break;
    checked_neighbourhoods(capture, s, o, nb, ps, checked, X, r);
    Y = fill_holes(s, nb, X, r);
  }
  bool part_merged = false;  // the part rounds match by X alone: one fill after the last
  for (int round = 0; round < o.part_rounds; ++round) {
    if (part_round(capture, s, o, ps, X, r) == 0) break;
    part_merged = true;
    find_parts(s, o, X);
    checked_neighbourhoods(capture, s, o, nb, ps, checked, X, r);
  }
  if (part_merged) Y = fill_holes(s, nb, X, r);
  for (int round = 0; round < o.model_rounds; ++round) {
    if (model_round(capture, s, o, nb, Y, ps, X, r) == 0) break;  // nb: the models of the current X
    fit_neighbourhoods(s, o, X, nb);
    Y = fill_holes(s, nb, X, r);
  }
  for (size_t k = 0; k < ps.list.size(); ++k)
    if (!ps.done[k]) r.unmerged.push_back(capture.labels[ps.list[k].column]);
  r.merged = static_cast<int>(r.merges.size());
  if (progress) progress(0.8);
  smooth(s, o, Y);
  if (progress) progress(1.0);
  for (MarkerData* d : {&out.merged, &out.cleaned}) {
    d->rate = capture.rate;
    d->first_frame = capture.first_frame;
    for (int c : s.columns) d->labels.push_back(capture.labels[c]);
  }
  out.merged.xyz = std::move(X);
  out.cleaned.xyz = std::move(Y);
  r.gaps = find_gaps(out.merged);
  return out;
}

std::vector<GapRecord> find_gaps(const MarkerData& d) {
  std::vector<GapRecord> gaps;
  for (int i = 0; i < d.marker_count(); ++i)
    for (int t = 0; t < d.frame_count(); ++t) {
      if (d.present(t, i)) continue;
      const int first = t;
      while (t + 1 < d.frame_count() && !d.present(t + 1, i)) ++t;
      gaps.push_back({d.labels[i], first, t});
    }
  return gaps;
}

nlohmann::json clean_report_json(const CleanReport& r) {
  nlohmann::json merges = nlohmann::json::array();
  for (const auto& m : r.merges)
    merges.push_back({{"piece", m.piece}, {"marker", m.marker}, {"first_frame", m.first}, {"last_frame", m.last},
                      {"mean_distance_mm", m.mean_distance_mm}});
  nlohmann::json undone = nlohmann::json::array();
  for (const auto& m : r.undone)
    undone.push_back({{"piece", m.piece}, {"marker", m.marker}, {"first_frame", m.first}, {"last_frame", m.last},
                      {"model_distance_mm", m.mean_distance_mm}});
  nlohmann::json gaps = nlohmann::json::array();
  for (const auto& g : r.gaps) gaps.push_back({{"marker", g.marker}, {"first_frame", g.first}, {"last_frame", g.last}});
  return {{"markers", r.markers}, {"pieces", r.pieces}, {"merged", r.merged}, {"unmerged", r.unmerged},
          {"merges", merges}, {"merges_undone", undone}, {"gaps_before_merge", r.gaps_before}, {"gaps_found", r.gaps_after_merge},
          {"gaps_filled", r.gaps_filled}, {"gaps_left", r.gaps_left}, {"samples_missing", r.samples_missing},
          {"filled_from_neighbours", r.filled_from_neighbours}, {"filled_by_interpolation", r.filled_by_interpolation},
          {"gaps", gaps}};
}

std::string clean_summary_line(const CleanReport& r) {
  return std::to_string(r.markers) + " markers; " + std::to_string(r.merged) + " of " + std::to_string(r.pieces) +
         " pieces merged (" + std::to_string(r.unmerged.size()) + " left, " +
         std::to_string(r.undone.size()) + " merges undone); " + std::to_string(r.gaps_after_merge) +
         " gaps found (" + std::to_string(r.gaps_before) + " before merging), " + std::to_string(r.gaps_filled) + " filled, " +
         std::to_string(r.gaps_left) + " left; " + std::to_string(r.filled_from_neighbours) + " samples from neighbours, " +
         std::to_string(r.filled_by_interpolation) + " by interpolation";
}

}  // namespace bodymodel
