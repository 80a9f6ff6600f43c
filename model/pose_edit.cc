#include "model/pose_edit.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/error.h"
#include "core/geometry.h"
#include "model/format.h"

namespace bodymodel {

double mean_vertex_error_after_rigid_fit(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B) {
  Eigen::MatrixX3d a = apply(fit_rigid_motion(A, B), A);
  return (a - B).rowwise().norm().mean();
}

double restore_volume(Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, double target_volume, double tolerance,
                      int max_steps) {
  double h_total = 0;
  if (!(target_volume > 0)) return 0;
  for (int step = 0; step < max_steps; ++step) {
    const double vol = signed_volume(V, F);
    if (!(vol > 0)) break;
    if (std::abs(vol - target_volume) <= tolerance * target_volume) break;
    const double area = face_areas(V, F).sum();
    if (!(area > 0)) break;
    const double h = (target_volume - vol) / area;
    const Eigen::MatrixX3d N = vertex_normals(V, F);
    if (!N.allFinite()) break;
    V += h * N;
    h_total += h;
  }
  return h_total;
}

Eigen::VectorXd torso_weight(const ModelRig& rig) {
  Eigen::VectorXd sel = Eigen::VectorXd::Zero(rig.bone_count());
  for (int b = 0; b < rig.bone_count(); ++b) {
    const std::string& n = rig.bone_names[b];
    if (n == "root" || n.rfind("spine", 0) == 0 || n.rfind("pelvis", 0) == 0) sel(b) = 1;
  }
  return rig.weights * sel;
}

namespace {
Eigen::MatrixX3d rows_of(const Eigen::MatrixX3d& A, const std::vector<int>& idx) {
  Eigen::MatrixX3d out(idx.size(), 3);
  for (size_t i = 0; i < idx.size(); ++i) out.row(i) = A.row(idx[i]);
  return out;
}
}  // namespace

TorsoOffset torso_offset(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B, const Eigen::VectorXd& torso_w) {
  TorsoOffset out;
  std::vector<int> idx;
  for (Eigen::Index v = 0; v < torso_w.size(); ++v)
    if (torso_w(v) >= 0.9) idx.push_back(static_cast<int>(v));
  if (idx.size() < 3) return out;
  const Eigen::MatrixX3d placed = apply(fit_rigid_motion(A, B), A);
  const Eigen::MatrixX3d a = rows_of(placed, idx), b = rows_of(B, idx);
  const RigidMotion m = fit_rigid_motion(a, b);
  const Eigen::RowVector3d c = a.colwise().mean();
  out.translation_mm = ((m.R * c.transpose() + m.t) - c.transpose()).norm();
  out.rotation_deg = Eigen::AngleAxisd(m.R).angle() * 180 / M_PI;
  out.mean_distance_mm = (a - b).rowwise().norm().mean();
  out.mean_distance_after_mm = (apply(m, a) - b).rowwise().norm().mean();
  return out;
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

Eigen::Matrix3d canonical_rotation(const ModelRig& rig, const Eigen::MatrixX3d& V) {
  Skeleton sk = rig.skeleton_for(V);
  int l = sk.find("upperleg01.L"), r = sk.find("upperleg01.R");
  if (l < 0 || r < 0) {
    l = sk.find("pelvis.L");
    r = sk.find("pelvis.R");
  }
  if (l < 0 || r < 0) return Eigen::Matrix3d::Identity();
  // Left–right axis from the hip joints (exactly along x in the symmetric rest skeleton), up
  // as close to +y as is orthogonal to it.
  Eigen::Vector3d x = (sk.heads.row(l) - sk.heads.row(r)).transpose();
  if (x.norm() < 1e-9) return Eigen::Matrix3d::Identity();
  x.normalize();
  Eigen::Vector3d y = Eigen::Vector3d::UnitY() - x.y() * x;
  if (y.norm() < 1e-6) return Eigen::Matrix3d::Identity();
  y.normalize();
  Eigen::Matrix3d B;  // columns: the body's x, y, z axes in world coordinates
  B.col(0) = x;
  B.col(1) = y;
  B.col(2) = x.cross(y);
  return B.transpose();  // maps the body's axes onto world x, y, z
}

PoseTransfer pose_transfer_from_examples(const SubModel& fm, const Eigen::VectorXd& target, int neighbours) {
  PoseTransfer out;
  const SemanticRegression& reg = fm.regression;
  const int N = static_cast<int>(fm.labels.rows());
  const int L = reg.label_count();
  out.pose_labels = Eigen::VectorXd::Zero(L);
  out.coefficient_change = Eigen::VectorXd::Zero(fm.component_count());
  if (N == 0 || fm.pca.coefficients.rows() != N || fm.labels.cols() != L) return out;
  std::vector<int> pose_cols, subject_cols;
  for (int l = 0; l < L; ++l) (reg.labels[l].name.rfind("pose:", 0) == 0 ? pose_cols : subject_cols).push_back(l);
  if (pose_cols.empty()) return out;
  // Each sample's subject: the samples with identical subject labels; its standard-pose sample
  // is the one with all joint angles (near) zero.
  auto pose_norm = [&](int i) {
    double s = 0;
    for (int l : pose_cols) s += std::isfinite(fm.labels(i, l)) ? fm.labels(i, l) * fm.labels(i, l) : 1e6;
    return std::sqrt(s);
  };
  auto same_subject = [&](int a, int b) {
    for (int l : subject_cols) {
      double u = fm.labels(a, l), v = fm.labels(b, l);
      if (std::isfinite(u) != std::isfinite(v) || (std::isfinite(u) && std::abs(u - v) > 1e-9 * (1 + std::abs(u))))
        return false;
    }
    return true;
  };
  std::vector<int> standard;
  for (int i = 0; i < N; ++i)
    if (pose_norm(i) < 1e-6) standard.push_back(i);
  struct Example {
    int sample, standard;
    double distance;
  };
  std::vector<Example> ex;
  for (int i = 0; i < N; ++i) {
    double pn = pose_norm(i);
    if (pn < 1e-6 || pn >= 1e3) continue;  // standard pose, or unknown joint angles
    int st = -1;
    for (int j : standard)
      if (same_subject(i, j)) {
        st = j;
        break;
      }
    if (st < 0) continue;
    double dist = 0;
    for (int l : pose_cols) dist += (fm.labels(i, l) - target(l)) * (fm.labels(i, l) - target(l));
    ex.push_back({i, st, std::sqrt(dist)});
  }
  if (ex.empty()) return out;
  const int k = std::min<int>(neighbours, ex.size());
  std::partial_sort(ex.begin(), ex.begin() + k, ex.end(),
                    [](const Example& a, const Example& b) { return a.distance < b.distance; });
  // Gaussian weights with a width set by the nearest example (at least 0.1 rad over all angles).
  const double sigma = std::max(0.1, 1.5 * ex[0].distance);
  double wsum = 0;
  for (int e = 0; e < k; ++e) {
    double w = std::exp(-0.5 * (ex[e].distance * ex[e].distance - ex[0].distance * ex[0].distance) / (sigma * sigma));
    out.coefficient_change += w * (fm.pca.coefficients.row(ex[e].sample) - fm.pca.coefficients.row(ex[e].standard)).transpose();
    for (int l : pose_cols) out.pose_labels(l) += w * fm.labels(ex[e].sample, l);
    wsum += w;
  }
  out.coefficient_change /= wsum;
  out.pose_labels /= wsum;
  out.examples = k;
  out.nearest_distance = ex[0].distance;
  return out;
}

PositionConstraints pose_morph_constraints(const BodyModel& model, RelativeRotationDecoder& decoder,
                                           const Eigen::MatrixX3d& V, const Pose& pose, const Encoding& unconstrained,
                                           const PoseMorphOptions& o, int* torso_anchors) {
  PositionConstraints pc;
  int anchors = 0;
  if (o.use_tip_constraints) {
    // Joint rotations are about world-aligned axes of the skeleton's rest frame (+y up, facing
    // +z, left–right along x): skin the body turned into that frame, then turn the targets back.
    const Eigen::Matrix3d G = o.canonical_frame ? canonical_rotation(model.rig, V) : Eigen::Matrix3d::Identity();
    const Eigen::MatrixX3d Vc = V * G.transpose();
    Skeleton sk = model.rig.skeleton_for(Vc);
    Eigen::MatrixX3d posed = linear_blend_skinning(Vc, model.rig.weights, forward_kinematics(sk, pose)) * G;
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
    if (o.constrain_every_bone) {
      // Per-region handling: the vertices each bone carries nearly alone (weight ≥ 0.9), a
      // few per bone, placed by skinning like the tips.
      std::vector<char> used(V.rows(), 0);
      for (int v : verts) used[v] = 1;
      Eigen::SparseMatrix<double, Eigen::ColMajor> W = model.rig.weights;  // #V by #B
      for (int b = 0; b < W.outerSize(); ++b) {
        std::vector<std::pair<double, int>> cand;
        for (Eigen::SparseMatrix<double, Eigen::ColMajor>::InnerIterator it(W, b); it; ++it)
          if (it.value() >= 0.9 && !used[it.row()]) cand.emplace_back(it.value(), static_cast<int>(it.row()));
        if (cand.empty()) continue;
        // Evenly spread over the bone's region (every n-th of them in index order).
        std::sort(cand.begin(), cand.end(), [](auto& a, auto& c) { return a.second < c.second; });
        const int step = std::max<int>(1, static_cast<int>(cand.size()) / o.vertices_per_bone);
        for (size_t i = 0; i < cand.size(); i += step) {
          verts.push_back(cand[i].second);
          used[cand[i].second] = 1;
        }
      }
    }
    std::vector<Eigen::RowVector3d> targets;
    for (int v : verts) targets.push_back(posed.row(v));
    std::vector<double> weights(verts.size(), DecoderOptions{}.constraint_weight);
    if (o.anchor_torso && o.torso_anchors > 0) {
      // The torso of the unconstrained pose-changed body, placed rigidly on the skinned torso.
      const Eigen::VectorXd tw = torso_weight(model.rig);
      std::vector<char> used(V.rows(), 0);
      for (int v : verts) used[v] = 1;
      std::vector<int> torso;
      for (Eigen::Index v = 0; v < tw.size(); ++v)
        if (tw(v) >= 0.9) torso.push_back(static_cast<int>(v));
      if (torso.size() >= 3) {
        const Eigen::MatrixX3d D0 = decoder.decode(unconstrained);
        Eigen::MatrixX3d a(torso.size(), 3), b(torso.size(), 3);
        for (size_t i = 0; i < torso.size(); ++i) {
          a.row(i) = D0.row(torso[i]);
          b.row(i) = posed.row(torso[i]);
        }
        const Eigen::MatrixX3d placed = apply(fit_rigid_motion(a, b), a);
        const size_t step = std::max<size_t>(1, torso.size() / o.torso_anchors);
        for (size_t i = 0; i < torso.size(); i += step) {
          if (used[torso[i]]) continue;
          verts.push_back(torso[i]);
          targets.push_back(placed.row(i));
          weights.push_back(o.torso_anchor_weight);
          anchors += 1;
        }
      }
    }
    pc.vertices.resize(verts.size());
    pc.targets.resize(verts.size(), 3);
    pc.weights.resize(verts.size());
    for (size_t i = 0; i < verts.size(); ++i) {
      pc.vertices(i) = verts[i];
      pc.targets.row(i) = targets[i];
      pc.weights(i) = weights[i];
    }
  }
  if (torso_anchors) *torso_anchors = anchors;
  return pc;
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

  // 1. Example-based transfer: pose changes of training subjects in poses near the target.
  PoseTransfer transfer;
  transfer.coefficient_change = Eigen::VectorXd::Zero(fm.component_count());
  transfer.pose_labels = Eigen::VectorXd::Zero(reg.label_count());
  if (o.transfer_neighbours > 0) transfer = pose_transfer_from_examples(fm, target, o.transfer_neighbours);
  Eigen::VectorXd c1 = c0 + transfer.coefficient_change;
  Eigen::VectorXd pred1 = reg.predict(c1);

  // 2. Linear correction (eq. 11): the joint angles the transfer missed, the other labels back
  //    to their values before the transfer.
  std::vector<int> cols;
  std::vector<double> delta;
  int npose = 0, nkeep = 0;
  for (int l = 0; l < reg.label_count(); ++l) {
    const std::string& n = reg.labels[l].name;
    if (n.rfind("pose:", 0) == 0) {
      cols.push_back(l);
      delta.push_back(transfer.examples > 0 ? target(l) - transfer.pose_labels(l) : target(l) - pred(l));
      ++npose;
    } else if (o.keep_labels.empty() ||
               std::find(o.keep_labels.begin(), o.keep_labels.end(), n) != o.keep_labels.end()) {
      cols.push_back(l);
      delta.push_back(pred(l) - pred1(l));
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
  Eigen::VectorXd z = transfer.coefficient_change + constrained_change(S, d, co);
  Eigen::VectorXd xp = x + fm.pca.basis * z;

  int anchors = 0;
  const PositionConstraints pc = pose_morph_constraints(model, decoder, V, pose, model.encoding_of(xp), o, &anchors);
  Eigen::MatrixX3d out = pc.vertices.size() >= 3 ? decoder.decode(model.encoding_of(xp), pc)
                                                  : decoder.decode(model.encoding_of(xp));
  const Eigen::MatrixX3i& F = model.tmpl->faces();
  const double v0 = signed_volume(V, F);
  const double before = v0 > 0 ? signed_volume(out, F) / v0 : 1;
  double offset = 0;
  if (o.preserve_volume && v0 > 0) {
    const double tol = std::clamp(o.volume_tolerance, 0.0, 0.5);
    const double target = std::clamp(before, 1 - tol, 1 + tol) * v0;
    if (target != before * v0) offset = restore_volume(out, F, target);
  }
  if (summary) {
    summary->pose_labels = npose;
    summary->kept_labels = nkeep;
    summary->tip_vertices = static_cast<int>(pc.vertices.size()) - anchors;
    summary->torso_anchors = anchors;
    summary->change_norm = z.norm();
    summary->transfer_examples = transfer.examples;
    summary->transfer_pose_distance = transfer.nearest_distance;
    summary->volume_ratio_before = before;
    summary->volume_ratio = v0 > 0 ? signed_volume(out, F) / v0 : 1;
    summary->volume_offset_mm = offset;
  }
  return out;
}

Eigen::MatrixX3d blend_pose_morphs(const BodyModel& model, RelativeRotationDecoder& decoder,
                                   const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B,
                                   double t, const Pose& pose, const PoseMorphOptions& o) {
  const Encoding e = interpolate(model.encode(A, "pose morph A"), model.encode(B, "pose morph B"), t);
  const PositionConstraints pc = pose_morph_constraints(model, decoder, V, pose, e, o, nullptr);
  Eigen::MatrixX3d out = pc.vertices.size() >= 3 ? decoder.decode(e, pc) : decoder.decode(e);
  const Eigen::MatrixX3i& F = model.tmpl->faces();
  const double v0 = signed_volume(V, F);
  if (o.preserve_volume && v0 > 0) {
    const double before = signed_volume(out, F) / v0;
    const double tol = std::clamp(o.volume_tolerance, 0.0, 0.5);
    const double target = std::clamp(before, 1 - tol, 1 + tol) * v0;
    if (target != before * v0) restore_volume(out, F, target);
  }
  return out;
}

}  // namespace bodymodel
