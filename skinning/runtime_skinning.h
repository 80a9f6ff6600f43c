// Runtime rig evaluation: float32, flat arrays (outputs structure-of-arrays), multithreaded (TBB), SIMD inner
// loops (GCC vector extensions; AVX-512, AVX2/FMA or SSE2 clone chosen at run time). LBS, Animation Space and MWE with
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
#include <cstdint>
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
  // Bone matrices as floats, plus a zero bone B for unused slots: row-major 3 by 4 (12 floats,
  // MWE and normals) or column-major padded (16 floats [c0 0 c1 0 c2 0 t 0], LBS and AS).
  void pack_bones(const BoneTransforms& M, bool column_major, std::vector<float>* out) const;
  SkinningMethod method_;
  int n_ = 0, K_ = 0, B_ = 0;
  // Positions read vertex-major arrays (one vertex's slots contiguous: one cache line stream),
  // normals slot-major ones (structure of arrays over vertices).
  std::vector<uint16_t> idx_;      // n by K bone per slot (B = the zero bone for unused slots)
  std::vector<int> nidx_;          // K by n, the same
  std::vector<float> coef_;        // position coefficients, vertex-major: LBS n by K weights,
                                   // AS n by K·4 (p_k), MWE n by K·12 (U_k = W_k ⊙ ṽ, row-major)
  std::vector<float> lcoef_;       // K by n LBS weights (normals)
  std::vector<float> rest_;        // n by 3 (LBS only), plus one float of padding
  std::vector<float> ncoef_;       // normal coefficients: K·9 by n (LBS: none, uses coef_)
  std::vector<float> nrest_;       // 3 by n rest normals (LBS/AS)
  bool has_normals_ = false;
};

}  // namespace bodymodel
