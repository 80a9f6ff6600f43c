// Linear skinning rigs (Jacka et al. 2007 §2): linear blend skinning (SSD), Animation Space
// (Merry et al. 2006) and Multi-Weight Enveloping (Wang & Phillips 2002, eq. 3), stored in one
// per-vertex, per-influence-slot layout, and their reference (double precision) evaluation.
// A dqs rig holds SSD-style weights posed by dual-quaternion blending (Kavan et al. 2007) instead.
//
// Bone b in a pose is the affine map M_b (rest → posed, 3 by 4 = [R t]); ṽ = [v; 1].
//   LBS:  v' = Σ_k w_k M_k ṽ                         1 coefficient per slot
//   DQS:  v' = DQ(Σ_k w_k q̂_k) v                     1 coefficient per slot (rigid M_k only)
//   AS:   v' = Σ_k M_k p_k                           4 coefficients per slot (p_k, a 4-vector)
//   MWE:  v'_j = Σ_k Σ_i W_k[j][i] (M_k)_ji ṽ_i       12 coefficients per slot, index 4·j + i
// An MWE rig fitted in delta space over an SSD or rigid base stores the base folded into W (the
// base is itself an MWE rig: W_k[j][i] = w_k), so evaluation never needs the base.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/skeleton.h"

namespace bodymodel {

enum class SkinningMethod { lbs, animation_space, mwe, dqs };

// "ssd"/"lbs", "as", "mwe", "dqs"  ↔  the enum. Throws InputError for an unknown name.
SkinningMethod parse_skinning_method(const std::string& name);
std::string skinning_method_name(SkinningMethod m);   // "ssd", "as", "mwe", "dqs"
// Coefficients per influence slot: 1 (ssd, dqs), 4 or 12.
int coefficients_per_influence(SkinningMethod m);

struct SkinningRig {
  SkinningMethod method = SkinningMethod::lbs;
  int bone_count = 0;
  Eigen::MatrixX3d rest;          // #V by 3 rest positions (used by LBS and MWE; kept for AS too)
  Eigen::MatrixXi influences;     // #V by K bone index per slot, -1 = unused slot
  Eigen::MatrixXd coefficients;   // #V by K·c (c = coefficients_per_influence), slot-major

  int vertex_count() const { return static_cast<int>(rest.rows()); }
  int max_influences() const { return static_cast<int>(influences.cols()); }
  // Throws InputError naming the element when shapes, indices or values are inconsistent.
  void validate(const std::string& what = "rig") const;
};

// Posed positions for one set of bone transforms (#B of them).       returns #V by 3
// A dqs rig needs rigid transforms (InputError naming the bone otherwise).
Eigen::MatrixX3d evaluate_rig(const SkinningRig& rig, const BoneTransforms& M);

// Dense LBS weights (#V by #B) of an LBS (or dqs) rig.
Eigen::MatrixXd dense_weights(const SkinningRig& lbs_rig);

// An LBS rig from dense weights W (#V by #B): each vertex keeps its `max_influences` largest
// weights above `threshold`, renormalised to sum to one.
SkinningRig lbs_rig_from_weights(const Eigen::MatrixX3d& rest, const Eigen::MatrixXd& W,
                                 int max_influences, double threshold = 1e-6);

// The same deformation written as an MWE rig (12 coefficients per slot), e.g. a base to fold in.
SkinningRig lbs_as_mwe(const SkinningRig& lbs_rig);

}  // namespace bodymodel
