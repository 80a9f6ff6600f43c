// Registrations against ground truth, scan by scan and pooled
// (docs/evaluation.md#registration-against-ground-truth): correspondence, surface fit, holes,
// flipped and locally folded triangles by body region, joint rotation errors with their swing and
// twist. `bodymodel eval-registration` reads the files and prints; Python's
// `evaluate_registration` calls evaluate_scan directly.
#pragma once

#include <Eigen/Core>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/io/pose_csv.h"
#include "core/mesh.h"
#include "core/skeleton.h"
#include "registration/metrics.h"

namespace bodymodel {

// Body region of a MakeHuman bone name ("hands", "feet", "head/face", "neck", "legs", "arms",
// "shoulders", "torso/pelvis").
std::string bone_region(const std::string& bone);

// Swing (angle between the bone's posed directions) and twist (rotation about the bone's own axis
// that is left) of the error between two world rotations of a bone with rest direction d, degrees.
std::pair<double, double> swing_twist_deg(const Eigen::Matrix3d& estimated, const Eigen::Matrix3d& truth,
                                          const Eigen::Vector3d& d);

struct FlippedTriangle {
  int triangle = 0;
  std::string region;   // the region most of its vertices are in
  int bone = 0;         // the bone of largest weight at its first vertex
  double angle_deg = 0;  // between its normal and the truth's
  double truth_area_ratio = 0, registered_area_ratio = 0;  // against the rest template
  bool unseen = false, truth_folded = false;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // on the truth
};

struct HoleVertex {
  int vertex = 0;
  std::string region;
  int bone = 0;
  double surface_mm = 0, correspondence_mm = 0;
};

struct ScanEvaluation {
  RegistrationErrors errors;
  double correspondence_p95 = 0;
  int flipped_hands = 0, flipped_truth_folded = 0, flipped_seen_unfolded = 0;
  int folded_registration = 0, folded_truth = 0;  // locally folded (no truth needed)
  std::vector<FlippedTriangle> flipped;
  std::vector<HoleVertex> holes;  // hole vertices farther than hole_report_mm from the truth
  // With both poses: per major joint (RegistrationEvaluator::joints) and per distal phalanx.
  std::vector<double> joint_deg, swing_deg, twist_deg, finger_deg;
  double joint_median = NAN, joint_max = NAN, finger_median = NAN;
};

struct RegistrationEvaluationSummary {
  int scans = 0;
  double correspondence_median_of_means = NAN, correspondence_p95_all = NAN;
  double surface_mean = NAN, hole_max = 0, hole_median_of_max = NAN;
  int flipped = 0, flipped_truth_folded = 0, flipped_unseen = 0, flipped_seen_unfolded = 0;
  int folded_registration = 0, folded_truth = 0;
  std::map<std::string, int> flipped_by_region, flipped_unseen_by_region;
  size_t joint_samples = 0;
  double joint_median = NAN, joint_p95 = NAN;
  std::vector<std::string> joint_names;
  std::vector<double> joint_medians, joint_maxima, swing_medians, twist_medians;  // per major joint
  double finger_median = NAN, finger_p95 = NAN;
};

// Evaluates registrations of one template (its rest mesh, skeleton and skinning weights: the
// regions and rest areas) and pools them.
class RegistrationEvaluator {
 public:
  RegistrationEvaluator(Mesh rest, Skeleton skeleton, const SkinWeights& weights, double hole_report_mm = 10.0);

  // registered, truth: #V by 3 on the template's topology; scan: its points (the hole mask);
  // poses optional (joint errors only with both). InputError when the sizes disagree.
  ScanEvaluation evaluate_scan(const Eigen::MatrixX3d& registered, const Eigen::MatrixX3d& truth,
                               const Eigen::MatrixX3d& scan, const PoseRecord* registered_pose = nullptr,
                               const PoseRecord* truth_pose = nullptr) const;
  // Adds a scan's evaluation to the pooled figures.
  void add(const ScanEvaluation& e);
  RegistrationEvaluationSummary summary() const;

  const Skeleton& skeleton() const { return skeleton_; }
  const std::vector<std::string>& vertex_region() const { return vertex_region_; }
  const std::vector<int>& vertex_bone() const { return vertex_bone_; }
  const std::vector<int>& joints() const { return joints_; }

 private:
  Mesh rest_;
  Skeleton skeleton_;
  double hole_report_mm_;
  Eigen::VectorXd rest_area_;
  std::vector<std::string> vertex_region_;
  std::vector<int> vertex_bone_, joints_, fingertips_;
  std::vector<Eigen::Vector3d> rest_dir_;
  // Pooled.
  std::vector<double> scan_means_, all_vertices_, surface_means_, hole_max_, joint_all_, finger_all_;
  std::vector<std::vector<double>> per_joint_, per_swing_, per_twist_;
  RegistrationEvaluationSummary totals_;
};

}  // namespace bodymodel
