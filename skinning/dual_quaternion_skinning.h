// Dual-quaternion skinning (Kavan et al. 2007), the reference without the candy-wrapper collapse,
// as libigl's dqs(): unit dual quaternions of the rigid bone maps are blended with the weights
// (each flipped into the hemisphere of the vertex's first bone), normalised and applied.
#pragma once

#include <Eigen/Core>

#include "core/skeleton.h"

namespace bodymodel {

// V #V by 3 rest positions, W #V by #B dense weights, M #B rigid maps (InputError if not rigid).
// returns #V by 3
Eigen::MatrixX3d dual_quaternion_skinning(const Eigen::MatrixX3d& V, const Eigen::MatrixXd& W,
                                          const BoneTransforms& M);

// The same with sparse weights: influences #V by K (bone per slot, −1 unused), weights #V by K.
// Multithreaded.                                                              returns #V by 3
Eigen::MatrixX3d dual_quaternion_skinning(const Eigen::MatrixX3d& V, const Eigen::MatrixXi& influences,
                                          const Eigen::MatrixXd& weights, const BoneTransforms& M);

}  // namespace bodymodel
