// A small full model (shape and pose) made in-test from MakeHuman bodies, the way synth-db
// makes its truth meshes: each subject in the standard pose and in a few poses, posed by linear
// blend skinning with MakeHuman's weights; height/weight as subject labels and every bone's
// rotation vector as pose labels; the model's rig fitted from MakeHuman (8 training bodies).
// Shared by the pose-morph tests (tests/model) and the character tests (tests/tools).
#pragma once

#include <fmt/format.h>

#include <vector>

#include "core/makehuman.h"
#include "core/rotation.h"
#include "core/skeleton.h"
#include "model/body_model.h"
#include "model/model_rig.h"

namespace bodymodel::testing {

struct SmallFullModelSubject {
  MakeHuman::Body body;
  double height_cm = 0;         // subject label
  double weight_kg = 0;         // subject label
  std::vector<Pose> poses;      // posed copies besides the standard pose
};

inline BodyModel build_small_full_model(const MakeHuman& mh, const std::vector<SmallFullModelSubject>& subjects) {
  ModelBuildInput in;
  in.F = mh.body_faces();
  in.subject_labels = {{"height_cm", "cm"}, {"weight_kg", "kg"}};
  std::vector<Eigen::RowVector2d> rows;
  std::vector<Pose> poses;
  for (size_t s = 0; s < subjects.size(); ++s) {
    const SmallFullModelSubject& sub = subjects[s];
    const MakeHuman::Body& b = sub.body;
    auto add = [&](const Eigen::MatrixX3d& V, const Pose& p, bool standard, size_t k) {
      in.meshes.push_back(V);
      in.scan_ids.push_back(fmt::format("s{}_p{}", s, k));
      in.subject_ids.push_back(fmt::format("s{}", s));
      in.is_standard_pose.push_back(standard);
      rows.emplace_back(sub.height_cm, sub.weight_kg);
      poses.push_back(p);
    };
    add(b.mesh.V, Pose::rest(b.skeleton.bone_count()), true, 0);
    for (size_t k = 0; k < sub.poses.size(); ++k)
      add(linear_blend_skinning(b.mesh.V, b.weights, forward_kinematics(b.skeleton, sub.poses[k])), sub.poses[k],
          false, k + 1);
  }
  const Skeleton sk = mh.body(MacroSettings{}).skeleton;
  for (int b = 0; b < sk.bone_count(); ++b)
    for (const char* ax : {"rx", "ry", "rz"}) in.pose_labels.push_back({"pose:" + sk.names[b] + ":" + ax, "rad"});
  const int S = static_cast<int>(in.meshes.size());
  in.subject_label_values.resize(S, 2);
  in.pose_label_values.resize(S, in.pose_labels.size());
  for (int s = 0; s < S; ++s) {
    in.subject_label_values.row(s) = rows[s];
    for (int b = 0; b < sk.bone_count(); ++b)
      in.pose_label_values.block(s, 3 * b, 1, 3) = rotation_vector_of(poses[s].rotations[b]).transpose();
  }
  BodyModel model = build_body_model(in);
  ModelRigOptions ro;
  ro.training_bodies = 8;
  model.rig = fit_makehuman_rig(mh, ro);
  return model;
}

}  // namespace bodymodel::testing
