#include "markers/deform_evaluation.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <numeric>

#include "core/error.h"
#include "core/geometry.h"
#include "skinning/bone_recovery.h"
#include "skinning/fit_lbs.h"
#include "skinning/fit_mwe.h"
#include "skinning/skinning_examples.h"

namespace bodymodel {
namespace {

// The capture frames per mesh frame; InputError for what compare_marker_skins refuses.
int check_inputs(const std::vector<Eigen::MatrixX3d>& meshes, const MarkerData& d, const MarkerDeformOptions& o) {
  check_marker_data(d, "markers deform input");
  if (meshes.size() < 3) throw InputError("markers deform: need at least 3 meshes (training and held-out frames), found " + std::to_string(meshes.size()));
  for (int m = 0; m < d.marker_count(); ++m)
    if (!d.labels[static_cast<size_t>(m)].empty() && d.labels[static_cast<size_t>(m)][0] == '*')
      throw InputError("markers deform input: unlabelled piece '" + d.labels[static_cast<size_t>(m)] + "' (run markers clean first)");
  for (int f = 0; f < d.frame_count(); ++f)
    for (int m = 0; m < d.marker_count(); ++m)
      if (!d.present(f, m))
        throw InputError("markers deform input: marker '" + d.labels[static_cast<size_t>(m)] + "' is missing at frame " +
                         std::to_string(f + 1) + " (run markers clean first)");
  if (!(o.mesh_rate > 0) || !std::isfinite(o.mesh_rate))
    throw InputError("markers deform: the mesh rate must be a positive number, found " + std::to_string(o.mesh_rate));
  const double ratio = d.rate / o.mesh_rate;
  const int k = ratio < 1e6 ? static_cast<int>(std::lround(ratio)) : 0;
  if (k < 1 || std::abs(ratio - k) > 1e-6)
    throw InputError("markers deform: the capture rate (" + std::to_string(d.rate) + " Hz) must be a whole multiple of the mesh rate (" + std::to_string(o.mesh_rate) + ")");
  if (o.confidence.size() && (o.confidence.rows() != d.frame_count() || o.confidence.cols() != d.marker_count()))
    throw InputError("markers deform: the confidences are " + std::to_string(o.confidence.rows()) + " by " + std::to_string(o.confidence.cols()) +
                     ", the capture has " + std::to_string(d.frame_count()) + " frames by " + std::to_string(d.marker_count()) + " markers");
  for (Eigen::Index f = 0; f < o.confidence.rows(); ++f) check_confidence(o.confidence.row(f).transpose(), o.confidence.cols());
  const int expected = (static_cast<int>(meshes.size()) - 1) * k + 1;
  if (d.frame_count() != expected)
    throw InputError("markers deform: the capture has " + std::to_string(d.frame_count()) + " frames but " +
                     std::to_string(meshes.size()) + " meshes at " + std::to_string(o.mesh_rate) + " fps make " +
                     std::to_string(expected) + " at " + std::to_string(d.rate) + " Hz");
  return k;
}

Eigen::VectorXi nearest_vertices(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& P, Eigen::VectorXd* distance) {
  Eigen::VectorXi nearest(P.rows());
  distance->resize(P.rows());
  for (Eigen::Index i = 0; i < P.rows(); ++i)
    (*distance)(i) = std::sqrt((V.rowwise() - P.row(i)).rowwise().squaredNorm().minCoeff(&nearest(i)));
  return nearest;
}

// Each part's markers: those whose nearest vertex is in the part, topped up with the nearest to
// the part's vertex centroid.
std::vector<std::vector<int>> skeleton_markers(const Eigen::MatrixX3d& rest, const Eigen::VectorXi& vertex_part, int parts,
                                               const Eigen::MatrixX3d& reference, const Eigen::VectorXi& nearest, int min_members) {
  std::vector<std::vector<int>> members(static_cast<size_t>(parts));
  for (Eigen::Index i = 0; i < reference.rows(); ++i)
    members[static_cast<size_t>(vertex_part(nearest(i)))].push_back(static_cast<int>(i));
  for (int p = 0; p < parts; ++p) {
    auto& mem = members[static_cast<size_t>(p)];
    if (static_cast<int>(mem.size()) >= min_members) continue;
    Eigen::RowVector3d c = Eigen::RowVector3d::Zero();
    int n = 0;
    for (Eigen::Index j = 0; j < rest.rows(); ++j)
      if (vertex_part(j) == p) c += rest.row(j), ++n;
    if (n) c /= n;
    std::vector<int> order(static_cast<size_t>(reference.rows()));
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](int a, int b) {
      return (reference.row(a) - c).squaredNorm() < (reference.row(b) - c).squaredNorm();
    });
    for (int i : order) {
      if (static_cast<int>(mem.size()) >= min_members) break;
      if (std::find(mem.begin(), mem.end(), i) == mem.end()) mem.push_back(i);
    }
  }
  return members;
}

MethodError method_error(const std::string& name, const std::vector<Eigen::MatrixX3d>& truth,
                         const std::function<Eigen::MatrixX3d(size_t)>& pose) {
  MethodError e{name, 0, 0, {}};
  double sum = 0;
  long n = 0;
  for (size_t k = 0; k < truth.size(); ++k) {
    const Eigen::VectorXd d = (pose(k) - truth[k]).rowwise().norm();
    e.frame_mean.push_back(d.mean());
    e.max = std::max(e.max, d.maxCoeff());
    sum += d.sum(), n += d.size();
  }
  e.mean = n ? sum / static_cast<double>(n) : 0;
  return e;
}

// Row `frame` of the samples' confidence (empty when there is none).
Eigen::VectorXd frame_confidence(const MarkerDeformOptions& o, int frame) {
  return o.confidence.size() ? Eigen::VectorXd(o.confidence.row(frame).transpose()) : Eigen::VectorXd();
}

// SSD and MWE rigs fitted to the training meshes posed by the marker skeleton.
void fit_rigs(MarkerDeformComparison& r, const std::vector<Eigen::MatrixX3d>& meshes, const MarkerData& d,
              const MarkerDeformOptions& o) {
  SkinningExamples ex;
  ex.rest = meshes[0];
  const Eigen::MatrixX3d reference = marker_frame(d, 0);
  for (int k : r.train_meshes) {
    const int f = k * r.frames_per_mesh;
    ex.transforms.push_back(fit_marker_skeleton(reference, marker_frame(d, f), r.part_markers, o.skin, frame_confidence(o, f)));
    ex.poses.push_back(meshes[static_cast<size_t>(k)]);
  }
  LbsFitOptions lo;
  lo.max_influences = o.max_influences;
  r.ssd = fit_lbs(ex, {}, lo);
  r.mwe = fit_mwe(ex, &r.ssd);
}

// Each vertex's part weights interpolated from its k nearest reference markers (inverse distance),
// as the paper interpolates the markers' weights over the marker surface.
Eigen::MatrixXd vertex_weights_from_markers(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3d& reference,
                                            const Eigen::MatrixXd& marker_weights, int k) {
  Eigen::MatrixXd W = Eigen::MatrixXd::Zero(rest.rows(), marker_weights.cols());
  const int n = std::min<int>(k, static_cast<int>(reference.rows()));
  for (Eigen::Index j = 0; j < rest.rows(); ++j) {
    const Eigen::VectorXd d2 = (reference.rowwise() - rest.row(j)).rowwise().squaredNorm();
    std::vector<int> order(static_cast<size_t>(d2.size()));
    std::iota(order.begin(), order.end(), 0);
    std::partial_sort(order.begin(), order.begin() + n, order.end(), [&](int a, int b) { return d2(a) < d2(b); });
    for (int i = 0; i < n; ++i)
      W.row(j) += marker_weights.row(order[static_cast<size_t>(i)]) / std::max(std::sqrt(d2(order[static_cast<size_t>(i)])), 1e-9);
    W.row(j) /= W.row(j).sum();
  }
  return W;
}

}  // namespace

Eigen::MatrixX3d marker_frame(const MarkerData& d, int frame) {
  Eigen::MatrixX3d P(d.marker_count(), 3);
  for (int m = 0; m < d.marker_count(); ++m) P.row(m) = d.at(frame, m).transpose();
  return P;
}

Eigen::MatrixXd filled_sample_confidence(const MarkerData& d, const std::vector<GapRecord>& gaps, double filled_weight,
                                         double halflife) {
  if (!(filled_weight > 0 && filled_weight <= 1)) throw InputError("the filled samples' weight must be in (0, 1], found " + std::to_string(filled_weight));
  if (!(halflife > 0) || !std::isfinite(halflife)) throw InputError("the filled samples' half-life must be positive, found " + std::to_string(halflife));
  std::map<std::string, int> column;
  for (int i = 0; i < d.marker_count(); ++i) column[d.labels[static_cast<size_t>(i)]] = i;
  Eigen::MatrixXd c = Eigen::MatrixXd::Ones(d.frame_count(), d.marker_count());
  for (const GapRecord& g : gaps) {
    const auto it = column.find(g.marker);
    if (it == column.end()) throw InputError("cleaning report: gap of marker '" + g.marker + "', which the capture does not have");
    if (g.first < 0 || g.last < g.first || g.last >= d.frame_count())
      throw InputError("cleaning report: gap of marker '" + g.marker + "' over frames " + std::to_string(g.first) + "-" +
                       std::to_string(g.last) + ", not within the capture's " + std::to_string(d.frame_count()) +
                       " frames (a report of another capture?)");
    for (int f = g.first; f <= g.last; ++f) {  // frames to the nearest sample seen, either side
      const int before = g.first > 0 ? f - g.first + 1 : d.frame_count();
      const int after = g.last + 1 < d.frame_count() ? g.last + 1 - f : d.frame_count();
      c(f, it->second) = filled_weight * std::exp2(-(std::min(before, after) - 1) / halflife);
    }
  }
  return c;
}

BoneTransforms fit_marker_skeleton(const Eigen::MatrixX3d& reference, const Eigen::MatrixX3d& markers,
                                   const std::vector<std::vector<int>>& part_markers, const MarkerSkinOptions& o,
                                   const Eigen::VectorXd& confidence) {
  BoneTransforms M;
  for (const auto& mem : part_markers) {
    Eigen::MatrixX3d A(static_cast<Eigen::Index>(mem.size()), 3), B(static_cast<Eigen::Index>(mem.size()), 3);
    Eigen::VectorXd c = Eigen::VectorXd::Ones(static_cast<Eigen::Index>(mem.size()));
    for (size_t k = 0; k < mem.size(); ++k) {
      A.row(static_cast<Eigen::Index>(k)) = reference.row(mem[k]);
      B.row(static_cast<Eigen::Index>(k)) = markers.row(mem[k]);
      if (confidence.size()) c(static_cast<Eigen::Index>(k)) = confidence(mem[k]);
    }
    const double scale = std::sqrt((A.rowwise() - A.colwise().mean()).rowwise().squaredNorm().mean());
    const RigidMotion g = fit_rigid_robust(A, B, o.outlier_factor, o.outlier_floor * scale, nullptr, c);
    Eigen::Affine3d T = Eigen::Affine3d::Identity();
    T.linear() = g.R;
    T.translation() = g.t;
    M.push_back(T);
  }
  return M;
}

MarkerDeformComparison compare_marker_skins(const std::vector<Eigen::MatrixX3d>& meshes, const Eigen::MatrixX3i& F,
                                            const MarkerData& d, const MarkerDeformOptions& o,
                                            const ProgressCallback& progress) {
  MarkerDeformComparison r;
  r.frames_per_mesh = check_inputs(meshes, d, o);
  const Eigen::MatrixX3d reference = marker_frame(d, 0);
  Eigen::VectorXd distance;
  const Eigen::VectorXi nearest = nearest_vertices(meshes[0], reference, &distance);
  for (int m = 0; m < d.marker_count(); ++m)
    if (distance(m) > o.max_marker_distance)
      throw InputError("markers deform: marker '" + d.labels[static_cast<size_t>(m)] + "' is " + std::to_string(distance(m)) +
                       " from the reference mesh in frame 1 (more than " + std::to_string(o.max_marker_distance) +
                       "): not this mesh's markers, or another unit");
  std::vector<Eigen::MatrixX3d> train, truth;
  for (int k = 0; k < static_cast<int>(meshes.size()); ++k) {
    (k % 2 ? r.test_meshes : r.train_meshes).push_back(k);
    (k % 2 ? truth : train).push_back(meshes[static_cast<size_t>(k)]);
  }
  report_progress(progress, 0.05, "parts");
  BoneRecoveryOptions bo;
  bo.bones = o.parts;
  bo.seed = o.seed;
  const RecoveredBones parts = recover_bones(meshes[0], F, train, bo);
  r.part_markers = skeleton_markers(meshes[0], parts.vertex_bone, o.parts, reference, nearest, o.skin.min_members);
  report_progress(progress, 0.3, "rigs");
  fit_rigs(r, meshes, d, o);
  const Eigen::MatrixXd W = dense_weights(r.ssd);
  Eigen::MatrixXd marker_weights(reference.rows(), W.cols());
  for (Eigen::Index i = 0; i < reference.rows(); ++i) marker_weights.row(i) = W.row(nearest(i));
  const Eigen::MatrixXd vertex_weights =
      o.weight_markers > 0 ? vertex_weights_from_markers(meshes[0], reference, marker_weights, o.weight_markers) : W;
  r.skin = build_marker_skin(meshes[0], reference, vertex_weights, marker_weights, o.skin);
  report_progress(progress, 0.7, "held-out frames");
  for (int k : r.test_meshes) r.test_frames.push_back(k * r.frames_per_mesh);
  auto at = [&](size_t k) { return marker_frame(d, r.test_frames[k]); };
  auto trust = [&](size_t k) { return frame_confidence(o, r.test_frames[k]); };
  const std::pair<const char*, MarkerSkinStage> stages[] = {
      {"park", MarkerSkinStage::full}, {"park-quadratic", MarkerSkinStage::quadratic}, {"park-rigid", MarkerSkinStage::rigid}};
  for (const auto& [name, stage] : stages)
    r.errors.push_back(method_error(name, truth, [&, st = stage](size_t k) { return deform_by_markers(r.skin, at(k), st, trust(k)); }));
  for (const SkinningRig* rig : {&r.ssd, &r.mwe})
    r.errors.push_back(method_error(rig == &r.ssd ? "ssd" : "mwe", truth, [&](size_t k) {
      return evaluate_rig(*rig, fit_marker_skeleton(reference, at(k), r.part_markers, o.skin, trust(k)));
    }));
  report_progress(progress, 1.0, "done");
  return r;
}

}  // namespace bodymodel
