// Set-up of the pose fit (docs/pose_fit.md#stages): what its stages share, built once from the
// inputs and read-only after (PoseProblem), the start of the unknowns, and the helpers that put
// residuals of its samples and priors into a ceres::Problem.
//
// Data flow, one way: inputs → PoseProblem (parameters, landmarks, samples, chains, scan index)
// → stages, which change only the PoseUnknowns → result.
#pragma once

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <vector>

#include "core/mesh.h"
#include "core/point_index.h"
#include "core/skeleton.h"
#include "registration/landmarks.h"
#include "registration/pose_fit_options.h"
#include "registration/pose_parameters.h"
#include "registration/pose_residuals.h"

namespace bodymodel {

class PoseProblem {
 public:
  // Checks the inputs (InputError for weights that do not fit, a skeleton with no single root at
  // bone 0, an empty scan, landmarks out of range; see resolve_pose_parameters) and sets up the
  // parameters, landmarks and samples. All arguments must outlive the problem.
  PoseProblem(const Mesh& template_rest, const Skeleton& skeleton, const SkinWeights& weights,
              const PointCloud& scan, const std::vector<Landmark>& landmarks,
              const PoseFitOptions& options);
  PoseProblem(const PoseProblem&) = delete;  // residuals point into chains
  PoseProblem& operator=(const PoseProblem&) = delete;

  // The inputs.
  const Mesh& tpl;              // rest template, #V vertices (mm)
  const Skeleton& skeleton;     // #B bones
  const SkinWeights& W;         // #V by #B
  const PointCloud& scan;       // #S points with unit normals (or none)
  const PoseFitOptions& o;
  int vertex_count = 0, bone_count = 0;

  PoseParameterization z;       // the fitted parameters (#P)

  // The landmarks whose vertex follows the root or a fitted bone closely enough
  // (PoseFitOptions::landmark_rigid_depth, counting the hand stage's bones as fitted), and of
  // those, the ones that do so with the hand stage's bones held at rest: used in the
  // landmark-only and body stages (the others only in the hand stage).
  std::vector<Landmark> landmarks;
  std::vector<char> landmark_in_body;  // per landmark
  int body_landmarks = 0;              // count of landmark_in_body

  // Hand stage: its samples (template vertices weighted > 0.25 on late bones, strided to
  // hand_sample_vertices) and the hand region (#V: vertices mostly on late bones or their parents,
  // palm and wrist, whose closest scan points are the hand's).
  std::vector<int> hand_samples;
  std::vector<char> hand_region;

  // Samples: the template vertex of each residual source, in three ranges: the ICP samples
  // [0, body_samples) (every stride-th vertex), the landmarks [body_samples, hand_first) (in the
  // order of `landmarks`), the hand samples [hand_first, end).
  std::vector<int> samples;
  int body_samples = 0, hand_first = 0;
  // Per sample: mostly (≥ 0.5) on late bones, so not paired in the body stages (held open,
  // fingers cannot follow a fist and only shake the wrist).
  std::vector<char> on_late;
  std::vector<Chain> chains;                    // per sample
  std::vector<std::vector<int>> chain_params;   // per sample: the parameter of each chain block

  PointIndex scan_index;                        // over scan.P
  double cos_min = 0;                           // cos of max_normal_angle_deg

  // Agreement of scan normal j with a template vertex normal n (1×3): their cosine, or its
  // absolute value with unsigned normals. Needs scan normals.
  double normal_agreement(int j, const Eigen::RowVector3d& n) const;
};

// The start of the unknowns: a similarity transform from the body landmarks (≥ 3), else from
// centroids and bounding-box sizes; joints at rest. InputError if it is not finite.
PoseUnknowns initial_unknowns(const PoseProblem& problem);

// The pose of the unknowns (#B rotations) and the template posed with it (#V by 3, mm).
Pose current_pose(const PoseProblem& problem, const PoseUnknowns& unknowns);
Eigen::MatrixX3d posed_template(const PoseProblem& problem, const PoseUnknowns& unknowns);

// Adds every parameter block (scale, root, translation, then the #P joints) to `solver_problem`.
void add_parameter_blocks(ceres::Problem& solver_problem, const PoseProblem& problem,
                          PoseUnknowns& unknowns);

// Adds the PointResidual of sample si against `target` (mm) with scan `normal` (zero: no plane
// term), on the blocks of its chain. `loss` may be null; the problem takes ownership.
void add_sample(ceres::Problem& solver_problem, const PoseProblem& problem, PoseUnknowns& unknowns,
                int si, const Eigen::Vector3d& target, const Eigen::Vector3d& normal,
                double weight, double plane_weight, double point_weight, ceres::LossFunction* loss);

// A prior pulling a joint parameter aa towards `centre` with `weight`: one residual for a one-dof
// parameter (centre[0]), three for a ball joint's rotation vector.
void add_joint_prior(ceres::Problem& solver_problem, bool one_dof, double weight,
                     const Eigen::Vector3d& centre, Eigen::Vector3d& aa);

// Solves with dense normal Cholesky, at most max_iterations Levenberg–Marquardt steps, silently.
void solve_pose_problem(ceres::Problem& solver_problem, int max_iterations, int threads);

}  // namespace bodymodel
