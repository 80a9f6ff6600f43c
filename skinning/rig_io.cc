#include "skinning/rig_io.h"

#include "core/error.h"
#include "core/io/npz.h"

#include <nlohmann/json.hpp>

#include <cmath>

namespace bodymodel {

void save_rig(const std::filesystem::path& path, const SkinningRig& rig, const Eigen::MatrixX3i& faces,
              const std::vector<BoneTransforms>& poses, const Skeleton* skeleton) {
  rig.validate(path.string());
  Npz z;
  z.put_text("format", "bodymodel-skinning-rig-1");
  z.put_text("method", skinning_method_name(rig.method));
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
  if (skeleton && skeleton->bone_count() > 0) {
    skeleton->validate();
    if (skeleton->bone_count() != rig.bone_count)
      throw InputError(path.string() + ": the skeleton has " + std::to_string(skeleton->bone_count()) +
                       " bones, the rig " + std::to_string(rig.bone_count));
    z.put_text("skeleton_names", nlohmann::json(skeleton->names).dump());
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

}  // namespace bodymodel
