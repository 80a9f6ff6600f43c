// Tiny model and rig files in the real formats, made in code: the fuzz seeds (make_seeds.cc) and
// the reliability tests that corrupt one array at a time (tests/reliability/) start from these.
#pragma once

#include <Eigen/Core>
#include <memory>

#include "core/io/npz.h"
#include "core/skeleton.h"
#include "model/model_file.h"
#include "skinning/rig_io.h"

namespace bodymodel::tiny {

// A tetrahedron (#V = 4, #F = 4), outward faces.
inline Eigen::MatrixX3d tetra_vertices() {
  Eigen::MatrixX3d V(4, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  return V;
}
inline Eigen::MatrixX3i tetra_faces() {
  Eigen::MatrixX3i F(4, 3);
  F << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  return F;
}

// A model file with tiny arrays: the tetrahedron template (D = 60 encoding values), K = 2
// components, 3 samples, 2 labels, a two-bone rig (made by hand: building a model needs the
// solver stages, which the fuzz build leaves out).
inline Npz model_npz() {
  BodyModel m;
  m.tmpl = std::make_shared<EncodingTemplate>(tetra_vertices(), tetra_faces());
  const int D = m.tmpl->encoding_size(), K = 2, N = 3;
  m.mean = EncodingMean::from_values(Eigen::VectorXd::Zero(D));
  m.metadata = {{"format", "bodymodel-model"}, {"format_version", 1}};
  for (SubModel* sub : {&m.shape, &m.full}) {
    sub->pca.mean = Eigen::VectorXd::Zero(D);
    sub->pca.basis = Eigen::MatrixXd::Identity(D, K);
    sub->pca.eigenvalues = Eigen::Vector2d(2.0, 0.5);
    sub->pca.coefficients = Eigen::MatrixXd::Random(N, K);
    sub->labels = Eigen::MatrixXd::Random(N, 2);
    sub->sample_ids = {"s0", "s1", "s2"};
    sub->regression.labels = {{"height_cm", "cm", 170, 10, 150, 190}, {"sex", "", 0.5, 0.5, 0, 1}};
    sub->regression.offsets = Eigen::Vector2d(170, 0.5);
    sub->regression.gradients = Eigen::MatrixXd::Random(K, 2);
    sub->semantic_basis.basis = Eigen::MatrixXd::Identity(K, K);
    sub->semantic_basis.variances = Eigen::Vector2d(1, 1);
    sub->semantic_basis.semantic_labels = {"height_cm"};
  }
  m.rig.bone_names = {"root", "child"};
  m.rig.parents = {-1, 0};
  m.rig.head_regressor.resize(2, 4);
  m.rig.head_regressor.insert(0, 0) = 1;
  m.rig.head_regressor.insert(1, 1) = 0.5;
  m.rig.head_regressor.insert(1, 2) = 0.5;
  m.rig.tail_regressor = m.rig.head_regressor;
  m.rig.weights.resize(4, 2);
  for (int v = 0; v < 4; ++v) m.rig.weights.insert(v, v % 2) = 1;
  return model_to_npz(m);
}

// A skinning rig (SSD, the tetrahedron, 2 bones) with one fitted pose and, when `with_skeleton`,
// a two-bone skeleton; written to `path`.
inline void write_rig(const std::filesystem::path& path, bool with_skeleton) {
  SkinningRig rig;
  rig.bone_count = 2;
  rig.rest = tetra_vertices();
  rig.influences.resize(4, 2);
  rig.influences << 0, 1, 0, -1, 1, 0, 1, -1;
  rig.coefficients.resize(4, 2);
  rig.coefficients << 0.5, 0.5, 1, 0, 0.75, 0.25, 1, 0;
  BoneTransforms pose(2, Eigen::Affine3d::Identity());
  pose[1].translate(Eigen::Vector3d(1, 2, 3));
  Skeleton s;
  if (with_skeleton) {
    s.names = {"root", "child"};
    s.parents = {-1, 0};
    s.heads.resize(2, 3);
    s.heads << 0, 0, 0, 0, 0.5, 0;
    s.tails.resize(2, 3);
    s.tails << 0, 0.5, 0, 0, 1, 0;
  }
  save_rig(path, rig, tetra_faces(), {pose}, with_skeleton ? &s : nullptr);
}

}  // namespace bodymodel::tiny
