// glTF export: the .glb re-read with tinygltf has the expected counts, weights summing to one, and
// glTF's own skinning (node hierarchy from the animation's first frame × inverse bind matrices)
// reproduces our LBS of the same frame within 1e-3 mm.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <sys/wait.h>
#include <unistd.h>

#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>   // declarations only: the implementation is in skinning/gltf_export.cc

#include "core/error.h"
#include "core/geometry.h"
#include "core/io/atomic_write.h"
#include "skinning/gltf_export.h"

namespace bodymodel {
namespace {

// A tube along +x (mm, 300 long) with a branching 5-bone skeleton: 0 root → 1 → 2, and 0 → 3 → 4.
// Weights: smooth hats over all five bones, so vertices have up to 5 non-zero weights (truncated
// to 4 by the export).
struct Character {
  Eigen::MatrixX3d V;
  Eigen::MatrixX3i F;
  Skeleton skeleton;
  SkinWeights W;
};

Character make_character() {
  Character c;
  const int rings = 21, seg = 12;
  c.V.resize(rings * seg, 3);
  for (int r = 0; r < rings; ++r)
    for (int s = 0; s < seg; ++s) {
      const double a = 2 * M_PI * s / seg;
      c.V.row(r * seg + s) << 300.0 * r / (rings - 1), 30 * std::cos(a), 30 * std::sin(a) + 500;
    }
  std::vector<Eigen::Vector3i> tris;
  for (int r = 0; r + 1 < rings; ++r)
    for (int s = 0; s < seg; ++s) {
      const int a = r * seg + s, b = r * seg + (s + 1) % seg;
      tris.emplace_back(a, b, b + seg);
      tris.emplace_back(a, b + seg, a + seg);
    }
  c.F.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t i = 0; i < tris.size(); ++i) c.F.row(static_cast<Eigen::Index>(i)) = tris[i];
  c.skeleton.names = {"root", "upper", "lower", "side", "tip"};
  c.skeleton.parents = {-1, 0, 1, 0, 3};
  c.skeleton.heads.resize(5, 3);
  c.skeleton.heads << 0, 0, 500, 100, 0, 500, 200, 0, 500, 50, 0, 520, 150, 0, 530;
  c.skeleton.tails = c.skeleton.heads;
  c.skeleton.tails.col(0).array() += 100;
  std::vector<Eigen::Triplet<double>> trip;
  for (int i = 0; i < c.V.rows(); ++i) {
    double w[5], sum = 0;
    for (int b = 0; b < 5; ++b) {
      const double d = (c.V.row(i) - c.skeleton.heads.row(b)).norm();
      w[b] = std::exp(-d * d / (2 * 90.0 * 90.0)) + (b == 0 ? 1e-3 : 0);
      sum += w[b];
    }
    for (int b = 0; b < 5; ++b) trip.emplace_back(i, b, w[b] / sum);
  }
  c.W.resize(c.V.rows(), 5);
  c.W.setFromTriplets(trip.begin(), trip.end());
  return c;
}

Pose random_pose(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  Pose p = Pose::rest(5);
  for (auto& R : p.rotations)
    R = Eigen::AngleAxisd(1.2 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()).toRotationMatrix();
  p.root_translation = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 200;
  return p;
}

tinygltf::Model load(const std::string& bytes) {
  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  const bool ok = loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                              static_cast<unsigned int>(bytes.size()));
  EXPECT_TRUE(ok) << err;
  EXPECT_TRUE(err.empty()) << err;
  return model;
}

// Typed element access through accessor → bufferView → buffer (tightly packed views).
template <typename T>
const T* data_of(const tinygltf::Model& m, int accessor) {
  const auto& a = m.accessors.at(static_cast<size_t>(accessor));
  const auto& v = m.bufferViews.at(static_cast<size_t>(a.bufferView));
  return reinterpret_cast<const T*>(m.buffers.at(static_cast<size_t>(v.buffer)).data.data() + v.byteOffset + a.byteOffset);
}

Eigen::Matrix4d trs(const std::vector<double>& t, const std::vector<double>& q) {
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  if (q.size() == 4) M.topLeftCorner<3, 3>() = Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized().toRotationMatrix();
  if (t.size() == 3) M.topRightCorner<3, 1>() << t[0], t[1], t[2];
  return M;
}

TEST(GltfExport, ReReadCountsWeightsAndSkinningMatchOurLbs) {
  const Character c = make_character();
  std::mt19937 rng(3);
  GltfAnimation anim;
  anim.frame_time = 0.04;
  std::vector<Pose> poses;
  for (int t = 0; t < 6; ++t) {
    poses.push_back(random_pose(rng));
    anim.frames.push_back(forward_kinematics(c.skeleton, poses.back()));
  }
  GltfExportSummary summary;
  const std::string bytes = skinned_gltf_bytes(c.V, c.F, {}, c.skeleton, c.W, &anim, {}, &summary);
  EXPECT_EQ(summary.bytes, bytes.size());
  EXPECT_EQ(summary.frames, 6);
  EXPECT_GT(summary.vertices_truncated, 0);                  // 5 non-zero weights per vertex
  EXPECT_LT(summary.max_dropped_weight, 0.3);
  ASSERT_EQ(bytes.substr(0, 4), "glTF");

  const tinygltf::Model m = load(bytes);
  ASSERT_EQ(m.meshes.size(), 1u);
  ASSERT_EQ(m.skins.size(), 1u);
  ASSERT_EQ(m.animations.size(), 1u);
  ASSERT_EQ(m.nodes.size(), 6u);   // 5 joints + the mesh node
  const auto& prim = m.meshes[0].primitives.at(0);
  const int n = static_cast<int>(c.V.rows());
  EXPECT_EQ(m.accessors.at(static_cast<size_t>(prim.attributes.at("POSITION"))).count, static_cast<size_t>(n));
  EXPECT_EQ(m.accessors.at(static_cast<size_t>(prim.indices)).count, static_cast<size_t>(3 * c.F.rows()));
  EXPECT_EQ(m.skins[0].joints.size(), 5u);
  EXPECT_EQ(m.nodes[0].children, (std::vector<int>{1, 3}));

  // Weights: 4 per vertex, sum to one; the same as gltf_top4_weights.
  const float* w = data_of<float>(m, prim.attributes.at("WEIGHTS_0"));
  const uint8_t* j = data_of<uint8_t>(m, prim.attributes.at("JOINTS_0"));
  ASSERT_EQ(m.accessors.at(static_cast<size_t>(prim.attributes.at("JOINTS_0"))).componentType,
            TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE);
  const SkinWeights W4 = gltf_top4_weights(c.W);
  Eigen::MatrixXd Wfile = Eigen::MatrixXd::Zero(n, 5);
  double worst_sum = 0;
  for (int i = 0; i < n; ++i) {
    double s = 0;
    for (int k = 0; k < 4; ++k) {
      s += w[4 * i + k];
      Wfile(i, j[4 * i + k]) += w[4 * i + k];
    }
    worst_sum = std::max(worst_sum, std::abs(s - 1));
  }
  EXPECT_LT(worst_sum, 1e-6);
  EXPECT_LT((Wfile - Eigen::MatrixXd(W4)).cwiseAbs().maxCoeff(), 1e-7);

  // glTF skinning of frame 0: node locals from the animation's first keyframes, world matrices
  // down the hierarchy, joint matrix = world · IBM; in metres, compared in mm.
  const auto& anim_m = m.animations[0];
  std::vector<std::vector<double>> T(5), Q(5);
  for (int b = 0; b < 5; ++b) {
    T[static_cast<size_t>(b)] = m.nodes[static_cast<size_t>(b)].translation;
    Q[static_cast<size_t>(b)] = m.nodes[static_cast<size_t>(b)].rotation;
  }
  for (const auto& ch : anim_m.channels) {
    const auto& sampler = anim_m.samplers.at(static_cast<size_t>(ch.sampler));
    EXPECT_EQ(m.accessors.at(static_cast<size_t>(sampler.output)).count, 6u);
    const float* out = data_of<float>(m, sampler.output);
    auto& dst = ch.target_path == "rotation" ? Q[static_cast<size_t>(ch.target_node)] : T[static_cast<size_t>(ch.target_node)];
    const int width = ch.target_path == "rotation" ? 4 : 3;
    dst.assign(out, out + width);   // keyframe 0
    if (width == 4) {
      EXPECT_NEAR(Eigen::Vector4d(out[0], out[1], out[2], out[3]).norm(), 1.0, 1e-6);
    }
  }
  const float* times = data_of<float>(m, anim_m.samplers.at(0).input);
  EXPECT_FLOAT_EQ(times[5], 0.2f);
  std::vector<Eigen::Matrix4d> G(5);
  for (int b = 0; b < 5; ++b) {
    const Eigen::Matrix4d L = trs(T[static_cast<size_t>(b)], Q[static_cast<size_t>(b)]);
    const int p = c.skeleton.parents[static_cast<size_t>(b)];
    G[static_cast<size_t>(b)] = p >= 0 ? Eigen::Matrix4d(G[static_cast<size_t>(p)] * L) : L;
  }
  const float* ibm = data_of<float>(m, m.skins[0].inverseBindMatrices);
  std::vector<Eigen::Matrix4d> J(5);
  for (int b = 0; b < 5; ++b)
    J[static_cast<size_t>(b)] = G[static_cast<size_t>(b)] * Eigen::Map<const Eigen::Matrix4f>(ibm + 16 * b).cast<double>();
  const float* pos = data_of<float>(m, prim.attributes.at("POSITION"));
  Eigen::MatrixX3d gltf_posed(n, 3);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector4d v(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2], 1.0);
    Eigen::Vector4d acc = Eigen::Vector4d::Zero();
    for (int k = 0; k < 4; ++k) acc += double(w[4 * i + k]) * (J[j[4 * i + k]] * v);
    gltf_posed.row(i) = acc.head<3>().transpose() * 1000.0;   // m → mm
  }
  const Eigen::MatrixX3d ours = linear_blend_skinning(c.V, W4, anim.frames[0]);
  EXPECT_LT((gltf_posed - ours).cwiseAbs().maxCoeff(), 1e-3);
  // The pose really moves the mesh (the comparison is not trivial).
  EXPECT_GT((ours - c.V).rowwise().norm().maxCoeff(), 50.0);

  // Normals are unit; positions' min/max are present (required by the spec).
  const auto& pa = m.accessors.at(static_cast<size_t>(prim.attributes.at("POSITION")));
  EXPECT_EQ(pa.minValues.size(), 3u);
  EXPECT_NEAR(pa.maxValues[0], 0.3, 1e-6);
}

TEST(GltfExport, FlatSkeletonCarriesArbitraryRigidBoneMaps) {
  const Character c = make_character();
  const Skeleton flat = flat_skeleton(5);
  std::mt19937 rng(5);
  GltfAnimation anim;
  anim.frames.push_back(forward_kinematics(c.skeleton, random_pose(rng)));
  const std::string bytes = skinned_gltf_bytes(c.V, c.F, {}, flat, c.W, &anim);
  const tinygltf::Model m = load(bytes);
  ASSERT_EQ(m.animations.size(), 1u);
  // Every flat joint is a root: 5 rotation + 5 translation channels; one common identity root
  // node above them (node 6, after the mesh node 5) carries the skin's skeleton.
  EXPECT_EQ(m.animations[0].channels.size(), 10u);
  ASSERT_EQ(m.nodes.size(), 7u);
  EXPECT_EQ(m.nodes[6].children, (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_EQ(m.skins.at(0).skeleton, 6);
  EXPECT_EQ(m.scenes.at(0).nodes, (std::vector<int>{5, 6}));
}

TEST(GltfExport, BadInputIsRejectedWithAReason) {
  const Character c = make_character();
  // Wrong weight shape.
  EXPECT_THROW(skinned_gltf_bytes(c.V, c.F, {}, c.skeleton, SkinWeights(c.V.rows(), 4)), InputError);
  // A vertex without weights.
  SkinWeights W = c.W;
  W.prune([](Eigen::Index r, Eigen::Index, double) { return r != 7; });
  EXPECT_THROW(skinned_gltf_bytes(c.V, c.F, {}, c.skeleton, W), InputError);
  // NaN vertex.
  Eigen::MatrixX3d V = c.V;
  V(3, 1) = std::nan("");
  EXPECT_THROW(skinned_gltf_bytes(V, c.F, {}, c.skeleton, c.W), InputError);
  // Non-rigid animation transform.
  GltfAnimation anim;
  anim.frames.push_back(BoneTransforms(5, Eigen::Affine3d::Identity()));
  anim.frames[0][2].linear() *= 1.1;
  try {
    skinned_gltf_bytes(c.V, c.F, {}, c.skeleton, c.W, &anim);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lower"), std::string::npos) << e.what();
  }
}

// The Khronos validator (npm gltf-validator) finds no errors in the exported file. Runs when
// `node` can load the package (NODE_PATH, or BODYMODEL_GLTF_VALIDATOR = its node_modules folder;
// scripts/test.sh installs it into build/npm and sets the latter); skipped otherwise.
// The unskinned export (`bodymodel serve`'s glb download): positions in metres, normals and
// triangles read back as written, no skin.
TEST(GltfExport, StaticMeshReadsBackInMetresWithoutASkin) {
  const Character c = make_character();
  const tinygltf::Model m = load(static_gltf_bytes(c.V, c.F));
  ASSERT_EQ(m.meshes.size(), 1u);
  EXPECT_TRUE(m.skins.empty());
  EXPECT_TRUE(m.animations.empty());
  const auto& prim = m.meshes[0].primitives.at(0);
  const auto& pa = m.accessors.at(static_cast<size_t>(prim.attributes.at("POSITION")));
  ASSERT_EQ(static_cast<Eigen::Index>(pa.count), c.V.rows());
  const float* P = data_of<float>(m, prim.attributes.at("POSITION"));
  const float* N = data_of<float>(m, prim.attributes.at("NORMAL"));
  double worst = 0, worst_unit = 0;
  for (Eigen::Index v = 0; v < c.V.rows(); ++v) {
    for (int d = 0; d < 3; ++d) worst = std::max(worst, std::abs(1000.0 * P[3 * v + d] - c.V(v, d)));
    worst_unit = std::max(worst_unit, std::abs(std::hypot(double(N[3 * v]), double(N[3 * v + 1]), double(N[3 * v + 2])) - 1));
  }
  EXPECT_LT(worst, 1e-3);  // mm: float32 metres of values up to 530 mm
  EXPECT_LT(worst_unit, 1e-6);
  ASSERT_EQ(static_cast<Eigen::Index>(m.accessors.at(static_cast<size_t>(prim.indices)).count), 3 * c.F.rows());
  const uint32_t* I = data_of<uint32_t>(m, prim.indices);
  for (Eigen::Index f = 0; f < c.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) ASSERT_EQ(I[3 * f + k], static_cast<uint32_t>(c.F(f, k)));
  EXPECT_THROW(static_gltf_bytes(Eigen::MatrixX3d(), c.F), InputError);
  Eigen::MatrixX3i bad = c.F;
  bad(0, 0) = static_cast<int>(c.V.rows());
  EXPECT_THROW(static_gltf_bytes(c.V, bad), InputError);
}

TEST(GltfExport, MaterialPartsBecomePrimitivesSharingTheVertices) {
  const Character c = make_character();
  const int nf = static_cast<int>(c.F.rows());
  GltfExportOptions o;
  o.parts = {{"skin", 0, 100, {0.8, 0.6, 0.5}, 0.7}, {"cloth", 100, nf - 100, {0.2, 0.3, 0.5}, 0.9}};
  const tinygltf::Model m = load(skinned_gltf_bytes(c.V, c.F, {}, c.skeleton, c.W, nullptr, o));
  ASSERT_EQ(m.meshes.size(), 1u);
  ASSERT_EQ(m.meshes[0].primitives.size(), 2u);
  ASSERT_EQ(m.materials.size(), 2u);
  for (int k = 0; k < 2; ++k) {
    const auto& p = m.meshes[0].primitives[static_cast<size_t>(k)];
    EXPECT_EQ(p.material, k);
    EXPECT_EQ(p.attributes.at("POSITION"), m.meshes[0].primitives[0].attributes.at("POSITION"));
    EXPECT_EQ(m.accessors[static_cast<size_t>(p.indices)].count, static_cast<size_t>(3 * (k == 0 ? 100 : nf - 100)));
  }
  EXPECT_EQ(m.materials[1].name, "cloth");
  EXPECT_NEAR(m.materials[1].pbrMetallicRoughness.baseColorFactor[2], 0.5, 1e-12);
  EXPECT_NEAR(m.materials[0].pbrMetallicRoughness.roughnessFactor, 0.7, 1e-12);
  // Parts must tile the triangles in order, with colours in [0, 1].
  GltfExportOptions gap = o;
  gap.parts[1].first_triangle = 101;
  EXPECT_THROW(skinned_gltf_bytes(c.V, c.F, {}, c.skeleton, c.W, nullptr, gap), InputError);
  GltfExportOptions shortfall = o;
  shortfall.parts[1].triangle_count -= 1;
  EXPECT_THROW(skinned_gltf_bytes(c.V, c.F, {}, c.skeleton, c.W, nullptr, shortfall), InputError);
  GltfExportOptions bright = o;
  bright.parts[0].base_colour[0] = 1.5;
  EXPECT_THROW(skinned_gltf_bytes(c.V, c.F, {}, c.skeleton, c.W, nullptr, bright), InputError);
}

// Levels of detail: one mesh and mesh node per level, all bound to the one skin, in the scene,
// tagged with extras {"lod": k}; materials with the same name and factors shared.
TEST(GltfExport, LevelsShareOneSkinAndTheirMaterials) {
  const Character c = make_character();
  const int nf = static_cast<int>(c.F.rows()), B = c.skeleton.bone_count();
  GltfLevel full{"lod0", c.V, c.F, {}, c.W, {{"skin", 0, 100, {0.8, 0.6, 0.5}, 0.7}, {"cloth", 100, nf - 100, {0.2, 0.3, 0.5}, 0.9}}, {}, {}};
  GltfLevel coarse{"lod1", c.V, c.F.topRows(150), {}, c.W, {{"skin", 0, 100, {0.8, 0.6, 0.5}, 0.7}, {"cloth", 100, 50, {0.2, 0.3, 0.5}, 0.9}}, {}, {}};
  GltfExportSummary sum;
  const tinygltf::Model m = load(skinned_lods_gltf_bytes({full, coarse}, c.skeleton, nullptr, {}, &sum));
  ASSERT_EQ(m.meshes.size(), 2u);
  ASSERT_EQ(m.skins.size(), 1u);
  EXPECT_EQ(m.materials.size(), 2u);
  EXPECT_EQ(sum.triangles, nf + 150);
  EXPECT_EQ(sum.vertices, 2 * static_cast<int>(c.V.rows()));
  for (int k = 0; k < 2; ++k) {
    const tinygltf::Node& node = m.nodes.at(static_cast<size_t>(B + k));
    EXPECT_EQ(node.name, k ? "lod1" : "lod0");
    EXPECT_EQ(node.mesh, k);
    EXPECT_EQ(node.skin, 0);
    EXPECT_EQ(node.extras.Get("lod").GetNumberAsInt(), k);
    EXPECT_NE(std::find(m.scenes[0].nodes.begin(), m.scenes[0].nodes.end(), B + k), m.scenes[0].nodes.end());
    for (int p = 0; p < 2; ++p) EXPECT_EQ(m.meshes[static_cast<size_t>(k)].primitives[static_cast<size_t>(p)].material, p);
  }
  EXPECT_EQ(m.accessors.at(static_cast<size_t>(m.meshes[1].primitives[1].indices)).count, 150u);
  // One level: the single-mesh layout, no extras.
  EXPECT_FALSE(load(skinned_lods_gltf_bytes({full}, c.skeleton)).nodes.at(static_cast<size_t>(B)).extras.IsObject());
  EXPECT_THROW(skinned_lods_gltf_bytes({}, c.skeleton), InputError);
  coarse.W = c.W.topRows(10);
  EXPECT_THROW(skinned_lods_gltf_bytes({full, coarse}, c.skeleton), InputError);   // checked level by level
}

// Morph targets: sparse accessors without a buffer view holding only the listed vertices (scaled to
// metres, min and max covering the zeros), every primitive with every target, the mesh's default
// weights and target names, and a `weights` channel on the level's node (#frames × #targets
// values); bad indices or weights are refused.
TEST(GltfExport, MorphTargetsAreSparseAndPlayedByAWeightsChannel) {
  const Character c = make_character();
  const int nf = static_cast<int>(c.F.rows()), B = c.skeleton.bone_count();
  GltfLevel full{"lod0", c.V, c.F, {}, c.W, {{"skin", 0, 100, {0.8, 0.6, 0.5}, 0.7}, {"cloth", 100, nf - 100, {0.2, 0.3, 0.5}, 0.9}}, {}, {}};
  Eigen::MatrixX3d d(3, 3);
  d << 1, 2, 3, -4, 5, 6, 7, -8, 9;
  full.targets = {{"frame_1", {3, 10, 50}, d}, {"frame_2", {7}, Eigen::MatrixX3d::Constant(1, 3, 0.5)}};
  full.target_weights = Eigen::MatrixXd::Zero(3, 2);
  full.target_weights(1, 0) = full.target_weights(2, 1) = 1;
  std::mt19937 rng(3);
  GltfAnimation anim;
  for (int t = 0; t < 3; ++t) anim.frames.push_back(forward_kinematics(c.skeleton, random_pose(rng)));
  const tinygltf::Model m = load(skinned_lods_gltf_bytes({full}, c.skeleton, &anim));
  const tinygltf::Mesh& mesh = m.meshes.at(0);
  ASSERT_EQ(mesh.primitives.size(), 2u);
  for (const tinygltf::Primitive& p : mesh.primitives) ASSERT_EQ(p.targets.size(), 2u);
  EXPECT_EQ(mesh.weights, std::vector<double>({0.0, 0.0}));
  EXPECT_EQ(mesh.extras.Get("targetNames").Get(1).Get<std::string>(), "frame_2");
  const tinygltf::Accessor& a = m.accessors.at(static_cast<size_t>(mesh.primitives[1].targets[0].at("POSITION")));
  EXPECT_EQ(a.bufferView, -1);
  EXPECT_EQ(a.count, static_cast<size_t>(c.V.rows()));
  ASSERT_TRUE(a.sparse.isSparse);
  ASSERT_EQ(a.sparse.count, 3);
  EXPECT_EQ(a.sparse.indices.componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
  const auto bytes = [&](int view, int offset) {
    const tinygltf::BufferView& bv = m.bufferViews.at(static_cast<size_t>(view));
    return m.buffers[0].data.data() + bv.byteOffset + offset;
  };
  const auto* idx = reinterpret_cast<const uint16_t*>(bytes(a.sparse.indices.bufferView, a.sparse.indices.byteOffset));
  const auto* val = reinterpret_cast<const float*>(bytes(a.sparse.values.bufferView, a.sparse.values.byteOffset));
  EXPECT_EQ(std::vector<int>(idx, idx + 3), std::vector<int>({3, 10, 50}));
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(val[3 * i + k], 0.001 * d(i, k), 1e-9);
  ASSERT_EQ(a.minValues.size(), 3u);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(a.minValues[k], std::vector<double>({-0.004, -0.008, 0.0})[k], 1e-9);
  EXPECT_NEAR(a.maxValues[0], 0.007, 1e-9);
  // The weights channel: LINEAR, on the mesh node, the keys' weights in order.
  int channels = 0;
  for (const tinygltf::AnimationChannel& ch : m.animations.at(0).channels) {
    if (ch.target_path != "weights") continue;
    ++channels;
    EXPECT_EQ(ch.target_node, B);
    const tinygltf::AnimationSampler& s = m.animations[0].samplers.at(static_cast<size_t>(ch.sampler));
    EXPECT_EQ(s.interpolation, "LINEAR");
    const tinygltf::Accessor& o = m.accessors.at(static_cast<size_t>(s.output));
    ASSERT_EQ(o.count, 6u);
    const auto* w = reinterpret_cast<const float*>(bytes(o.bufferView, static_cast<int>(o.byteOffset)));
    EXPECT_EQ(std::vector<float>(w, w + 6), std::vector<float>({0, 0, 1, 0, 0, 1}));
  }
  EXPECT_EQ(channels, 1);
  // Refused: indices not increasing, out of range, deltas not matching, weights of the wrong shape.
  GltfLevel bad = full;
  bad.targets[0].vertex = {10, 3, 50};
  EXPECT_THROW(skinned_lods_gltf_bytes({bad}, c.skeleton, &anim), InputError);
  bad = full;
  bad.targets[1].vertex = {static_cast<int>(c.V.rows())};
  EXPECT_THROW(skinned_lods_gltf_bytes({bad}, c.skeleton, &anim), InputError);
  bad = full;
  bad.targets[1].vertex = {1, 2};
  EXPECT_THROW(skinned_lods_gltf_bytes({bad}, c.skeleton, &anim), InputError);
  bad = full;
  bad.target_weights = Eigen::MatrixXd::Zero(2, 2);
  EXPECT_THROW(skinned_lods_gltf_bytes({bad}, c.skeleton, &anim), InputError);
}

// Morph weights sampled at their own times (corrections added between keys): the weights channel
// gets its own input accessor with those times (min, max set) and one row of weights per time,
// the joints keep the keys' input; times that do not increase strictly, or leave the clip, are
// refused, and so are weights with a row per key instead of per time.
TEST(GltfExport, MorphWeightsAtTheirOwnTimesGetTheirOwnSamplerInput) {
  const Character c = make_character();
  GltfLevel full{"lod0", c.V, c.F, {}, c.W, {}, {}, {}, {}};
  full.targets = {{"frame_1", {3}, Eigen::MatrixX3d::Constant(1, 3, 1.0)}, {"frame_1.5", {4}, Eigen::MatrixX3d::Constant(1, 3, 2.0)}};
  full.target_weights = Eigen::MatrixXd::Zero(4, 2);
  full.target_weights(1, 0) = full.target_weights(2, 1) = 1;
  full.target_times = {0.0, 0.1, 0.15, 0.2};   // keys at 0, 0.1, 0.2 s and one sample half-way
  std::mt19937 rng(5);
  GltfAnimation anim;
  anim.frame_time = 0.1;
  for (int t = 0; t < 3; ++t) anim.frames.push_back(forward_kinematics(c.skeleton, random_pose(rng)));
  const tinygltf::Model m = load(skinned_lods_gltf_bytes({full}, c.skeleton, &anim));
  const auto floats = [&](int index) {
    const tinygltf::Accessor& a = m.accessors.at(static_cast<size_t>(index));
    const tinygltf::BufferView& bv = m.bufferViews.at(static_cast<size_t>(a.bufferView));
    const auto* f = reinterpret_cast<const float*>(m.buffers[0].data.data() + bv.byteOffset + a.byteOffset);
    return std::vector<float>(f, f + a.count * static_cast<size_t>(tinygltf::GetNumComponentsInType(static_cast<uint32_t>(a.type))));
  };
  int weights = 0, joint_input = -1;
  for (const tinygltf::AnimationChannel& ch : m.animations.at(0).channels) {
    const tinygltf::AnimationSampler& s = m.animations[0].samplers.at(static_cast<size_t>(ch.sampler));
    if (ch.target_path != "weights") {
      joint_input = s.input;
      EXPECT_EQ(floats(s.input), std::vector<float>({0.0f, 0.1f, 0.2f}));
      continue;
    }
    ++weights;
    EXPECT_NE(s.input, joint_input);
    EXPECT_EQ(floats(s.input), std::vector<float>({0.0f, 0.1f, 0.15f, 0.2f}));
    const tinygltf::Accessor& in = m.accessors.at(static_cast<size_t>(s.input));
    EXPECT_EQ(in.minValues, std::vector<double>({0.0}));
    EXPECT_NEAR(in.maxValues.at(0), 0.2, 1e-7);
    EXPECT_EQ(floats(s.output), std::vector<float>({0, 0, 1, 0, 0, 1, 0, 0}));
  }
  EXPECT_EQ(weights, 1);
  GltfLevel bad = full;
  bad.target_times = {0.0, 0.15, 0.1, 0.2};
  EXPECT_THROW(skinned_lods_gltf_bytes({bad}, c.skeleton, &anim), InputError);
  bad.target_times = {0.0, 0.1, 0.15, 0.25};   // past the last key
  EXPECT_THROW(skinned_lods_gltf_bytes({bad}, c.skeleton, &anim), InputError);
  bad.target_times = {0.0, 0.1, 0.2};           // 3 times for 4 rows of weights
  EXPECT_THROW(skinned_lods_gltf_bytes({bad}, c.skeleton, &anim), InputError);
}

TEST(GltfExport, KhronosValidatorReportsNoErrors) {
  const char* modules = std::getenv("BODYMODEL_GLTF_VALIDATOR");
  const char* node_path = std::getenv("NODE_PATH");
  std::string env;
  if (modules) env = std::string("NODE_PATH=") + modules + " ";
  else if (node_path) env = std::string("NODE_PATH=") + node_path + " ";
  else if (std::filesystem::exists("/tmp/node_modules/gltf-validator")) env = "NODE_PATH=/tmp/node_modules ";
  else GTEST_SKIP() << "gltf-validator not installed (npm install gltf-validator; set BODYMODEL_GLTF_VALIDATOR)";
  const Character c = make_character();
  std::mt19937 rng(11);
  GltfAnimation anim;
  for (int t = 0; t < 4; ++t) anim.frames.push_back(forward_kinematics(c.skeleton, random_pose(rng)));
  const auto dir = std::filesystem::temp_directory_path() / ("bodymodel_gltf_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto file = dir / "tube.glb", flat = dir / "flat.glb";
  write_skinned_gltf(file, c.V, c.F, {}, c.skeleton, c.W, &anim);
  write_skinned_gltf(flat, c.V, c.F, {}, flat_skeleton(5), c.W, &anim);   // several root joints
  GltfExportOptions two;
  two.parts = {{"skin", 0, 100, {0.8, 0.6, 0.5}}, {"cloth", 100, static_cast<int>(c.F.rows()) - 100, {0.2, 0.3, 0.5}}};
  const auto parts = dir / "parts.glb";
  write_skinned_gltf(parts, c.V, c.F, {}, c.skeleton, c.W, &anim, two);  // two materials
  const auto levels = dir / "levels.glb";   // two levels of detail sharing the skin and materials
  {
    GltfLevel full{"lod0", c.V, c.F, {}, c.W, two.parts, {}, {}}, coarse{"lod1", c.V, c.F.topRows(150), {}, c.W, two.parts, {}, {}};
    coarse.parts[1].triangle_count = 50;
    // The full level with two sparse morph targets played by a weights channel with its own times
    // (one sample half-way between keys 1 and 2).
    full.targets = {{"a", {3, 10, 50}, Eigen::MatrixX3d::Constant(3, 3, 2.0)}, {"b", {7}, Eigen::MatrixX3d::Constant(1, 3, -1.0)}};
    full.target_weights = Eigen::MatrixXd::Zero(5, 2);
    full.target_weights(1, 0) = full.target_weights(2, 1) = 1;
    const double ft = anim.frame_time;
    full.target_times = {0, ft, 1.5 * ft, 2 * ft, 3 * ft};
    const std::string bytes = skinned_lods_gltf_bytes({full, coarse}, c.skeleton, &anim);
    write_text_file(levels, bytes);
  }
  const auto script = std::filesystem::path(__FILE__).parent_path() / "gltf_validate.js";
  const auto log = dir / "validator.txt";
  const int rc = std::system((env + "node " + script.string() + " " + file.string() + " " + flat.string() + " " + parts.string() + " " + levels.string() + " > " +
                              log.string() + " 2>&1").c_str());
  const std::string text = read_text_file(log);
  std::filesystem::remove_all(dir);
  if (WIFEXITED(rc) && WEXITSTATUS(rc) == 2) GTEST_SKIP() << text;
  EXPECT_EQ(rc, 0) << text;
  EXPECT_NE(text.find("tube.glb: errors 0 "), std::string::npos) << text;
  EXPECT_NE(text.find("flat.glb: errors 0 "), std::string::npos) << text;
  EXPECT_NE(text.find("parts.glb: errors 0 "), std::string::npos) << text;
  EXPECT_NE(text.find("levels.glb: errors 0 "), std::string::npos) << text;
  std::printf("%s", text.c_str());   // the validator's counts and first messages, for the log
}

}  // namespace
}  // namespace bodymodel
