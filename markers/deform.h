// Driving a detailed mesh by dense markers (Park & Hodgins 2006 §5.2–5.3). The body is split into
// near-rigid parts; each part has a local reference frame (origin: its member markers' mean in
// the reference pose, axes: their covariance's eigenvectors). In every frame a part's rigid motion
// is the absolute-orientation fit (Horn / Kabsch) of its members to their local reference
// positions; what remains is approximated by a quadratic deformation A (eq. 6, least squares over
// the members) and the rest is interpolated at the members by radial basis functions (eq. 7: a
// cubic B-spline, dilation twice the largest distance from a member to its nearest member). A
// vertex is the weighted blend of where each of its parts puts it (eq. 8–9).
// Differences from the paper (docs/markers.md#driving-a-skin-by-the-markers), all options:
// A has a constant column (3 by 10, q = [x y z x² y² z² xy yz zx 1]) because the rigid alignment
// centres the members but not their quadratic terms, so a rigid-plus-quadratic motion needs it to
// be reproduced exactly; A is fitted with a ridge towards the identity and the B-spline system with
// one on its diagonal (exact interpolation of sparse markers is ill-conditioned: the B-spline is not
// positive definite in 3-D), so by default the markers are followed closely, not exactly; members
// that the part's fit does not explain are left out (errors of the cleaning); a vertex ignores parts
// with no member within reach (a quadratic extrapolates wildly far from its markers). The part
// weights of vertices and markers are the caller's (markers/deform_evaluation.h: an SSD rig's).
// Confidence (a departure, only when the caller gives one): a marker's confidence in (0, 1] weighs
// it in the rigid and quadratic fits and divides its RBF ridge; a marker below rbf_min_confidence
// (a sample the cleaning filled far from a seen one) is left out of the RBF residual, so the part's
// fit and its trusted neighbours' residual place the skin there.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/geometry.h"

namespace bodymodel {

struct MarkerSkinOptions {
  double membership = 0.2;        // a marker belongs to a part when its weight for it is at least this (§5.2)
  int min_members = 4;            // a part with fewer markers takes the nearest ones to its vertices
  double quadratic_ridge = 0.3;   // towards [I 0 | 0], relative to tr(QᵀQ)/10 of the part's quadratic vectors
  double dilation = 2;            // s_p = dilation × the largest nearest-member distance (the paper: twice)
  double rbf_ridge = 0.01;        // added to the kernel matrix's diagonal (φ(0) = 2/3); 0 = exact interpolation
  // A member whose residual exceeds max(outlier_factor × the median, outlier_floor × the part's
  // scale) is left out of the fits (0 = keep every member).
  double outlier_factor = 3, outlier_floor = 0.1;
  // A vertex leaves out the parts with no member within reach × the part's dilation (0: keep all).
  double reach = 1;
  // With confidences: a marker below this is left out of the RBF residual; the others' ridge is
  // rbf_ridge / confidence (1: only fully trusted markers are interpolated).
  double rbf_min_confidence = 0.05;
};

// rigid: parts' rigid motion only; quadratic: plus A; full: plus the RBF residual (the paper's method).
enum class MarkerSkinStage { rigid, quadratic, full };

struct MarkerSkinPart {
  std::vector<int> members;          // marker indices
  Eigen::Vector3d origin;            // reference-pose centroid of the members
  Eigen::Matrix3d axes;              // rows: principal axes (a rotation); local = axes · (p − origin)
  double scale = 1;                  // RMS member radius: quadratic vectors are built from local / scale
  double dilation = 1;               // s_p, in the caller's unit
  Eigen::MatrixX3d member_local;     // members' local reference positions
  std::vector<int> vertices;         // vertices with a weight for this part
  Eigen::VectorXd vertex_weight;
  Eigen::MatrixX3d vertex_local;     // their local reference positions
};

struct MarkerSkin {
  int vertex_count = 0, marker_count = 0;
  double quadratic_ridge = MarkerSkinOptions().quadratic_ridge;
  double rbf_ridge = MarkerSkinOptions().rbf_ridge;
  double rbf_min_confidence = MarkerSkinOptions().rbf_min_confidence;
  double outlier_factor = MarkerSkinOptions().outlier_factor, outlier_floor = MarkerSkinOptions().outlier_floor;
  std::vector<MarkerSkinPart> parts;  // parts without vertices are dropped
};

// rest: #V by 3 (the detailed mesh in the reference pose); reference_markers: #M by 3 (same unit);
// vertex_weights #V by P and marker_weights #M by P (non-negative; each vertex's row is normalised to
// sum to one). A marker belongs to the parts it weighs at least `membership` for, and to its largest.
// InputError when shapes disagree, a weight is negative or not finite, a vertex has no weight, or
// there are fewer than min_members (≥ 3) markers.
MarkerSkin build_marker_skin(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3d& reference_markers,
                             const Eigen::MatrixXd& vertex_weights, const Eigen::MatrixXd& marker_weights,
                             const MarkerSkinOptions& options = {});

// One part's motion in one frame: the rigid map current → local (R, t), A (3 by 10, on local / scale)
// and the RBF weights (#members by 3, in units of scale).
struct PartMotion {
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  Eigen::Matrix<double, 3, 10> A;
  Eigen::MatrixX3d rbf;
};
// confidence: #M in (0, 1] (empty: every marker 1, the paper's method).
PartMotion fit_part_motion(const MarkerSkinPart& part, const Eigen::MatrixX3d& markers, MarkerSkinStage stage,
                           const MarkerSkin& skin, const Eigen::VectorXd& confidence = Eigen::VectorXd());
// Where the part puts a point given by its local reference position (eq. 8), in global coordinates.
Eigen::Vector3d part_position(const MarkerSkinPart& part, const PartMotion& m, const Eigen::Vector3d& local);

// The deformed mesh (#V by 3) for the markers of one frame (#M by 3, every marker present), each
// weighed by its confidence (#M in (0, 1]; empty: all 1, the paper's method).
// InputError when the marker count differs, a marker is not finite or a confidence is outside (0, 1].
Eigen::MatrixX3d deform_by_markers(const MarkerSkin& skin, const Eigen::MatrixX3d& markers,
                                   MarkerSkinStage stage = MarkerSkinStage::full,
                                   const Eigen::VectorXd& confidence = Eigen::VectorXd());
// InputError unless `confidence` is empty or #M values in (0, 1].
void check_confidence(const Eigen::VectorXd& confidence, Eigen::Index markers);

// 0/1 weights: 1 where r ≤ max(factor × median(r), floor); all 1 when factor ≤ 0, fewer than 4
// residuals or fewer than 3 would stay.
Eigen::VectorXd inlier_weights(const Eigen::VectorXd& r, double factor, double floor);
// Kabsch (A → B) refitted on the inliers of its residuals (inlier_weights), up to 3 rounds; each
// point weighed by `prior` too (empty: 1).
RigidMotion fit_rigid_robust(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B, double factor, double floor,
                             Eigen::VectorXd* weights = nullptr, const Eigen::VectorXd& prior = Eigen::VectorXd());

// The cubic B-spline of eq. 7 (support |r| < 2, φ(0) = 2/3).
double cubic_bspline(double r);

}  // namespace bodymodel
