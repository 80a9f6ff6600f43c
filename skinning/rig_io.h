// Skinning rigs as NumPy .npz (np.load opens them). Keys:
//   format            text  "bodymodel-skinning-rig-1"
//   method            text  "ssd" | "as" | "mwe"
//   bone_count        scalar #B
//   rest              #V by 3 float64 rest positions (data units)
//   faces             #F by 3 int32 triangles, 0-based (0 rows when unknown)
//   influences        #V by K int32 bone per slot, −1 = unused slot
//   coefficients      #V by K·c float64, c = 1 (ssd: w_k), 4 (as: p_k = [x y z w], slot-major),
//                     12 (mwe: W_k[j][i] at 12k + 4j + i, output row j, input column i of M_k)
//   pose_transforms   optional, #P·#B by 12 float64: the fitted poses' bone maps M_b rest → posed,
//                     row p·#B + b = the 3 by 4 matrix [R t] in row-major order
// Posing: ssd v' = Σ_k w_k M_k ṽ; as v' = Σ_k M_k p_k; mwe v'_j = Σ_k Σ_i W_k[j][i] (M_k)_ji ṽ_i,
// with ṽ = [v; 1] and k over the vertex's slots.
#pragma once

#include <filesystem>
#include <vector>

#include "skinning/skinning_rig.h"

namespace bodymodel {

void save_rig(const std::filesystem::path& path, const SkinningRig& rig, const Eigen::MatrixX3i& faces = {},
              const std::vector<BoneTransforms>& pose_transforms = {});

// Throws InputError naming the file and key when a key is missing or inconsistent.
SkinningRig load_rig(const std::filesystem::path& path, Eigen::MatrixX3i* faces = nullptr,
                     std::vector<BoneTransforms>* pose_transforms = nullptr);

}  // namespace bodymodel
