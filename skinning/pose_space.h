// Example-based skinning over an SSD rig: corrections learnt at the example poses and
// interpolated in pose space by radial basis functions (the CMU 15-864 skinning lecture's "Pose
// Space Deformation" and "EigenSkin", and Park & Hodgins 2006's quadratic deformation).
//
//   psd        Lewis et al. 2000: v' = Σ_k w_k M_k (v + d(x)). At example pose p the corrective
//              displacement d_p is the one that makes the SSD land on the example, taken into the
//              rest pose through the blended linear part L = Σ_k w_k R_k (d_p = L⁻¹ (q_p − SSD_p),
//              a damped inverse); d(x) = d̄ + Σ_p c_p φ(‖x − x_p‖) interpolates the d_p − d̄.
//   eigenskin  Kry et al. 2002: the same displacements, compressed per vertex neighbourhood by PCA
//              (a few eigen-displacements per neighbourhood, i.e. a few basis weights per vertex);
//              the neighbourhood's mode coefficients are what the RBFs interpolate.
//   quadratic  Park & Hodgins 2006 §5.3 (the issue calls it §4), applied to mesh vertices in place
//              of markers: every near-rigid part (here: a bone, its members the vertices with SSD
//              weight ≥ 0.2 as in their §5.2, plus the vertices it is primary for) has, in its
//              local frame (centroid and principal axes of its rest members, eq. 6's frame), a
//              quadratic deformation A_p fitted per example by least squares (eq. 6, ridge
//              towards the rigid [I 0 0]); a vertex is the SSD-weighted blend of its parts (eq. 9).
//              The paper's A is 3 by 9 because each part's frame comes from aligning its own
//              markers (Horn), which centres them; here the part frames are the bone maps shared
//              by every method (SSD weights held fixed), which need not centre a part, so A gets a
//              translation column: 3 by 10, q = [x y z x² y² z² xy yz zx 1].
//              Unlike the paper, which has the markers of every frame, a new pose has no markers:
//              A is interpolated in pose space by RBFs over the examples, and so is the residual
//              (the paper's spatial RBF residual of eq. 7 becomes a per-vertex pose-space RBF).
//
// Pose space. There is no skeleton hierarchy (bones may be recovered from the meshes), so a pose
// is described locally, as in Kry et al.'s joint supports and Kurihara & Miyata 2004's weighted
// PSD. Bones a and b are joined when some vertex has SSD weight ≥ 0.1 on both; the "joint angle"
// is their relative rotation R_aᵀR_b. Vertices are grouped into neighbourhoods: those sharing
// their primary (largest-weight) bone a and their second bone (when its weight is ≥ 0.1). For a
// neighbourhood the distance between poses x and y is
//   D(x, y)² = Σ_{b joined to a} ω_b ‖R_a(x)ᵀR_b(x) − R_a(y)ᵀR_b(y)‖²_F,
// ω_b = the mean over the neighbourhood's vertices of w_a + w_b (Kurihara & Miyata's joint weight:
// a vertex counts a joint with its weights on the two bones it joins, so a vertex carried by the
// upper arm alone still feels the elbow): only the joints around it count. A quadratic part (the
// vertices whose primary bone is a) uses the same with its own ω.
// Kernel φ(D) = exp(−D²/(2σ²)), σ = the kernel width times the median D between distinct
// examples (a neighbourhood moved by one bone only has D ≡ 0 and keeps the mean correction).
// The RBF system is regularised: (Φ + λI) c = d − d̄ (λ = 0 is Lewis's exact interpolation, which
// over-fits noisy captures). Far from every example the correction returns to the mean d̄.
// PSD and EigenSkin thus share their pose space: EigenSkin is PSD with each neighbourhood's
// displacement fields truncated to a few principal components.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/progress.h"
#include "skinning/skinning_examples.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

enum class PoseSpaceMethod { psd, eigenskin, quadratic };

// "psd", "eigenskin", "quadratic" ↔ the enum; throws InputError for an unknown name.
PoseSpaceMethod parse_pose_space_method(const std::string& name);
std::string pose_space_method_name(PoseSpaceMethod m);
// True if `name` is one of the three (no throw).
bool is_pose_space_method(const std::string& name);

struct PoseSpaceOptions {
  PoseSpaceMethod method = PoseSpaceMethod::psd;
  // σ = kernel_width × median distance between the examples (per vertex / neighbourhood / part).
  double kernel_width = 1.0;
  // λ added to the diagonal of the kernel matrix (whose diagonal is 1): regularised RBF.
  double rbf_ridge = 1e-2;
  // PSD / EigenSkin: damping ε of the pre-skinning inverse d = (LᵀL + εI)⁻¹ Lᵀ r; L's singular
  // values are ≈ 1 except where SSD collapses (candy wrapper), where ε keeps d bounded.
  double inverse_damping = 1e-2;
  // EigenSkin: eigen-displacements kept per neighbourhood (Kry et al. §4: "a few").
  int eigenskin_modes = 4;
  // Neighbourhoods: vertices sharing their primary bone and their second bone, when the second
  // bone's weight is at least this (else the primary bone alone).
  double neighbourhood_weight = 0.1;
  // Quadratic: part membership (Park & Hodgins §5.2: 0.2) and the ridge of the per-example
  // 3 by 10 fit towards [I 0 0], relative to tr(QᵀQ)/10 of the part's quadratic vectors Q.
  double membership_weight = 0.2;
  double quadratic_ridge = 1e-3;
  // Quadratic: fit the pose-space residual RBF on top (Park & Hodgins' second stage).
  bool quadratic_residual = true;
};

struct PoseSpaceFitSummary {
  PoseSpaceMethod method = PoseSpaceMethod::psd;
  int vertices = 0, poses = 0, groups = 0;   // neighbourhoods
  double mean_modes = 0;                     // EigenSkin: modes kept per neighbourhood, mean
  double rms_residual = 0, max_residual = 0, seconds = 0;
  std::string brief() const;
};

// A fitted example-based rig. Everything is stored per vertex / neighbourhood / part so that
// posing needs only the bone maps of the new pose.
struct PoseSpaceRig {
  PoseSpaceMethod method = PoseSpaceMethod::psd;
  SkinningRig base;                        // the SSD rig (#V, #B, K slots)
  int poses = 0;                           // P examples
  // Pose features: relative rotations R_aᵀR_b of the bone pairs used, at every example.
  Eigen::MatrixXi pairs;                   // #pairs by 2 (a, b)
  Eigen::MatrixXd pair_features;           // #pairs by 9·P (row-major 3 by 3 blocks, example-major)
  Eigen::VectorXi primary;                 // #V primary bone
  // Neighbourhoods (#G): pose descriptor (pair indices, ω) and kernel width σ (0 = constant).
  Eigen::VectorXi vertex_group;            // #V
  std::vector<std::vector<int>> group_pairs;
  std::vector<std::vector<double>> group_omega;
  Eigen::VectorXd group_sigma;             // #G
  // Per vertex mean correction and RBF coefficients (psd: rest frame; quadratic residual: the
  // primary part's local axes; data units). EigenSkin keeps no vertex_coef.
  Eigen::MatrixXd vertex_mean;             // #V by 3
  Eigen::MatrixXd vertex_coef;             // #V by 3·P (example-major) or 0 by 0
  // EigenSkin: per neighbourhood P by m RBF coefficients of the mode weights; per vertex its
  // neighbourhood's m modes at the vertex (x block, y block, z block: 1 by 3m).
  std::vector<Eigen::MatrixXd> group_coef;
  std::vector<Eigen::RowVectorXd> vertex_modes;
  // Quadratic parts (one per bone): descriptor, σ, mean A and RBF coefficients (30 = row-major
  // 3 by 10), frame (centroid, axes, scale); per vertex and slot the quadratic vector in the slot's
  // part frame where the vertex is a member (1) of that part, else the slot moves it rigidly (0).
  std::vector<std::vector<int>> part_pairs;
  std::vector<std::vector<double>> part_omega;
  Eigen::VectorXd part_sigma;              // #B
  Eigen::MatrixXd part_mean;               // #B by 30
  std::vector<Eigen::MatrixXd> part_coef;  // #B, each P by 30
  Eigen::MatrixX3d part_centroid;          // #B by 3
  std::vector<Eigen::Matrix3d> part_axes;  // #B
  Eigen::VectorXd part_scale;              // #B
  Eigen::MatrixXi member;                  // #V by K
  Eigen::MatrixXd vertex_quadratic;        // #V by K·10

  int vertex_count() const { return base.vertex_count(); }
  int bone_count() const { return base.bone_count; }
  // Throws InputError naming the element when shapes or values are inconsistent.
  void validate(const std::string& what = "pose-space rig") const;
};

// base_lbs: the SSD rig fitted to the same examples (its influences and weights). The examples'
// transforms must be rigid (relative rotations). Throws InputError when there are fewer than
// 2 examples or the base does not match.
PoseSpaceRig fit_pose_space(const SkinningExamples& ex, const SkinningRig& base_lbs,
                            const PoseSpaceOptions& options = {}, PoseSpaceFitSummary* summary = nullptr,
                            const ProgressCallback& progress = {});

// Posed positions for bone maps M (#B, rigid).                                  returns #V by 3
Eigen::MatrixX3d evaluate_pose_space(const PoseSpaceRig& rig, const BoneTransforms& M);

}  // namespace bodymodel
