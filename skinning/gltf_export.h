// glTF 2.0 binary (.glb) export of a linear-blend-skinned character: rest mesh, normals, the
// joint hierarchy, up to 4 weights per vertex, inverse bind matrices and an optional animation.
//
// Units: the input is in `unit_scale`-units (mm for bodies); glTF is in METRES, so positions,
// joint translations and inverse bind matrices are multiplied by unit_scale (default 0.001).
//
// Joints (one node each, named after the bone, children under their parent node): the rest
// world matrix of joint b is a pure translation to its head h_b (no rest rotation), so the
// inverse bind matrix is translate(−h_b) and, for bone maps M_b (rest → posed, rigid,
// core/skeleton.h), the posed joint's world matrix is G_b = [Q_b | M_b(h_b)] with Q_b the linear
// part of M_b. Then G_b · IBM_b = M_b, i.e. glTF's skinning v' = Σ_k w_k G_k IBM_k v equals
// our LBS v' = Σ_k w_k M_k v. Local node transforms are G_parent⁻¹ G_b: rotation Q_pᵀ Q_b and
// translation Q_pᵀ (M_b(h_b) − M_p(h_p)) (constant = h_b − h_p for forward kinematics poses).
//
// Animation: one LINEAR sampler per joint for its local rotation (unit quaternions, sign kept
// continuous between frames) and one for the translation of every root joint and of any joint
// whose local translation changes over the clip; keyframe times k · frame_time seconds.
//
// Weights: each vertex keeps its 4 largest weights (ties: lower bone index), renormalised to sum
// to one (in float32, exactly as stored); unused slots get joint 0 and weight 0.
// The skinned mesh node sits at the scene root without a transform (as the spec requires); the
// root joint is a scene root too, or, when the skeleton has several roots, an identity node
// "skeleton_root" above them (glTF requires the joints to share one root). Bytes are written through write_atomically.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "core/skeleton.h"

namespace bodymodel {

struct GltfAnimation {
  std::string name = "clip";
  double frame_time = 1.0 / 30;         // seconds per frame (> 0)
  std::vector<BoneTransforms> frames;   // #frames, each #B rigid bone maps rest → posed
                                        // (input units), e.g. forward_kinematics of a pose
};

// A run of consecutive triangles with its own material: one primitive each, all sharing the
// mesh's vertex attributes (e.g. a dressed body: skin, garments, hair).
struct GltfMaterialPart {
  std::string name;
  int first_triangle = 0, triangle_count = 0;
  Eigen::Vector3d base_colour{0.8, 0.8, 0.8};   // linear RGB in [0, 1]
  double roughness = 0.8, metallic = 0.0;       // pbrMetallicRoughness factors in [0, 1]
};

struct GltfExportOptions {
  double unit_scale = 0.001;            // input unit → metre (mm → m)
  std::string mesh_name = "body";
  std::string generator = "bodymodel";
  double rigid_tolerance = 1e-4;        // max |QᵀQ − I| accepted for an animation bone map
  // Skinned export: empty = one primitive without a material; else the parts, in order, must
  // cover every triangle exactly once (InputError otherwise).
  std::vector<GltfMaterialPart> parts;
};

struct GltfExportSummary {
  int vertices = 0, triangles = 0, joints = 0, frames = 0;
  int vertices_truncated = 0;           // vertices that had more than 4 non-zero weights
  double max_dropped_weight = 0;        // largest total weight dropped from one vertex
  size_t bytes = 0;                     // size of the .glb
};

// The .glb bytes.
//   V  #V by 3 rest positions (input units, e.g. mm)      F  #F by 3 triangles (0-based)
//   N  #V by 3 rest normals (unit), or empty: area-weighted vertex normals of (V, F)
//   skeleton  #B bones (heads in input units)              W  #V by #B skinning weights
//   animation optional (nullptr: no animation)
// Throws InputError naming the element for inconsistent sizes, NaNs, out-of-range faces,
// empty weight rows, non-rigid animation transforms or more than 65 536 joints.
std::string skinned_gltf_bytes(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                               const Eigen::MatrixX3d& N, const Skeleton& skeleton,
                               const SkinWeights& W, const GltfAnimation* animation = nullptr,
                               const GltfExportOptions& options = {},
                               GltfExportSummary* summary = nullptr);

// A morph target of a level: `vertex` (strictly increasing rows of the level's V) moved by
// `delta` (input units). glTF adds the targets BEFORE skinning, so the deltas are in bind space.
// Written as a sparse accessor without a buffer view: only the listed vertices are stored.
struct GltfMorphTarget {
  std::string name;
  std::vector<int> vertex;
  Eigen::MatrixX3d delta;               // one row per listed vertex
};

// One mesh of a multi-mesh export: a level of detail of one character (same skeleton).
struct GltfLevel {
  std::string name;                     // the mesh and its node
  Eigen::MatrixX3d V;                   // as skinned_gltf_bytes' V, F, N, W and options.parts
  Eigen::MatrixX3i F;
  Eigen::MatrixX3d N;
  SkinWeights W;
  std::vector<GltfMaterialPart> parts;
  // Morph targets (every primitive of the mesh gets them all; extras.targetNames gives their
  // names) and, with an animation, their weights per key: #frames by #targets, written as a
  // `weights` channel on the level's node (LINEAR between keys). Empty = no channel (weights 0).
  std::vector<GltfMorphTarget> targets;
  Eigen::MatrixXd target_weights;
  // The times (s) of target_weights' rows when they are not the animation's keys (the channel then
  // has its own sampler input): strictly increasing, within the clip. Empty = one row per key.
  std::vector<double> target_times;
};

// Several skinned meshes sharing one skeleton, skin and animation (levels of detail): mesh k on
// node B + k (B joints), every mesh node in the scene; with more than one level each mesh node
// carries extras {"lod": k}. Parts with the same name and factors share one material. The
// summary adds up vertices and triangles over the levels. options.mesh_name and options.parts
// are not used (each level has its own).
std::string skinned_lods_gltf_bytes(const std::vector<GltfLevel>& levels, const Skeleton& skeleton,
                                    const GltfAnimation* animation = nullptr, const GltfExportOptions& options = {},
                                    GltfExportSummary* summary = nullptr);

// skinned_gltf_bytes written to `path` atomically.
GltfExportSummary write_skinned_gltf(const std::filesystem::path& path, const Eigen::MatrixX3d& V,
                                     const Eigen::MatrixX3i& F, const Eigen::MatrixX3d& N,
                                     const Skeleton& skeleton, const SkinWeights& W,
                                     const GltfAnimation* animation = nullptr,
                                     const GltfExportOptions& options = {});

// A plain (unskinned) mesh as .glb bytes: positions (scaled by options.unit_scale, float32),
// unit normals (N, or area-weighted vertex normals when empty), uint32 triangle indices, one
// node. Throws InputError as skinned_gltf_bytes does for the mesh.
std::string static_gltf_bytes(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                              const Eigen::MatrixX3d& N = Eigen::MatrixX3d(),
                              const GltfExportOptions& options = {});

// The 4-influence weights the exporter stores (#V by #B, float32 values widened to double):
// for tests and for comparing against the exported file.
SkinWeights gltf_top4_weights(const SkinWeights& W);

// A skeleton of #B unconnected joints with heads at the origin, for rigs whose bones have no
// hierarchy (bones recovered from a mesh sequence): the animation then carries each bone's map.
Skeleton flat_skeleton(int bone_count, const std::string& prefix = "bone");

}  // namespace bodymodel
