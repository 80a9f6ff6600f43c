#include "model/pose_edit.h"

#include <algorithm>
#include <numeric>

#include "core/error.h"
#include "core/geometry.h"
#include "model/format.h"

namespace bodymodel {

double mean_vertex_error_after_rigid_fit(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B) {
  Eigen::MatrixX3d a = apply(fit_rigid_motion(A, B), A);
  return (a - B).rowwise().norm().mean();
}

Eigen::MatrixX3d edit_with_handles(const BodyModel& model, RelativeRotationDecoder& decoder,
                                   const Eigen::MatrixX3d& V, const std::vector<VertexHandle>& handles,
                                   const EditOptions& o, EditSummary* summary) {
  const int nV = model.tmpl->vertex_count();
  if (handles.empty()) throw InputError("edit: no handles given");
  for (auto& h : handles)
    if (h.vertex < 0 || h.vertex >= nV)
      throw InputError(fmt::format("edit: handle vertex {} is out of range (the model has {} vertices)", h.vertex, nV));
  const SubModel& sm = model.shape;
  Eigen::VectorXd x = model.encode(V, "input body").values;
  Eigen::VectorXd c = sm.pca.project(x);
  const Eigen::VectorXd detail = x - sm.pca.reconstruct(c);

  // Constraints: handles (decoder default weight) and anchors far from them.
  PositionConstraints pc;
  std::vector<int> verts;
  std::vector<Eigen::Vector3d> targets;
  std::vector<double> weights;
  const double hw = DecoderOptions{}.constraint_weight;
  for (auto& h : handles) {
    verts.push_back(h.vertex);
    targets.push_back(V.row(h.vertex).transpose() + h.offset);
    weights.push_back(hw);
  }
  Eigen::VectorXd dist = Eigen::VectorXd::Constant(nV, 1e300);
  for (auto& h : handles)
    for (int v = 0; v < nV; ++v) dist(v) = std::min(dist(v), (V.row(v) - V.row(h.vertex)).norm());
  // Farthest-point sampling among the eligible vertices.
  std::vector<int> anchors;
  Eigen::VectorXd fd = dist;
  for (int a = 0; a < o.anchors; ++a) {
    int best = -1;
    double bd = o.anchor_distance_mm;
    for (int v = 0; v < nV; ++v)
      if (dist(v) >= o.anchor_distance_mm && fd(v) >= bd) {
        bd = fd(v);
        best = v;
      }
    if (best < 0) break;
    anchors.push_back(best);
    for (int v = 0; v < nV; ++v) fd(v) = std::min(fd(v), (V.row(v) - V.row(best)).norm());
  }
  for (int a : anchors) {
    verts.push_back(a);
    targets.push_back(V.row(a).transpose());
    weights.push_back(o.anchor_weight);
  }
  pc.vertices.resize(verts.size());
  pc.targets.resize(verts.size(), 3);
  pc.weights.resize(verts.size());
  for (size_t i = 0; i < verts.size(); ++i) {
    pc.vertices(i) = verts[i];
    pc.targets.row(i) = targets[i].transpose();
    pc.weights(i) = weights[i];
  }
  auto handle_errors = [&](const Eigen::MatrixX3d& M, bool rigid) {
    Eigen::MatrixX3d P = M;
    if (rigid) {
      // The projected shape has no placement: fit it onto the constraint targets.
      Eigen::MatrixX3d A(verts.size(), 3), B(verts.size(), 3);
      for (size_t i = 0; i < verts.size(); ++i) {
        A.row(i) = M.row(verts[i]);
        B.row(i) = targets[i].transpose();
      }
      P = apply(fit_rigid_motion(A, B, pc.weights.cwiseSqrt()), M);
    }
    std::vector<double> e;
    for (size_t i = 0; i < handles.size(); ++i) e.push_back((P.row(verts[i]).transpose() - targets[i]).norm());
    return e;
  };
  EditSummary sum;
  for (int it = 0; it < o.iterations; ++it) {
    Eigen::MatrixX3d Vc = decoder.decode(model.encoding_of(x), pc);
    Eigen::VectorXd xc = model.encode(Vc).values;
    c = sm.pca.project(xc);
    x = sm.pca.reconstruct(c) + detail;
    auto e = handle_errors(decoder.decode(model.encoding_of(x)), true);
    sum.handle_error_per_iteration_mm.push_back(*std::max_element(e.begin(), e.end()));
    sum.iterations = it + 1;
  }
  Eigen::MatrixX3d out = decoder.decode(model.encoding_of(x), pc);
  auto e = handle_errors(out, false);
  sum.max_handle_error_mm = *std::max_element(e.begin(), e.end());
  sum.mean_handle_error_mm = std::accumulate(e.begin(), e.end(), 0.0) / e.size();
  if (summary) *summary = sum;
  return out;
}

Eigen::MatrixX3d pose_morph(const BodyModel& model, RelativeRotationDecoder& decoder, const Eigen::MatrixX3d& V,
                            const Pose& pose, const PoseMorphOptions& o, PoseMorphSummary* summary) {
  if (model.rig.empty()) throw InputError("pose: the model has no skeleton (rebuild it without --no-rig)");
  if (static_cast<int>(pose.rotations.size()) != model.rig.bone_count())
    throw InputError(fmt::format("pose: {} bone rotations, the model's skeleton has {} bones",
                                 pose.rotations.size(), model.rig.bone_count()));
  const SubModel& fm = model.full;
  const SemanticRegression& reg = fm.regression;
  Eigen::VectorXd x = model.encode(V, "input body").values;
  Eigen::VectorXd c0 = fm.pca.project(x);
  Eigen::VectorXd pred = reg.predict(c0);
  Eigen::VectorXd target = pose_label_values(reg.labels, model.rig.bone_names, pose);
  std::vector<int> cols;
  std::vector<double> delta;
  int npose = 0, nkeep = 0;
  for (int l = 0; l < reg.label_count(); ++l) {
    const std::string& n = reg.labels[l].name;
    if (n.rfind("pose:", 0) == 0) {
      cols.push_back(l);
      delta.push_back(target(l) - pred(l));
      ++npose;
    } else if (o.keep_labels.empty() ||
               std::find(o.keep_labels.begin(), o.keep_labels.end(), n) != o.keep_labels.end()) {
      cols.push_back(l);
      delta.push_back(0.0);
      ++nkeep;
    }
  }
  // Labels on comparable scales: each row divided by the label's standard deviation.
  Eigen::MatrixXd S(fm.component_count(), cols.size());
  Eigen::VectorXd d(cols.size());
  for (size_t i = 0; i < cols.size(); ++i) {
    double sd = std::max(reg.labels[cols[i]].stddev, 1e-6);
    S.col(i) = reg.gradients.col(cols[i]) / sd;
    d(i) = delta[i] / sd;
  }
  ConstrainedChangeOptions co;
  co.damping = o.damping;
  Eigen::VectorXd z = constrained_change(S, d, co);
  Eigen::VectorXd xp = x + fm.pca.basis * z;

  PositionConstraints pc;
  if (o.use_tip_constraints) {
    Skeleton sk = model.rig.skeleton_for(V);
    Eigen::MatrixX3d posed = linear_blend_skinning(V, model.rig.weights, forward_kinematics(sk, pose));
    // Tip vertex sets: weight of the tip bone and its descendants.
    std::vector<int> verts;
    std::vector<std::string> tips = o.tip_bones;
    if (o.constrain_elbows_and_knees)
      for (const char* b : {"lowerarm01.L", "lowerarm01.R", "lowerleg01.L", "lowerleg01.R"}) tips.push_back(b);
    for (const auto& tip : tips) {
      int b = sk.find(tip);
      if (b < 0) continue;
      Eigen::VectorXd sel = Eigen::VectorXd::Zero(sk.bone_count());
      for (int k = 0; k < sk.bone_count(); ++k) {
        int p = k;
        while (p >= 0 && p != b) p = sk.parents[p];
        if (p == b) sel(k) = 1;
      }
      Eigen::VectorXd w = model.rig.weights * sel;
      std::vector<int> idx(w.size());
      std::iota(idx.begin(), idx.end(), 0);
      int k = std::min<int>(o.vertices_per_tip, idx.size());
      std::partial_sort(idx.begin(), idx.begin() + k, idx.end(), [&](int a, int b2) { return w(a) > w(b2); });
      for (int i = 0; i < k; ++i)
        if (w(idx[i]) > 0.5) verts.push_back(idx[i]);
    }
    pc.vertices.resize(verts.size());
    pc.targets.resize(verts.size(), 3);
    for (size_t i = 0; i < verts.size(); ++i) {
      pc.vertices(i) = verts[i];
      pc.targets.row(i) = posed.row(verts[i]);
    }
  }
  if (summary) {
    summary->pose_labels = npose;
    summary->kept_labels = nkeep;
    summary->tip_vertices = static_cast<int>(pc.vertices.size());
    summary->change_norm = z.norm();
  }
  if (pc.vertices.size() >= 3) return decoder.decode(model.encoding_of(xp), pc);
  return decoder.decode(model.encoding_of(xp));
}

}  // namespace bodymodel
