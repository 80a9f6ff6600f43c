// The skeleton a model carries so that pose morphing (§5.4) can turn a BVH frame into joint
// angles and limb-tip targets for ANY body of the model: bone names and parents, joint
// positions as a sparse linear function of the body's vertices (a joint regressor), and
// skinning weights.
//
// MakeHuman defines each joint as the mean of listed vertices, most of them helper vertices
// that a registered body mesh does not have (only the 13380 body vertices). The regressor is
// therefore FITTED: each bone head/tail is an affine combination (weights summing to one) of
// its k nearest body vertices of the default body, the weights found by least squares over
// random MakeHuman bodies, so the joints follow any body shape the sliders can make.
#pragma once

#include <Eigen/Core>
#include <Eigen/Sparse>
#include <string>
#include <vector>

#include "core/makehuman.h"
#include "core/skeleton.h"

namespace bodymodel {

struct ModelRig {
  std::vector<std::string> bone_names;  // #B
  std::vector<int> parents;             // #B, −1 for a root
  Eigen::SparseMatrix<double, Eigen::RowMajor> head_regressor;  // #B by #V
  Eigen::SparseMatrix<double, Eigen::RowMajor> tail_regressor;  // #B by #V
  SkinWeights weights;                  // #V by #B

  bool empty() const { return bone_names.empty(); }
  int bone_count() const { return static_cast<int>(bone_names.size()); }
  // The rig's skeleton placed in the body V (#V by 3, mm). InputError if empty or V has the
  // wrong number of rows.
  Skeleton skeleton_for(const Eigen::MatrixX3d& V) const;
};

struct ModelRigOptions {
  int support_vertices = 16;  // k nearest body vertices per joint
  int training_bodies = 24;   // random MakeHuman bodies for the least-squares fit
  unsigned seed = 1;
  double ridge = 1e-3;        // pulls weights towards the uniform mean of the support (stability)
};

struct ModelRigSummary {
  double max_joint_error_mm = 0;   // over the training bodies
  double mean_joint_error_mm = 0;
};

ModelRig fit_makehuman_rig(const MakeHuman& makehuman, const ModelRigOptions& options = {},
                           ModelRigSummary* summary = nullptr);

}  // namespace bodymodel
