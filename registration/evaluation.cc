#include "registration/evaluation.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/error.h"
#include "core/geometry.h"
#include "core/rotation.h"
#include "core/statistics.h"

namespace bodymodel {

std::string bone_region(const std::string& b) {
  auto has = [&](const char* k) { return b.find(k) != std::string::npos; };
  if (has("finger") || has("metacarpal") || has("wrist")) return "hands";
  if (has("toe") || has("foot")) return "feet";
  if (has("head") || has("jaw") || has("eye") || has("tongue") || has("teeth") || has("ear") ||
      has("lip") || has("nose") || has("cheek") || has("brow") || has("temple") || has("chin") ||
      has("levator") || has("oris") || has("oculi") || has("risorius") || has("special"))
    return "head/face";
  if (has("neck")) return "neck";
  if (has("upperleg") || has("lowerleg")) return "legs";
  if (has("upperarm") || has("lowerarm")) return "arms";
  if (has("clavicle") || has("shoulder")) return "shoulders";
  return "torso/pelvis";
}

std::pair<double, double> swing_twist_deg(const Eigen::Matrix3d& Qe, const Eigen::Matrix3d& Qt,
                                          const Eigen::Vector3d& d) {
  const Eigen::Quaterniond q(Qt.transpose() * Qe);  // the error in the bone's rest frame
  const Eigen::Vector3d e = q * d;
  const double swing = std::acos(std::clamp(e.dot(d), -1.0, 1.0)) * 180.0 / M_PI;
  double twist = 2.0 * std::atan2(q.vec().dot(d), q.w()) * 180.0 / M_PI;
  if (twist > 180) twist -= 360;
  if (twist < -180) twist += 360;
  return {swing, std::abs(twist)};
}

RegistrationEvaluator::RegistrationEvaluator(Mesh rest, Skeleton skeleton, const SkinWeights& W,
                                             double hole_report_mm)
    : rest_(std::move(rest)), skeleton_(std::move(skeleton)), hole_report_mm_(hole_report_mm) {
  const Skeleton& sk = skeleton_;
  if (W.rows() != rest_.V.rows())
    throw InputError(fmt::format("registration evaluation: {} skinning weight rows for {} template vertices",
                                 W.rows(), rest_.V.rows()));
  rest_area_ = face_areas(rest_.V, rest_.F);
  for (const auto& n : major_joints())
    if (sk.find(n) >= 0) joints_.push_back(sk.find(n));
  // The distal phalanx of each finger, evaluated apart (not a major joint).
  for (const char* side : {".L", ".R"})
    for (int f = 1; f <= 5; ++f)
      if (const int b = sk.find("finger" + std::to_string(f) + "-3" + side); b >= 0) fingertips_.push_back(b);
  rest_dir_.assign(sk.bone_count(), Eigen::Vector3d::UnitY());
  for (int b = 0; b < sk.bone_count(); ++b) {
    const Eigen::Vector3d d = (sk.tails.row(b) - sk.heads.row(b)).transpose();
    if (d.norm() > 1e-9) rest_dir_[b] = d.normalized();
  }
  vertex_region_.assign(W.rows(), "torso/pelvis");
  vertex_bone_.assign(W.rows(), 0);
  for (int i = 0; i < W.outerSize(); ++i) {
    double best = 0;
    for (SkinWeights::InnerIterator it(W, i); it; ++it)
      if (it.value() > best) {
        best = it.value();
        vertex_region_[i] = bone_region(sk.names[it.col()]);
        vertex_bone_[i] = int(it.col());
      }
  }
  per_joint_.resize(joints_.size());
  per_swing_.resize(joints_.size());
  per_twist_.resize(joints_.size());
  for (int j : joints_) totals_.joint_names.push_back(sk.names[j]);
}

ScanEvaluation RegistrationEvaluator::evaluate_scan(const Eigen::MatrixX3d& reg, const Eigen::MatrixX3d& truth,
                                                    const Eigen::MatrixX3d& scan, const PoseRecord* reg_pose,
                                                    const PoseRecord* truth_pose) const {
  const Eigen::MatrixX3i& F = rest_.F;
  if (reg.rows() != rest_.V.rows() || truth.rows() != rest_.V.rows())
    throw InputError(fmt::format("registration evaluation: {} registered and {} true vertices, the template has {}",
                                 reg.rows(), truth.rows(), rest_.V.rows()));
  ScanEvaluation s;
  const RegistrationErrors& e = s.errors = registration_errors(reg, truth, F, scan);
  s.correspondence_p95 =
      percentile(std::vector<double>(e.vertex_errors.data(), e.vertex_errors.data() + e.vertex_errors.size()), 95);
  for (Eigen::Index i = 0; i < truth.rows(); ++i)
    if (e.hole_vertex[i] && e.surface_errors(i) > hole_report_mm_)
      s.holes.push_back({int(i), vertex_region_[i], vertex_bone_[i], e.surface_errors(i), e.vertex_errors(i)});

  const Eigen::MatrixX3d Nr = face_normals(reg, F), Nt = face_normals(truth, F);
  const Eigen::VectorXd reg_area = face_areas(reg, F), truth_area = face_areas(truth, F);
  const std::vector<char> truth_folded = locally_folded_triangles(truth, rest_.V, F);
  const std::vector<char> reg_folded = locally_folded_triangles(reg, rest_.V, F);
  s.folded_registration = int(std::count(reg_folded.begin(), reg_folded.end(), 1));
  s.folded_truth = int(std::count(truth_folded.begin(), truth_folded.end(), 1));
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    if (!e.flipped[f]) continue;
    FlippedTriangle t;
    t.triangle = int(f);
    t.truth_folded = truth_folded[f];
    t.unseen = e.hole_vertex[F(f, 0)] && e.hole_vertex[F(f, 1)] && e.hole_vertex[F(f, 2)];
    std::map<std::string, int> votes;  // the region most of the triangle's vertices are in
    for (int c = 0; c < 3; ++c) ++votes[vertex_region_[F(f, c)]];
    t.region = std::max_element(votes.begin(), votes.end(),
                                [](const auto& x, const auto& y) { return x.second < y.second; })->first;
    t.bone = vertex_bone_[F(f, 0)];
    t.angle_deg = std::acos(std::clamp(Nr.row(f).dot(Nt.row(f)), -1.0, 1.0)) * 180.0 / M_PI;
    const double ra = std::max(rest_area_(f), 1e-12);
    t.truth_area_ratio = truth_area(f) / ra;
    t.registered_area_ratio = reg_area(f) / ra;
    t.centroid = ((truth.row(F(f, 0)) + truth.row(F(f, 1)) + truth.row(F(f, 2))) / 3.0).transpose();
    s.flipped_truth_folded += t.truth_folded;
    s.flipped_seen_unfolded += !t.unseen && !t.truth_folded;
    s.flipped_hands += t.region == "hands";
    s.flipped.push_back(std::move(t));
  }

  if (reg_pose && truth_pose) {
    const auto Qe = reg_pose->world_rotations(skeleton_);
    const auto Qt = truth_pose->world_rotations(skeleton_);
    for (int j : joints_) {
      s.joint_deg.push_back(rotation_angle_deg(Qe[j], Qt[j]));
      const auto [sw, tw] = swing_twist_deg(Qe[j], Qt[j], rest_dir_[j]);
      s.swing_deg.push_back(sw);
      s.twist_deg.push_back(tw);
    }
    for (int b : fingertips_) s.finger_deg.push_back(rotation_angle_deg(Qe[b], Qt[b]));
    s.finger_median = median(s.finger_deg);
    s.joint_median = median(s.joint_deg);
    if (!s.joint_deg.empty()) s.joint_max = *std::max_element(s.joint_deg.begin(), s.joint_deg.end());
  }
  return s;
}

void RegistrationEvaluator::add(const ScanEvaluation& s) {
  const RegistrationErrors& e = s.errors;
  RegistrationEvaluationSummary& t = totals_;
  ++t.scans;
  all_vertices_.insert(all_vertices_.end(), e.vertex_errors.data(), e.vertex_errors.data() + e.vertex_errors.size());
  scan_means_.push_back(e.correspondence_mean);
  surface_means_.push_back(e.surface_mean);
  hole_max_.push_back(e.hole_max);
  t.hole_max = std::max(t.hole_max, e.hole_max);
  t.flipped += e.flipped_triangles;
  t.flipped_unseen += e.flipped_unseen;
  t.flipped_truth_folded += s.flipped_truth_folded;
  t.flipped_seen_unfolded += s.flipped_seen_unfolded;
  t.folded_registration += s.folded_registration;
  t.folded_truth += s.folded_truth;
  for (const FlippedTriangle& f : s.flipped) {
    ++t.flipped_by_region[f.region];
    t.flipped_unseen_by_region[f.region] += f.unseen;
  }
  if (s.joint_deg.size() == joints_.size())
    for (size_t j = 0; j < joints_.size(); ++j) {
      per_joint_[j].push_back(s.joint_deg[j]);
      per_swing_[j].push_back(s.swing_deg[j]);
      per_twist_[j].push_back(s.twist_deg[j]);
    }
  joint_all_.insert(joint_all_.end(), s.joint_deg.begin(), s.joint_deg.end());
  finger_all_.insert(finger_all_.end(), s.finger_deg.begin(), s.finger_deg.end());
}

RegistrationEvaluationSummary RegistrationEvaluator::summary() const {
  RegistrationEvaluationSummary t = totals_;
  t.correspondence_median_of_means = median(scan_means_);
  t.correspondence_p95_all = percentile(all_vertices_, 95);
  if (!surface_means_.empty())
    t.surface_mean = std::accumulate(surface_means_.begin(), surface_means_.end(), 0.0) / double(surface_means_.size());
  t.hole_median_of_max = median(hole_max_);
  t.joint_samples = joint_all_.size();
  t.joint_median = median(joint_all_);
  t.joint_p95 = percentile(joint_all_, 95);
  for (size_t j = 0; j < joints_.size(); ++j) {
    t.joint_medians.push_back(median(per_joint_[j]));
    t.joint_maxima.push_back(per_joint_[j].empty() ? NAN : *std::max_element(per_joint_[j].begin(), per_joint_[j].end()));
    t.swing_medians.push_back(median(per_swing_[j]));
    t.twist_medians.push_back(median(per_twist_[j]));
  }
  t.finger_median = median(finger_all_);
  t.finger_p95 = percentile(finger_all_, 95);
  return t;
}

}  // namespace bodymodel
