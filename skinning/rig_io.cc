#include "skinning/rig_io.h"

#include "core/error.h"
#include "core/io/json_text.h"
#include "core/io/npz.h"

#include <nlohmann/json.hpp>

#include <cmath>

namespace bodymodel {

namespace {
void put_base(Npz& z, const std::filesystem::path& path, const SkinningRig& rig, const Eigen::MatrixX3i& faces,
              const std::vector<BoneTransforms>& poses) {
  z.put_int("bone_count", rig.bone_count);
  z.put("rest", Eigen::MatrixXd(rig.rest));
  z.put("faces", Eigen::MatrixXi(faces.size() ? Eigen::MatrixXi(faces) : Eigen::MatrixXi(0, 3)));
  z.put("influences", rig.influences);
  z.put("coefficients", rig.coefficients);
  if (!poses.empty()) {
    const Eigen::Index B = rig.bone_count;
    Eigen::MatrixXd T(static_cast<Eigen::Index>(poses.size()) * B, 12);
    for (size_t p = 0; p < poses.size(); ++p) {
      if (static_cast<Eigen::Index>(poses[p].size()) != B)
        throw InputError(path.string() + ": pose " + std::to_string(p) + " has " + std::to_string(poses[p].size()) +
                         " transforms, the rig " + std::to_string(B) + " bones");
      for (Eigen::Index b = 0; b < B; ++b) {
        const Eigen::Matrix<double, 3, 4> A = poses[p][static_cast<size_t>(b)].affine();
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 4; ++c) T(static_cast<Eigen::Index>(p) * B + b, 4 * r + c) = A(r, c);
      }
    }
    z.put("pose_transforms", T);
  }
}
}  // namespace

void save_rig(const std::filesystem::path& path, const SkinningRig& rig, const Eigen::MatrixX3i& faces,
              const std::vector<BoneTransforms>& poses, const Skeleton* skeleton) {
  rig.validate(path.string());
  Npz z;
  z.put_text("format", "bodymodel-skinning-rig-1");
  z.put_text("method", skinning_method_name(rig.method));
  put_base(z, path, rig, faces, poses);
  if (skeleton && skeleton->bone_count() > 0) {
    skeleton->validate();
    if (skeleton->bone_count() != rig.bone_count)
      throw InputError(path.string() + ": the skeleton has " + std::to_string(skeleton->bone_count()) +
                       " bones, the rig " + std::to_string(rig.bone_count));
    z.put_text("skeleton_names", json_text(nlohmann::json(skeleton->names)));
    Eigen::VectorXi parents(skeleton->bone_count());
    for (int b = 0; b < skeleton->bone_count(); ++b) parents(b) = skeleton->parents[static_cast<size_t>(b)];
    z.put("skeleton_parents", parents);
    z.put("skeleton_heads", Eigen::MatrixXd(skeleton->heads));
    z.put("skeleton_tails", Eigen::MatrixXd(skeleton->tails));
  }
  z.save(path);
}

SkinningRig load_rig(const std::filesystem::path& path, Eigen::MatrixX3i* faces,
                     std::vector<BoneTransforms>* poses, Skeleton* skeleton) {
  const Npz z = Npz::load(path);
  if (z.has("format") && z.text("format") == "bodymodel-pose-space-rig-1")
    throw InputError(path.string() + ": a " + (z.has("method") ? z.text("method") : std::string("pose-space")) +
                     " rig (pose-space corrections over SSD): only ssd, dqs, as and mwe rigs can be used here");
  if (!z.has("format") || z.text("format") != "bodymodel-skinning-rig-1")
    throw InputError(path.string() + ": not a bodymodel skinning rig (expected key 'format' = "
                     "'bodymodel-skinning-rig-1')");
  SkinningRig rig;
  try {
    rig.method = parse_skinning_method(z.text("method"));
  } catch (const InputError& e) {
    throw InputError(path.string() + ": 'method': " + e.what());
  }
  const double bones = z.scalar("bone_count");
  if (!(bones >= 1 && bones <= 1e6) || bones != std::floor(bones))
    throw InputError(path.string() + ": 'bone_count' is " + std::to_string(bones) +
                     ", expected a whole number from 1 to 1000000");
  rig.bone_count = static_cast<int>(bones);
  const Eigen::MatrixXd rest = z.matrix("rest");
  if (rest.cols() != 3) throw InputError(path.string() + ": 'rest' must have 3 columns");
  rig.rest = rest;
  rig.influences = z.int_matrix("influences");
  rig.coefficients = z.matrix("coefficients");
  rig.validate(path.string());
  if (faces) {
    const Eigen::MatrixXi F = z.int_matrix("faces");
    if (F.rows() && F.cols() != 3) throw InputError(path.string() + ": 'faces' must have 3 columns");
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      for (int k = 0; k < 3; ++k)
        if (F(f, k) < 0 || F(f, k) >= rig.rest.rows())
          throw InputError(path.string() + ": 'faces' row " + std::to_string(f) + " names vertex " +
                           std::to_string(F(f, k)) + ", expected 0.." + std::to_string(rig.rest.rows() - 1) +
                           " ('rest' has " + std::to_string(rig.rest.rows()) + " rows)");
    *faces = F.rows() ? Eigen::MatrixX3i(F) : Eigen::MatrixX3i(0, 3);
  }
  if (poses) {
    poses->clear();
    if (z.has("pose_transforms")) {
      const Eigen::MatrixXd T = z.matrix("pose_transforms");
      if (T.cols() != 12 || T.rows() % rig.bone_count != 0)
        throw InputError(path.string() + ": 'pose_transforms' must be #P·#B by 12");
      for (Eigen::Index r = 0; r < T.rows(); ++r)
        if (!T.row(r).allFinite())
          throw InputError(path.string() + ": 'pose_transforms' row " + std::to_string(r) + " (pose " +
                           std::to_string(r / rig.bone_count) + ", bone " + std::to_string(r % rig.bone_count) +
                           ") holds NaN or infinity");
      for (Eigen::Index p = 0; p < T.rows() / rig.bone_count; ++p) {
        BoneTransforms M(static_cast<size_t>(rig.bone_count), Eigen::Affine3d::Identity());
        for (int b = 0; b < rig.bone_count; ++b)
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c) M[static_cast<size_t>(b)].matrix()(r, c) = T(p * rig.bone_count + b, 4 * r + c);
        poses->push_back(M);
      }
    }
  }
  if (skeleton) {
    *skeleton = Skeleton{};
    if (z.has("skeleton_names")) {
      try {
        skeleton->names = nlohmann::json::parse(z.text("skeleton_names")).get<std::vector<std::string>>();
      } catch (const nlohmann::json::exception& e) {
        throw InputError(path.string() + ": 'skeleton_names' is not a JSON list of names: " + e.what());
      }
      for (const char* key : {"skeleton_parents", "skeleton_heads", "skeleton_tails"})
        if (!z.has(key)) throw InputError(path.string() + ": 'skeleton_names' without '" + key + "'");
      const Eigen::VectorXi parents = z.int_vector("skeleton_parents");
      skeleton->parents.assign(parents.data(), parents.data() + parents.size());
      const Eigen::MatrixXd heads = z.matrix("skeleton_heads"), tails = z.matrix("skeleton_tails");
      if (heads.cols() != 3 || tails.cols() != 3)
        throw InputError(path.string() + ": 'skeleton_heads' and 'skeleton_tails' must have 3 columns");
      skeleton->heads = heads;
      skeleton->tails = tails;
      if (skeleton->parents.size() != skeleton->names.size())
        throw InputError(path.string() + ": 'skeleton_parents' has " + std::to_string(skeleton->parents.size()) +
                         " entries, 'skeleton_names' " + std::to_string(skeleton->names.size()) + " bones");
      try {  // sizes, parents before children (so no cycles), finite joints
        skeleton->validate();
      } catch (const InputError& e) {
        throw InputError(path.string() + ": 'skeleton_parents'/'skeleton_heads'/'skeleton_tails': " + e.what());
      }
      if (skeleton->bone_count() != rig.bone_count)
        throw InputError(path.string() + ": the skeleton has " + std::to_string(skeleton->bone_count()) +
                         " bones, the rig " + std::to_string(rig.bone_count));
    }
  }
  return rig;
}

namespace {
Eigen::MatrixX3i read_faces(const Npz& z, const std::filesystem::path& path, Eigen::Index vertices) {
  const Eigen::MatrixXi F = z.int_matrix("faces");
  if (F.rows() && F.cols() != 3) throw InputError(path.string() + ": 'faces' must have 3 columns");
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (F(f, k) < 0 || F(f, k) >= vertices)
        throw InputError(path.string() + ": 'faces' row " + std::to_string(f) + " names vertex " +
                         std::to_string(F(f, k)) + ", expected 0.." + std::to_string(vertices - 1));
  return F.rows() ? Eigen::MatrixX3i(F) : Eigen::MatrixX3i(0, 3);
}
}  // namespace

bool is_pose_space_rig_file(const std::filesystem::path& path) {
  try {
    const Npz z = Npz::load(path);
    return z.has("format") && z.text("format") == "bodymodel-pose-space-rig-1";
  } catch (const InputError&) {
    return false;
  }
}

namespace {
// Ragged descriptor lists flattened: offsets (#G+1), pair indices, weights.
void put_descriptors(Npz& z, const std::string& prefix, const std::vector<std::vector<int>>& pairs,
                     const std::vector<std::vector<double>>& omega) {
  const Eigen::Index G = static_cast<Eigen::Index>(pairs.size());
  Eigen::VectorXi offsets(G + 1);
  offsets(0) = 0;
  for (Eigen::Index g = 0; g < G; ++g) offsets(g + 1) = offsets(g) + static_cast<int>(pairs[static_cast<size_t>(g)].size());
  Eigen::VectorXi list(offsets(G));
  Eigen::VectorXd w(offsets(G));
  for (Eigen::Index g = 0; g < G; ++g)
    for (size_t k = 0; k < pairs[static_cast<size_t>(g)].size(); ++k) {
      list(offsets(g) + static_cast<int>(k)) = pairs[static_cast<size_t>(g)][k];
      w(offsets(g) + static_cast<int>(k)) = omega[static_cast<size_t>(g)][k];
    }
  z.put(prefix + "_offsets", offsets);
  z.put(prefix + "_pair_list", list);
  z.put(prefix + "_omega_list", w);
}

void get_descriptors(const Npz& z, const std::string& file, const std::string& prefix,
                     std::vector<std::vector<int>>* pairs, std::vector<std::vector<double>>* omega) {
  const Eigen::VectorXi offsets = z.int_vector(prefix + "_offsets");
  const Eigen::VectorXi list = z.int_vector(prefix + "_pair_list");
  const Eigen::VectorXd w = z.vector(prefix + "_omega_list");
  const Eigen::Index G = offsets.size() - 1;
  if (G < 0 || offsets(0) != 0 || list.size() != offsets(G) || w.size() != offsets(G))
    throw InputError(file + ": '" + prefix + "_offsets', '" + prefix + "_pair_list' and '" + prefix +
                     "_omega_list' disagree");
  pairs->clear();
  omega->clear();
  for (Eigen::Index g = 0; g < G; ++g) {
    if (offsets(g + 1) < offsets(g))
      throw InputError(file + ": '" + prefix + "_offsets' decreases at entry " + std::to_string(g + 1));
    pairs->emplace_back(list.data() + offsets(g), list.data() + offsets(g + 1));
    omega->emplace_back(w.data() + offsets(g), w.data() + offsets(g + 1));
  }
}
}  // namespace

void save_pose_space_rig(const std::filesystem::path& path, const PoseSpaceRig& rig, const Eigen::MatrixX3i& faces,
                         const std::vector<BoneTransforms>& poses) {
  rig.validate(path.string());
  Npz z;
  z.put_text("format", "bodymodel-pose-space-rig-1");
  z.put_text("method", pose_space_method_name(rig.method));
  put_base(z, path, rig.base, faces, poses);
  z.put_int("poses", rig.poses);
  z.put("pairs", Eigen::MatrixXi(rig.pairs.rows() ? rig.pairs : Eigen::MatrixXi(0, 2)));
  z.put("pair_features", rig.pair_features);
  z.put("primary", Eigen::VectorXi(rig.primary));
  z.put("vertex_group", Eigen::VectorXi(rig.vertex_group));
  put_descriptors(z, "group", rig.group_pairs, rig.group_omega);
  z.put("group_sigma", Eigen::VectorXd(rig.group_sigma));
  z.put("vertex_mean", rig.vertex_mean);
  z.put("vertex_coef", rig.vertex_coef);
  const Eigen::Index n = rig.vertex_count();
  if (rig.method == PoseSpaceMethod::eigenskin) {
    const Eigen::Index G = static_cast<Eigen::Index>(rig.group_coef.size());
    Eigen::VectorXi columns(G);
    Eigen::Index total = 0, widest = 0;
    for (Eigen::Index g = 0; g < G; ++g) {
      columns(g) = static_cast<int>(rig.group_coef[static_cast<size_t>(g)].cols());
      total += columns(g);
      widest = std::max<Eigen::Index>(widest, columns(g));
    }
    Eigen::MatrixXd coef(rig.poses, total);
    for (Eigen::Index g = 0, c = 0; g < G; c += columns(g), ++g)
      coef.middleCols(c, columns(g)) = rig.group_coef[static_cast<size_t>(g)];
    Eigen::MatrixXd modes = Eigen::MatrixXd::Zero(n, 3 * widest);
    for (Eigen::Index i = 0; i < n; ++i)
      modes.row(i).head(rig.vertex_modes[static_cast<size_t>(i)].size()) = rig.vertex_modes[static_cast<size_t>(i)];
    z.put("group_columns", columns);
    z.put("group_coef", coef);
    z.put("vertex_modes", modes);
  }
  if (rig.method == PoseSpaceMethod::quadratic) {
    const int B = rig.bone_count();
    put_descriptors(z, "part", rig.part_pairs, rig.part_omega);
    z.put("part_sigma", Eigen::VectorXd(rig.part_sigma));
    z.put("part_mean", rig.part_mean);
    Eigen::MatrixXd coef(rig.poses, 30 * B);
    for (int b = 0; b < B; ++b) coef.middleCols(30 * b, 30) = rig.part_coef[static_cast<size_t>(b)];
    z.put("part_coef", coef);
    z.put("part_centroid", Eigen::MatrixXd(rig.part_centroid));
    Eigen::MatrixXd axes(B, 9);
    for (int b = 0; b < B; ++b)
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) axes(b, 3 * r + c) = rig.part_axes[static_cast<size_t>(b)](r, c);
    z.put("part_axes", axes);
    z.put("part_scale", Eigen::VectorXd(rig.part_scale));
    z.put("member", rig.member);
    z.put("vertex_quadratic", rig.vertex_quadratic);
  }
  z.save(path);
}

PoseSpaceRig load_pose_space_rig(const std::filesystem::path& path, Eigen::MatrixX3i* faces) {
  const Npz z = Npz::load(path);
  const std::string file = path.string();
  if (!z.has("format") || z.text("format") != "bodymodel-pose-space-rig-1")
    throw InputError(file + ": not a bodymodel pose-space rig (expected key 'format' = 'bodymodel-pose-space-rig-1')");
  PoseSpaceRig rig;
  try {
    rig.method = parse_pose_space_method(z.text("method"));
  } catch (const InputError& e) {
    throw InputError(file + ": 'method': " + e.what());
  }
  auto count = [&](const char* key, double hi) {
    const double v = z.scalar(key);
    if (!(v >= 1 && v <= hi) || v != std::floor(v))
      throw InputError(file + ": '" + key + "' is " + std::to_string(v) + ", expected a whole number from 1 to " +
                       std::to_string(static_cast<long long>(hi)));
    return static_cast<int>(v);
  };
  rig.base.method = SkinningMethod::lbs;
  rig.base.bone_count = count("bone_count", 65534);
  const Eigen::MatrixXd rest = z.matrix("rest");
  if (rest.cols() != 3) throw InputError(file + ": 'rest' must have 3 columns");
  rig.base.rest = rest;
  rig.base.influences = z.int_matrix("influences");
  rig.base.coefficients = z.matrix("coefficients");
  rig.poses = count("poses", 1e6);
  const Eigen::Index n = rig.base.rest.rows();
  rig.pairs = z.int_matrix("pairs");
  if (rig.pairs.rows() == 0) rig.pairs.resize(0, 2);   // an empty matrix comes back with one column
  rig.pair_features = z.matrix("pair_features");
  if (rig.pair_features.rows() == 0) rig.pair_features.resize(0, 9 * rig.poses);
  rig.primary = z.int_vector("primary");
  rig.vertex_group = z.int_vector("vertex_group");
  get_descriptors(z, file, "group", &rig.group_pairs, &rig.group_omega);
  rig.group_sigma = z.vector("group_sigma");
  const Eigen::MatrixXd mean = z.matrix("vertex_mean");
  if (mean.cols() != 3 || mean.rows() != n)
    throw InputError(file + ": 'vertex_mean' must be " + std::to_string(n) + " by 3");
  rig.vertex_mean = mean;
  rig.vertex_coef = z.matrix("vertex_coef");
  if (rig.vertex_coef.rows() == 0) rig.vertex_coef.resize(0, 0);
  const size_t G = rig.group_pairs.size();
  if (rig.method == PoseSpaceMethod::eigenskin) {
    const Eigen::VectorXi columns = z.int_vector("group_columns");
    const Eigen::MatrixXd coef = z.matrix("group_coef");
    const Eigen::MatrixXd modes = z.matrix("vertex_modes");
    if (static_cast<size_t>(columns.size()) != G || (columns.size() && columns.minCoeff() < 0) ||
        columns.sum() != (coef.rows() ? coef.cols() : 0) || (coef.rows() && coef.rows() != rig.poses))
      throw InputError(file + ": 'group_columns' and 'group_coef' disagree");
    for (Eigen::Index g = 0, c = 0; g < static_cast<Eigen::Index>(G); c += columns(g), ++g)
      rig.group_coef.push_back(columns(g) ? Eigen::MatrixXd(coef.middleCols(c, columns(g)))
                                          : Eigen::MatrixXd::Zero(rig.poses, 0));
    if (rig.vertex_group.size() != n || modes.rows() != n)
      throw InputError(file + ": 'vertex_group' and 'vertex_modes' need one row per vertex (" + std::to_string(n) + ")");
    for (Eigen::Index i = 0; i < n; ++i) {
      const int g = rig.vertex_group(i);
      if (g < 0 || static_cast<size_t>(g) >= G || 3 * columns(g) > modes.cols())
        throw InputError(file + ": vertex " + std::to_string(i) + " names neighbourhood " + std::to_string(g) +
                         " without stored modes");
      rig.vertex_modes.push_back(modes.row(i).head(3 * columns(g)));
    }
  }
  if (rig.method == PoseSpaceMethod::quadratic) {
    const int B = rig.base.bone_count;
    get_descriptors(z, file, "part", &rig.part_pairs, &rig.part_omega);
    rig.part_sigma = z.vector("part_sigma");
    rig.part_mean = z.matrix("part_mean");
    const Eigen::MatrixXd coef = z.matrix("part_coef");
    if (coef.rows() != rig.poses || coef.cols() != 30 * B)
      throw InputError(file + ": 'part_coef' must be " + std::to_string(rig.poses) + " by " + std::to_string(30 * B));
    for (int b = 0; b < B; ++b) rig.part_coef.push_back(coef.middleCols(30 * b, 30));
    const Eigen::MatrixXd centroid = z.matrix("part_centroid");
    if (centroid.cols() != 3) throw InputError(file + ": 'part_centroid' must have 3 columns");
    rig.part_centroid = centroid;
    const Eigen::MatrixXd axes = z.matrix("part_axes");
    if (axes.cols() != 9) throw InputError(file + ": 'part_axes' must have 9 columns");
    for (Eigen::Index b = 0; b < axes.rows(); ++b) {
      Eigen::Matrix3d E;
      for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) E(r, k) = axes(b, 3 * r + k);
      rig.part_axes.push_back(E);
    }
    rig.part_scale = z.vector("part_scale");
    rig.member = z.int_matrix("member");
    rig.vertex_quadratic = z.matrix("vertex_quadratic");
  }
  rig.validate(file);
  if (faces) *faces = read_faces(z, path, n);
  return rig;
}

}  // namespace bodymodel
