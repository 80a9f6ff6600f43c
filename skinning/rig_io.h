// Skinning rigs as NumPy .npz (np.load opens them). Keys:
//   format            text  "bodymodel-skinning-rig-1"
//   method            text  "ssd" | "as" | "mwe"
//   bone_count        int32 scalar #B
//   rest              #V by 3 float64 rest positions (data units)
//   faces             #F by 3 int32 triangles, 0-based (0 rows when unknown)
//   influences        #V by K int32 bone per slot, −1 = unused slot
//   coefficients      #V by K·c float64, c = 1 (ssd: w_k), 4 (as: p_k = [x y z w], slot-major),
//                     12 (mwe: W_k[j][i] at 12k + 4j + i, output row j, input column i of M_k)
//   pose_transforms   optional, #P·#B by 12 float64: the fitted poses' bone maps M_b rest → posed,
//                     row p·#B + b = the 3 by 4 matrix [R t] in row-major order
//   skeleton_names    optional text, a JSON list of the #B bone names (the bones the rig's
//                     influences index), with
//   skeleton_parents  #B int32 parent index (−1 root), skeleton_heads / skeleton_tails #B by 3
//                     float64 rest joint positions (data units). The same keys as the character
//                     rigs of `bodymodel character` (tools/pipeline/character_file.h).
// Posing: ssd v' = Σ_k w_k M_k ṽ; as v' = Σ_k M_k p_k; mwe v'_j = Σ_k Σ_i W_k[j][i] (M_k)_ji ṽ_i,
// with ṽ = [v; 1] and k over the vertex's slots; dqs: the ssd weights, dual-quaternion blend.
//
// Pose-space rigs (psd, eigenskin, quadratic; skinning/pose_space.h) are a different format:
//   format "bodymodel-pose-space-rig-1", method, bone_count, rest, faces, influences and
//   coefficients (the SSD base, as above), optional pose_transforms, and the arrays of
//   PoseSpaceRig under their own names (pairs, pair_features, primary, vertex_pairs, vertex_omega,
//   vertex_sigma, vertex_mean, vertex_coef, poses), the ragged group arrays flattened:
//   group_offsets (#G+1), group_pair_list / group_omega_list (pairs and ω of group g at
//   group_offsets[g]..[g+1]), group_sigma (#G), group_columns (#G), group_coef (P by Σ columns),
//   group_mean (#G by 27, quadratic), vertex_group, vertex_modes (#V by 3·max columns, padded),
//   part_centroid (#B by 3), part_axes (#B by 9, row-major), part_scale, member, vertex_quadratic.
#pragma once

#include <filesystem>
#include <vector>

#include "skinning/pose_space.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

// skeleton: optional (nullptr or 0 bones: no skeleton keys); must have rig.bone_count bones.
void save_rig(const std::filesystem::path& path, const SkinningRig& rig, const Eigen::MatrixX3i& faces = {},
              const std::vector<BoneTransforms>& pose_transforms = {}, const Skeleton* skeleton = nullptr);

// Throws InputError naming the file and key when a key is missing or inconsistent.
// skeleton (optional): the stored skeleton, or an empty Skeleton (0 bones) when the file has none.
// A pose-space rig file gets its own one-line error naming the method.
SkinningRig load_rig(const std::filesystem::path& path, Eigen::MatrixX3i* faces = nullptr,
                     std::vector<BoneTransforms>* pose_transforms = nullptr, Skeleton* skeleton = nullptr);

void save_pose_space_rig(const std::filesystem::path& path, const PoseSpaceRig& rig,
                         const Eigen::MatrixX3i& faces = {}, const std::vector<BoneTransforms>& pose_transforms = {});
// Throws InputError naming the file and the key or element that is missing or inconsistent.
PoseSpaceRig load_pose_space_rig(const std::filesystem::path& path, Eigen::MatrixX3i* faces = nullptr);
// True if the file is a pose-space rig (its 'format' key); false for anything else.
bool is_pose_space_rig_file(const std::filesystem::path& path);

}  // namespace bodymodel
