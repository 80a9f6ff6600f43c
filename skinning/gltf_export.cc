#include "skinning/gltf_export.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <sstream>

// The tinygltf implementation lives in this translation unit only. No images are written or
// read, so stb_image is not needed (Debian's tiny_gltf.h would include <stb_image.h>).
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#pragma GCC diagnostic push
// gcc's false positives inside tinygltf; clang has neither warning (and warns about unknown ones).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wrestrict"
#pragma GCC diagnostic ignored "-Wstringop-overflow"
#endif
#include <tiny_gltf.h>
#pragma GCC diagnostic pop

#include "core/error.h"
#include "core/geometry.h"
#include "core/io/atomic_write.h"

namespace bodymodel {
namespace {

// Builds one binary buffer (4-byte aligned views) with its views and accessors.
class BufferBuilder {
 public:
  explicit BufferBuilder(tinygltf::Model* model) : model_(model) { model_->buffers.emplace_back(); }

  // A view over `bytes` bytes copied from `data`; target 0 = none.
  int view(const void* data, size_t bytes, int target) {
    auto& buf = model_->buffers[0].data;
    while (buf.size() % 4) buf.push_back(0);
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = buf.size();
    v.byteLength = bytes;
    v.target = target;
    const auto* p = static_cast<const unsigned char*>(data);
    buf.insert(buf.end(), p, p + bytes);
    model_->bufferViews.push_back(v);
    return static_cast<int>(model_->bufferViews.size()) - 1;
  }

  // An accessor over a new view. `type` TINYGLTF_TYPE_*, `component` TINYGLTF_COMPONENT_TYPE_*.
  int accessor(const void* data, size_t bytes, int component, int type, size_t count, int target,
               std::vector<double> min = {}, std::vector<double> max = {}) {
    tinygltf::Accessor a;
    a.bufferView = view(data, bytes, target);
    a.byteOffset = 0;
    a.componentType = component;
    a.type = type;
    a.count = count;
    a.minValues = std::move(min);
    a.maxValues = std::move(max);
    model_->accessors.push_back(a);
    return static_cast<int>(model_->accessors.size()) - 1;
  }

  // A float VEC3 accessor of `count` zeros but for the `values` (3 per index) at `indices`
  // (strictly increasing): a sparse accessor without a buffer view; min and max cover the zeros.
  int sparse_vec3(size_t count, const std::vector<uint32_t>& indices, const std::vector<float>& values) {
    tinygltf::Accessor a;
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.type = TINYGLTF_TYPE_VEC3;
    a.count = count;
    a.minValues.assign(3, 0.0);
    a.maxValues.assign(3, 0.0);
    for (size_t i = 0; i < values.size(); ++i) {
      a.minValues[i % 3] = std::min(a.minValues[i % 3], double(values[i]));
      a.maxValues[i % 3] = std::max(a.maxValues[i % 3], double(values[i]));
    }
    if (!indices.empty()) {
      a.sparse.isSparse = true;
      a.sparse.count = static_cast<int>(indices.size());
      if (count <= 65536) {
        const std::vector<uint16_t> i16(indices.begin(), indices.end());
        a.sparse.indices.bufferView = view(i16.data(), i16.size() * 2, 0);
        a.sparse.indices.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
      } else {
        a.sparse.indices.bufferView = view(indices.data(), indices.size() * 4, 0);
        a.sparse.indices.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
      }
      a.sparse.indices.byteOffset = 0;
      a.sparse.values.bufferView = view(values.data(), values.size() * 4, 0);
      a.sparse.values.byteOffset = 0;
    }
    model_->accessors.push_back(a);
    return static_cast<int>(model_->accessors.size()) - 1;
  }

 private:
  tinygltf::Model* model_;
};

// The POSITION (scaled, with the bounds glTF requires) and unit NORMAL attributes of a
// triangle primitive; a degenerate normal becomes any unit vector.
void add_positions_and_normals(BufferBuilder& buf, tinygltf::Primitive& prim, const Eigen::MatrixX3d& V,
                               const Eigen::MatrixX3d& N, double scale) {
  const auto n = static_cast<size_t>(V.rows());
  std::vector<float> pos(3 * n), nrm(3 * n);
  std::vector<double> pmin(3, 1e300), pmax(3, -1e300);
  for (size_t i = 0; i < n; ++i) {
    Eigen::Vector3d nn = N.row(static_cast<Eigen::Index>(i)).transpose();
    const double len = nn.norm();
    nn = len > 1e-12 ? Eigen::Vector3d(nn / len) : Eigen::Vector3d(0, 1, 0);
    for (int d = 0; d < 3; ++d) {
      const float p = static_cast<float>(V(static_cast<Eigen::Index>(i), d) * scale);
      pos[3 * i + d] = p;
      pmin[d] = std::min(pmin[d], double(p));
      pmax[d] = std::max(pmax[d], double(p));
      nrm[3 * i + d] = static_cast<float>(nn(d));
    }
  }
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  prim.attributes["POSITION"] = buf.accessor(pos.data(), pos.size() * 4, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                             TINYGLTF_TYPE_VEC3, n, TINYGLTF_TARGET_ARRAY_BUFFER, pmin, pmax);
  prim.attributes["NORMAL"] = buf.accessor(nrm.data(), nrm.size() * 4, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                           TINYGLTF_TYPE_VEC3, n, TINYGLTF_TARGET_ARRAY_BUFFER);
}

// The triangles as one uint32 index accessor.
void add_indices(BufferBuilder& buf, tinygltf::Primitive& prim, const Eigen::MatrixX3i& F) {
  std::vector<uint32_t> idx(3 * static_cast<size_t>(F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) idx[3 * static_cast<size_t>(f) + k] = static_cast<uint32_t>(F(f, k));
  prim.indices = buf.accessor(idx.data(), idx.size() * 4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR,
                              idx.size(), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
}

// glTF quaternion [x y z w] of a rotation matrix, sign chosen so it is closest to `previous`.
Eigen::Vector4d quaternion_xyzw(const Eigen::Matrix3d& R, const Eigen::Vector4d* previous) {
  Eigen::Quaterniond q(R);
  q.normalize();
  Eigen::Vector4d v(q.x(), q.y(), q.z(), q.w());
  if (previous ? v.dot(*previous) < 0 : v(3) < 0) v = -v;
  return v;
}

void check_finite(const Eigen::MatrixXd& M, const std::string& what) {
  if (!M.allFinite()) throw InputError("glTF export: " + what + " contains NaN or infinite values");
}

}  // namespace

Skeleton flat_skeleton(int bone_count, const std::string& prefix) {
  if (bone_count < 1) throw InputError("flat skeleton: expected at least one bone, found " + std::to_string(bone_count));
  Skeleton s;
  for (int b = 0; b < bone_count; ++b) {
    s.names.push_back(prefix + std::to_string(b));
    s.parents.push_back(-1);
  }
  s.heads = Eigen::MatrixX3d::Zero(bone_count, 3);
  s.tails = Eigen::MatrixX3d::Zero(bone_count, 3);
  s.tails.col(1).setOnes();
  return s;
}

SkinWeights gltf_top4_weights(const SkinWeights& W) {
  std::vector<Eigen::Triplet<double>> trip;
  for (int i = 0; i < W.rows(); ++i) {
    std::vector<std::pair<double, int>> row;
    for (SkinWeights::InnerIterator it(W, i); it; ++it)
      if (it.value() > 0) row.emplace_back(it.value(), static_cast<int>(it.col()));
    std::sort(row.begin(), row.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    if (row.size() > 4) row.resize(4);
    double sum = 0;
    for (const auto& [w, b] : row) sum += w;
    if (!(sum > 0)) continue;   // an empty row stays empty (the exporter rejects it)
    // float32 values summing to one as closely as float allows: the largest absorbs the rest.
    float f[4] = {0, 0, 0, 0};
    float rest = 1.f;
    for (size_t k = 1; k < row.size(); ++k) {
      f[k] = static_cast<float>(row[k].first / sum);
      rest -= f[k];
    }
    f[0] = rest;
    for (size_t k = 0; k < row.size(); ++k) trip.emplace_back(i, row[k].second, static_cast<double>(f[k]));
  }
  SkinWeights out(W.rows(), W.cols());
  out.setFromTriplets(trip.begin(), trip.end());
  return out;
}

namespace {

// The argument checks of skinned_gltf_bytes on the mesh, skeleton, weights and options, before
// anything is built so a bad call fails with the first problem.
void check_skinned_inputs(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const Skeleton& skeleton,
                          const SkinWeights& W, const GltfExportOptions& options) {
  skeleton.validate();
  const int n = static_cast<int>(V.rows()), B = skeleton.bone_count();
  if (n == 0 || F.rows() == 0) throw InputError("glTF export: the mesh is empty (" + std::to_string(n) + " vertices, " +
                                                std::to_string(F.rows()) + " triangles)");
  if (B < 1 || B > 65536) throw InputError("glTF export: expected 1 to 65536 joints, found " + std::to_string(B));
  if (!(options.unit_scale > 0) || !std::isfinite(options.unit_scale))
    throw InputError("glTF export: unit_scale must be positive, found " + std::to_string(options.unit_scale));
  check_finite(V, "the rest vertices");
  check_finite(skeleton.heads, "the skeleton heads");
  if (F.minCoeff() < 0 || F.maxCoeff() >= n)
    throw InputError("glTF export: face indices must be in [0, " + std::to_string(n) + "), found " +
                     std::to_string(F.minCoeff()) + ".." + std::to_string(F.maxCoeff()));
  if (W.rows() != n || W.cols() != B)
    throw InputError("glTF export: weights are " + std::to_string(W.rows()) + " by " + std::to_string(W.cols()) +
                     ", expected #V " + std::to_string(n) + " by #bones " + std::to_string(B));
}

// The given normals, or the mesh's vertex normals when none are given; checked either way.
Eigen::MatrixX3d checked_normals(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const Eigen::MatrixX3d& N_in) {
  const int n = static_cast<int>(V.rows());
  Eigen::MatrixX3d N = N_in;
  if (N.size() == 0) {
    N = vertex_normals(V, F);
  } else if (N.rows() != n) {
    throw InputError("glTF export: " + std::to_string(N.rows()) + " normals for " + std::to_string(n) + " vertices");
  }
  check_finite(N, "the normals");
  return N;
}

// Rest translation of joint b relative to its parent (input units): a joint node's translation.
Eigen::Vector3d rest_offset(const Skeleton& skeleton, int b) {
  const int p = skeleton.parents[static_cast<size_t>(b)];
  Eigen::Vector3d t = skeleton.heads.row(b).transpose();
  if (p >= 0) t -= skeleton.heads.row(p).transpose();
  return t;
}

// The triangles of each part as its own primitive (sharing `prim`'s attributes) with a
// metallic-roughness material; the parts must tile the triangles in order.
void add_material_parts(tinygltf::Model& model, BufferBuilder& buf, const tinygltf::Primitive& prim,
                        const Eigen::MatrixX3i& F, const std::vector<GltfMaterialPart>& parts, tinygltf::Mesh& mesh) {
  int next = 0;
  for (const GltfMaterialPart& part : parts) {
    auto in01 = [](double v) { return v >= 0 && v <= 1; };
    if (part.first_triangle != next || part.triangle_count <= 0 || next + part.triangle_count > F.rows())
      throw InputError("glTF export: part '" + part.name + "' covers triangles " + std::to_string(part.first_triangle) +
                       ".." + std::to_string(part.first_triangle + part.triangle_count - 1) + ", expected to start at " +
                       std::to_string(next) + " within the " + std::to_string(F.rows()) + " triangles");
    if (!in01(part.base_colour.minCoeff()) || !in01(part.base_colour.maxCoeff()) || !in01(part.roughness) ||
        !in01(part.metallic))
      throw InputError("glTF export: part '" + part.name + "': colour, roughness and metallic must be in [0, 1]");
    tinygltf::Material m;
    m.name = part.name;
    m.pbrMetallicRoughness.baseColorFactor = {part.base_colour[0], part.base_colour[1], part.base_colour[2], 1.0};
    m.pbrMetallicRoughness.roughnessFactor = part.roughness;
    m.pbrMetallicRoughness.metallicFactor = part.metallic;
    // Levels of detail of one character share their parts' materials (same name and factors).
    const auto same = std::find_if(model.materials.begin(), model.materials.end(), [&](const tinygltf::Material& o) {
      return o.name == m.name && o.pbrMetallicRoughness.baseColorFactor == m.pbrMetallicRoughness.baseColorFactor &&
             o.pbrMetallicRoughness.roughnessFactor == m.pbrMetallicRoughness.roughnessFactor &&
             o.pbrMetallicRoughness.metallicFactor == m.pbrMetallicRoughness.metallicFactor;
    });
    tinygltf::Primitive p = prim;
    add_indices(buf, p, F.middleRows(part.first_triangle, part.triangle_count));
    p.material = static_cast<int>(same - model.materials.begin());
    if (same == model.materials.end()) model.materials.push_back(m);   // index = the old size
    mesh.primitives.push_back(p);
    next += part.triangle_count;
  }
  if (next != F.rows())
    throw InputError("glTF export: the parts cover " + std::to_string(next) + " of the " + std::to_string(F.rows()) +
                     " triangles");
}

// The JOINTS_0 and WEIGHTS_0 attributes: each vertex's top 4 weights, renormalised, counting in
// the summary the vertices that lost weight; refuses negative, non-finite or all-zero weights.
void add_joints_and_weights(BufferBuilder& buf, tinygltf::Primitive& prim, const SkinWeights& W, int n, int B,
                            GltfExportSummary& sum) {
  const SkinWeights W4 = gltf_top4_weights(W);
  const bool short_joints = B > 256;
  std::vector<uint8_t> j8;
  std::vector<uint16_t> j16;
  if (short_joints) j16.assign(4 * static_cast<size_t>(n), 0); else j8.assign(4 * static_cast<size_t>(n), 0);
  std::vector<float> w4(4 * static_cast<size_t>(n), 0.f);
  for (int i = 0; i < n; ++i) {
    double total = 0;
    int nonzero = 0;
    for (SkinWeights::InnerIterator it(W, i); it; ++it) {
      if (!std::isfinite(it.value()) || it.value() < 0)
        throw InputError("glTF export: weight of vertex " + std::to_string(i) + ", bone " + std::to_string(it.col()) +
                         " is " + std::to_string(it.value()) + ", expected a finite non-negative value");
      if (it.value() > 0) { total += it.value(); ++nonzero; }
    }
    if (!(total > 0)) throw InputError("glTF export: vertex " + std::to_string(i) + " has no positive weight");
    std::vector<std::pair<double, int>> kept;
    for (SkinWeights::InnerIterator it(W4, i); it; ++it) kept.emplace_back(it.value(), static_cast<int>(it.col()));
    std::sort(kept.begin(), kept.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    if (nonzero > 4) {
      ++sum.vertices_truncated;
      double kept_orig = 0;   // original weights of the kept bones
      for (const auto& [w, b] : kept) kept_orig += W.coeff(i, b);
      sum.max_dropped_weight = std::max(sum.max_dropped_weight, (total - kept_orig) / total);
    }
    for (size_t k = 0; k < kept.size(); ++k) {
      const size_t o = 4 * static_cast<size_t>(i) + k;
      w4[o] = static_cast<float>(kept[k].first);
      if (short_joints) j16[o] = static_cast<uint16_t>(kept[k].second); else j8[o] = static_cast<uint8_t>(kept[k].second);
    }
  }

  if (short_joints)
    prim.attributes["JOINTS_0"] = buf.accessor(j16.data(), j16.size() * 2, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                               TINYGLTF_TYPE_VEC4, n, TINYGLTF_TARGET_ARRAY_BUFFER);
  else
    prim.attributes["JOINTS_0"] = buf.accessor(j8.data(), j8.size(), TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                               TINYGLTF_TYPE_VEC4, n, TINYGLTF_TARGET_ARRAY_BUFFER);
  prim.attributes["WEIGHTS_0"] = buf.accessor(w4.data(), w4.size() * 4, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                              TINYGLTF_TYPE_VEC4, n, TINYGLTF_TARGET_ARRAY_BUFFER);
}

// The level's morph targets as sparse POSITION targets of `prim` (scaled to metres), the mesh's
// default weights (0) and the targets' names (extras.targetNames, read by three.js and Blender).
void add_morph_targets(BufferBuilder& buf, tinygltf::Primitive& prim, tinygltf::Mesh& mesh, const GltfLevel& l,
                       double s) {
  if (l.targets.empty()) return;
  tinygltf::Value::Array names;
  for (const GltfMorphTarget& t : l.targets) {
    std::vector<uint32_t> idx(t.vertex.begin(), t.vertex.end());
    std::vector<float> values(3 * idx.size());
    for (size_t i = 0; i < idx.size(); ++i)
      for (int d = 0; d < 3; ++d) values[3 * i + d] = static_cast<float>(t.delta(static_cast<Eigen::Index>(i), d) * s);
    prim.targets.push_back({{"POSITION", buf.sparse_vec3(static_cast<size_t>(l.V.rows()), idx, values)}});
    names.emplace_back(t.name);
  }
  mesh.weights.assign(l.targets.size(), 0.0);
  mesh.extras = tinygltf::Value(tinygltf::Value::Object{{"targetNames", tinygltf::Value(names)}});
}

// The morph targets' checks: indices strictly increasing within the level, finite deltas, and
// the weights (when given) one row per animation frame and one column per target.
void check_morph_targets(const GltfLevel& l, const GltfAnimation* animation) {
  for (const GltfMorphTarget& t : l.targets) {
    if (static_cast<Eigen::Index>(t.vertex.size()) != t.delta.rows())
      throw InputError("glTF export: morph target '" + t.name + "' of '" + l.name + "' has " +
                       std::to_string(t.vertex.size()) + " vertices and " + std::to_string(t.delta.rows()) + " deltas");
    for (size_t i = 0; i < t.vertex.size(); ++i)
      if (t.vertex[i] < 0 || t.vertex[i] >= l.V.rows() || (i && t.vertex[i] <= t.vertex[i - 1]))
        throw InputError("glTF export: morph target '" + t.name + "' of '" + l.name +
                         "': vertex indices must increase strictly within [0, " + std::to_string(l.V.rows()) +
                         "), found " + std::to_string(t.vertex[i]) + " at " + std::to_string(i));
    check_finite(t.delta, "morph target '" + t.name + "'");
  }
  if (l.target_weights.size() == 0) return;
  const Eigen::Index K = animation ? static_cast<Eigen::Index>(animation->frames.size()) : 0;
  const Eigen::Index T = l.target_times.empty() || !animation ? K : static_cast<Eigen::Index>(l.target_times.size());
  if (l.target_weights.rows() != T || l.target_weights.cols() != static_cast<Eigen::Index>(l.targets.size()))
    throw InputError("glTF export: morph weights of '" + l.name + "' are " + std::to_string(l.target_weights.rows()) +
                     " by " + std::to_string(l.target_weights.cols()) + ", expected #" +
                     (l.target_times.empty() ? "frames " : "target times ") + std::to_string(T) + " by #targets " +
                     std::to_string(l.targets.size()));
  for (size_t i = 0; i < l.target_times.size(); ++i) {
    const double t = l.target_times[i], end = static_cast<double>(K - 1) * animation->frame_time;
    if (!std::isfinite(t) || t < 0 || t > end * (1 + 1e-9) || (i && t <= l.target_times[i - 1]))
      throw InputError("glTF export: morph weight times of '" + l.name + "' must increase strictly within [0, " +
                       std::to_string(end) + "] s, found " + std::to_string(t) + " at " + std::to_string(i));
  }
  check_finite(l.target_weights, "morph weights of '" + l.name + "'");
}

// The joint nodes 0..B-1, the skin with its inverse bind matrices, the mesh nodes B..B+L-1 (one
// per level of detail, mesh k on node B + k, all with skin 0) and the scene (with a common root
// node B + L when the skeleton has several roots).
void add_skeleton_and_scene(tinygltf::Model& model, BufferBuilder& buf, const Skeleton& skeleton, double s,
                            const std::vector<std::string>& mesh_names) {
  const int B = skeleton.bone_count();
  for (int b = 0; b < B; ++b) {
    tinygltf::Node node;
    node.name = skeleton.names[static_cast<size_t>(b)];
    const Eigen::Vector3d t = rest_offset(skeleton, b) * s;
    if (t.squaredNorm() > 0) node.translation = {t(0), t(1), t(2)};
    model.nodes.push_back(node);
  }
  for (int b = 0; b < B; ++b) {
    const int p = skeleton.parents[static_cast<size_t>(b)];
    if (p >= 0) model.nodes[static_cast<size_t>(p)].children.push_back(b);
  }
  std::vector<float> ibm(16 * static_cast<size_t>(B), 0.f);
  for (int b = 0; b < B; ++b) {
    float* m = ibm.data() + 16 * static_cast<size_t>(b);   // column-major 4 by 4
    m[0] = m[5] = m[10] = m[15] = 1.f;
    for (int d = 0; d < 3; ++d) m[12 + d] = static_cast<float>(-skeleton.heads(b, d) * s);
  }
  tinygltf::Skin skin;
  skin.name = "skeleton";
  skin.inverseBindMatrices = buf.accessor(ibm.data(), ibm.size() * 4, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                          TINYGLTF_TYPE_MAT4, B, 0);
  skin.joints.resize(static_cast<size_t>(B));
  std::iota(skin.joints.begin(), skin.joints.end(), 0);
  std::vector<int> roots;
  for (int b = 0; b < B; ++b)
    if (skeleton.parents[static_cast<size_t>(b)] < 0) roots.push_back(b);

  const int L = static_cast<int>(mesh_names.size());
  tinygltf::Scene scene;
  scene.name = "scene";
  for (int k = 0; k < L; ++k) {
    tinygltf::Node mesh_node;
    mesh_node.name = mesh_names[static_cast<size_t>(k)];
    mesh_node.mesh = k;
    mesh_node.skin = 0;
    if (L > 1) mesh_node.extras = tinygltf::Value(tinygltf::Value::Object{{"lod", tinygltf::Value(k)}});
    model.nodes.push_back(mesh_node);   // node B + k
    scene.nodes.push_back(B + k);
  }
  if (roots.size() == 1) {
    skin.skeleton = roots[0];
    scene.nodes.push_back(roots[0]);
  } else {
    // glTF needs one common root for the joints: an identity node above the root joints.
    tinygltf::Node top;
    top.name = "skeleton_root";
    top.children = roots;
    model.nodes.push_back(top);   // node B + L
    skin.skeleton = B + L;
    scene.nodes.push_back(B + L);
  }
  model.skins.push_back(skin);
  model.scenes.push_back(scene);
  model.defaultScene = 0;
}

// Per joint, the animation's local rotations (xyzw) and translations frame by frame, and whether
// the joint ever leaves its rest offset (only those get a translation channel).
struct JointTracks {
  std::vector<std::vector<float>> rot, tra;
  std::vector<bool> moves;
};

// The joint tracks of an animation: each frame's bone maps checked rigid, projected onto
// rotations and made relative to the parent joint.
JointTracks joint_tracks(const Skeleton& skeleton, const GltfAnimation& animation, const GltfExportOptions& options,
                         double s) {
  const int B = skeleton.bone_count();
  const int T = static_cast<int>(animation.frames.size());
  JointTracks tracks;
  auto& rot = tracks.rot;
  auto& tra = tracks.tra;
  auto& moves = tracks.moves;
  rot.resize(static_cast<size_t>(B));
  tra.resize(static_cast<size_t>(B));
  std::vector<Eigen::Vector4d> prev(static_cast<size_t>(B));
  moves.assign(static_cast<size_t>(B), false);
  std::vector<Eigen::Matrix3d> Q(static_cast<size_t>(B));
  std::vector<Eigen::Vector3d> head(static_cast<size_t>(B));
  for (int t = 0; t < T; ++t) {
    const BoneTransforms& M = animation.frames[static_cast<size_t>(t)];
    if (static_cast<int>(M.size()) != B)
      throw InputError("glTF export: animation frame " + std::to_string(t) + " has " + std::to_string(M.size()) +
                       " bone transforms, expected " + std::to_string(B));
    for (int b = 0; b < B; ++b) {
      const Eigen::Matrix3d R = M[static_cast<size_t>(b)].linear();
      check_finite(M[static_cast<size_t>(b)].matrix(), "animation frame " + std::to_string(t) + ", bone " + std::to_string(b));
      const double dev = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
      if (dev > options.rigid_tolerance || R.determinant() < 0)
        throw InputError("glTF export: animation frame " + std::to_string(t) + ", bone " +
                         skeleton.names[static_cast<size_t>(b)] + " is not a rigid motion (|RᵀR − I| = " +
                         std::to_string(dev) + ", det " + std::to_string(R.determinant()) + ")");
      // Project onto the nearest rotation so the quaternion is exact.
      Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
      Q[static_cast<size_t>(b)] = svd.matrixU() * svd.matrixV().transpose();
      head[static_cast<size_t>(b)] = M[static_cast<size_t>(b)] * Eigen::Vector3d(skeleton.heads.row(b).transpose());
    }
    for (int b = 0; b < B; ++b) {
      const int p = skeleton.parents[static_cast<size_t>(b)];
      const Eigen::Matrix3d local_R = p >= 0 ? Eigen::Matrix3d(Q[static_cast<size_t>(p)].transpose() * Q[static_cast<size_t>(b)])
                                             : Q[static_cast<size_t>(b)];
      const Eigen::Vector3d local_t =
          (p >= 0 ? Eigen::Vector3d(Q[static_cast<size_t>(p)].transpose() * (head[static_cast<size_t>(b)] - head[static_cast<size_t>(p)]))
                  : head[static_cast<size_t>(b)]) * s;
      const Eigen::Vector4d q = quaternion_xyzw(local_R, t ? &prev[static_cast<size_t>(b)] : nullptr);
      prev[static_cast<size_t>(b)] = q;
      for (int d = 0; d < 4; ++d) rot[static_cast<size_t>(b)].push_back(static_cast<float>(q(d)));
      for (int d = 0; d < 3; ++d) tra[static_cast<size_t>(b)].push_back(static_cast<float>(local_t(d)));
      const Eigen::Vector3d rest_t = rest_offset(skeleton, b) * s;
      if (p < 0 || (local_t - rest_t).norm() > 1e-6 * std::max(1.0, rest_t.norm())) moves[static_cast<size_t>(b)] = true;
    }
  }
  return tracks;
}

// The animation: one linear sampler per joint rotation (and per moving joint's translation) over
// the shared frame times.
void add_animation(tinygltf::Model& model, BufferBuilder& buf, const Skeleton& skeleton, const GltfAnimation& animation,
                   const std::vector<GltfLevel>& levels, const GltfExportOptions& options, double s,
                   GltfExportSummary& sum) {
  const int B = skeleton.bone_count();
  const int T = static_cast<int>(animation.frames.size());
  if (!(animation.frame_time > 0) || !std::isfinite(animation.frame_time))
    throw InputError("glTF export: animation frame time must be positive, found " + std::to_string(animation.frame_time));
  sum.frames = T;
  const JointTracks tracks = joint_tracks(skeleton, animation, options, s);
  std::vector<float> times(static_cast<size_t>(T));
  for (int t = 0; t < T; ++t) times[static_cast<size_t>(t)] = static_cast<float>(t * animation.frame_time);
  const int input = buf.accessor(times.data(), times.size() * 4, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR,
                                 static_cast<size_t>(T), 0, {double(times.front())}, {double(times.back())});
  tinygltf::Animation anim;
  anim.name = animation.name;
  auto add = [&](int node, const std::vector<float>& values, int type, const char* path, size_t per_key = 1,
                 int own_input = -1, size_t keys = 0) {
    tinygltf::AnimationSampler sampler;
    sampler.input = own_input >= 0 ? own_input : input;
    sampler.interpolation = "LINEAR";
    sampler.output = buf.accessor(values.data(), values.size() * 4, TINYGLTF_COMPONENT_TYPE_FLOAT, type,
                                  (own_input >= 0 ? keys : static_cast<size_t>(T)) * per_key, 0);
    anim.samplers.push_back(sampler);
    tinygltf::AnimationChannel ch;
    ch.sampler = static_cast<int>(anim.samplers.size()) - 1;
    ch.target_node = node;
    ch.target_path = path;
    anim.channels.push_back(ch);
  };
  for (int b = 0; b < B; ++b) {
    add(b, tracks.rot[static_cast<size_t>(b)], TINYGLTF_TYPE_VEC4, "rotation");
    if (tracks.moves[static_cast<size_t>(b)]) add(b, tracks.tra[static_cast<size_t>(b)], TINYGLTF_TYPE_VEC3, "translation");
  }
  // Morph weights: the level's node (B + k), all targets' weights key by key.
  for (size_t k = 0; k < levels.size(); ++k) {
    const Eigen::MatrixXd& w = levels[k].target_weights;
    if (w.size() == 0) continue;
    std::vector<float> values;
    for (Eigen::Index t = 0; t < w.rows(); ++t)
      for (Eigen::Index j = 0; j < w.cols(); ++j) values.push_back(static_cast<float>(w(t, j)));
    const std::vector<double>& at = levels[k].target_times;
    int own = -1;
    if (!at.empty()) {   // the level's own sample times (e.g. corrections sampled between keys)
      const std::vector<float> t(at.begin(), at.end());
      own = buf.accessor(t.data(), t.size() * 4, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, t.size(), 0,
                         {double(t.front())}, {double(t.back())});
    }
    add(B + static_cast<int>(k), values, TINYGLTF_TYPE_SCALAR, "weights", static_cast<size_t>(w.cols()), own,
        static_cast<size_t>(w.rows()));
  }
  model.animations.push_back(anim);
}

}  // namespace

std::string skinned_gltf_bytes(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const Eigen::MatrixX3d& N_in,
                               const Skeleton& skeleton, const SkinWeights& W, const GltfAnimation* animation,
                               const GltfExportOptions& options, GltfExportSummary* summary) {
  GltfLevel level{options.mesh_name, V, F, N_in, W, options.parts, {}, {}, {}};
  return skinned_lods_gltf_bytes({level}, skeleton, animation, options, summary);
}

std::string skinned_lods_gltf_bytes(const std::vector<GltfLevel>& levels, const Skeleton& skeleton,
                                    const GltfAnimation* animation, const GltfExportOptions& options,
                                    GltfExportSummary* summary) {
  if (levels.empty()) throw InputError("glTF export: no mesh to write");
  // ---- checks, all levels before anything is built ----
  std::vector<Eigen::MatrixX3d> normals;
  for (const GltfLevel& l : levels) {
    check_skinned_inputs(l.V, l.F, skeleton, l.W, options);
    check_morph_targets(l, animation);
    normals.push_back(checked_normals(l.V, l.F, l.N));
  }
  const int B = skeleton.bone_count();
  GltfExportSummary sum;
  sum.joints = B;
  const double s = options.unit_scale;

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = options.generator;
  BufferBuilder buf(&model);

  // ---- one mesh per level (the buffer holds positions, normals, joints, weights, indices) ----
  std::vector<std::string> names;
  for (size_t k = 0; k < levels.size(); ++k) {
    const GltfLevel& l = levels[k];
    const int n = static_cast<int>(l.V.rows());
    sum.vertices += n;
    sum.triangles += static_cast<int>(l.F.rows());
    tinygltf::Primitive prim;
    add_positions_and_normals(buf, prim, l.V, normals[k], s);
    add_joints_and_weights(buf, prim, l.W, n, B, sum);
    tinygltf::Mesh mesh;
    mesh.name = l.name;
    add_morph_targets(buf, prim, mesh, l, s);
    if (l.parts.empty()) {
      add_indices(buf, prim, l.F);
      mesh.primitives.push_back(prim);
    } else {
      add_material_parts(model, buf, prim, l.F, l.parts, mesh);
    }
    model.meshes.push_back(mesh);
    names.push_back(l.name);
  }

  // ---- joints: nodes 0..B-1, the mesh nodes B.. ----
  add_skeleton_and_scene(model, buf, skeleton, s, names);

  // ---- animation ----
  if (animation && !animation->frames.empty()) add_animation(model, buf, skeleton, *animation, levels, options, s, sum);

  // ---- serialise ----
  std::ostringstream out;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&model, out, false, true))
    throw NumericalError("glTF export: tinygltf could not serialise the model");
  std::string bytes = out.str();
  sum.bytes = bytes.size();
  if (summary) *summary = sum;
  return bytes;
}

std::string static_gltf_bytes(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const Eigen::MatrixX3d& N_in,
                              const GltfExportOptions& options) {
  const int n = static_cast<int>(V.rows());
  if (n == 0 || F.rows() == 0) throw InputError("glTF export: the mesh is empty (" + std::to_string(n) + " vertices, " +
                                                std::to_string(F.rows()) + " triangles)");
  if (!(options.unit_scale > 0) || !std::isfinite(options.unit_scale))
    throw InputError("glTF export: unit_scale must be positive, found " + std::to_string(options.unit_scale));
  check_finite(V, "the vertices");
  if (F.minCoeff() < 0 || F.maxCoeff() >= n)
    throw InputError("glTF export: face indices must be in [0, " + std::to_string(n) + "), found " +
                     std::to_string(F.minCoeff()) + ".." + std::to_string(F.maxCoeff()));
  Eigen::MatrixX3d N = N_in.size() == 0 ? vertex_normals(V, F) : N_in;
  if (N.rows() != n)
    throw InputError("glTF export: " + std::to_string(N.rows()) + " normals for " + std::to_string(n) + " vertices");
  check_finite(N, "the normals");

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = options.generator;
  BufferBuilder buf(&model);
  tinygltf::Primitive prim;
  add_positions_and_normals(buf, prim, V, N, options.unit_scale);
  add_indices(buf, prim, F);
  tinygltf::Mesh mesh;
  mesh.name = options.mesh_name;
  mesh.primitives.push_back(prim);
  model.meshes.push_back(mesh);
  tinygltf::Node node;
  node.name = options.mesh_name;
  node.mesh = 0;
  model.nodes.push_back(node);
  tinygltf::Scene scene;
  scene.nodes.push_back(0);
  model.scenes.push_back(scene);
  model.defaultScene = 0;
  std::ostringstream out;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&model, out, false, true))
    throw NumericalError("glTF export: tinygltf could not serialise the mesh");
  return out.str();
}

GltfExportSummary write_skinned_gltf(const std::filesystem::path& path, const Eigen::MatrixX3d& V,
                                     const Eigen::MatrixX3i& F, const Eigen::MatrixX3d& N, const Skeleton& skeleton,
                                     const SkinWeights& W, const GltfAnimation* animation,
                                     const GltfExportOptions& options) {
  GltfExportSummary summary;
  const std::string bytes = skinned_gltf_bytes(V, F, N, skeleton, W, animation, options, &summary);
  write_atomically(path, [&](std::ostream& os) { os.write(bytes.data(), static_cast<std::streamsize>(bytes.size())); });
  return summary;
}

}  // namespace bodymodel
