// Runtime rig evaluation: float32, flat arrays (outputs structure-of-arrays), multithreaded (TBB), vectorisable inner
// loops (AVX2/FMA clone chosen at run time when the CPU has it). LBS, Animation Space and MWE with
// up to 8 influences per vertex; positions and, optionally, normals.
//
// Every method becomes one kernel: per slot k and output row j, a dot product of 4 per-vertex
// coefficients with row j of the bone's 3 by 4 matrix:
//   LBS  the blended matrix Σ_k w_k M_k is applied to ṽ        (coefficients w_k)
//   AS   v'_j = Σ_k Σ_i (M_k)_ji p_k,i                          (coefficients p_k)
//   MWE  v'_j = Σ_k Σ_i (M_k)_ji U_k[j][i],  U = W ⊙ ṽ precomputed at construction
// Normals (approximate, the usual practice): the rest normal through the same blend of the
// matrices' linear parts (LBS: Σ w_k R_k n; AS: Σ p_k,w R_k n; MWE: n'_j = Σ W_k[j][i] (M_k)_ji n_i),
// renormalised.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/skeleton.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

class RuntimeSkinner {
 public:
  static constexpr int kMaxInfluences = 8;
  // rest_normals: #V by 3 (needed only for pose_normals), or empty. Throws InputError when the
  // rig has more than 8 influence slots or is invalid.
  explicit RuntimeSkinner(const SkinningRig& rig, const Eigen::MatrixX3d& rest_normals = {});

  // Positions for bone maps M (#B). x, y, z: #V floats each (structure of arrays).
  // threads: 0 = TBB's default, otherwise at most this many.
  void pose(const BoneTransforms& M, float* x, float* y, float* z, int threads = 0) const;
  // Normals likewise (unit length). Requires rest normals at construction.
  void pose_normals(const BoneTransforms& M, float* nx, float* ny, float* nz, int threads = 0) const;
  // Convenience: #V by 3.
  Eigen::MatrixX3f pose(const BoneTransforms& M, int threads = 0) const;

  int vertex_count() const { return n_; }
  int slots() const { return K_; }
  SkinningMethod method() const { return method_; }

 private:
  void pack_bones(const BoneTransforms& M, std::vector<float>* out) const;
  SkinningMethod method_;
  int n_ = 0, K_ = 0, B_ = 0;
  // Positions read vertex-major arrays (one vertex's slots contiguous: one cache line stream),
  // normals slot-major ones (structure of arrays over vertices).
  std::vector<int> idx_;           // n by K bone per slot (B = the zero bone for unused slots)
  std::vector<int> nidx_;          // K by n, the same
  std::vector<float> coef_;        // n by K·12 position coefficients (LBS: n by K weights)
  std::vector<float> lcoef_;       // K by n LBS weights (normals)
  std::vector<float> rest_;        // n by 3 (LBS only)
  std::vector<float> ncoef_;       // normal coefficients: K·9 by n (LBS: none, uses coef_)
  std::vector<float> nrest_;       // 3 by n rest normals (LBS/AS)
  bool has_normals_ = false;
};

}  // namespace bodymodel
