#include "registration/proportions.h"

#include <algorithm>
#include <cmath>
#include <map>

namespace bodymodel {

const std::vector<ProportionSegment>& default_proportion_segments() {
  static const std::vector<ProportionSegment> segments = [] {
    std::vector<ProportionSegment> s;
    auto side = [](const char* b, const char* sd) { return std::string(b) + sd; };
    for (const char* sd : {".L", ".R"}) {
      const std::string l = std::string(sd) == ".L" ? "l_" : "r_";
      s.push_back({"upperarm" + std::string(sd), {side("upperarm01", sd), side("upperarm02", sd)},
                   false, {{l + "shoulder", l + "elbow"}}});
      s.push_back({"lowerarm" + std::string(sd), {side("lowerarm01", sd), side("lowerarm02", sd)},
                   false, {{l + "elbow", l + "wrist"}}});
      s.push_back({"upperleg" + std::string(sd), {side("upperleg01", sd), side("upperleg02", sd)},
                   false, {{l + "hip", l + "knee"}}});
      s.push_back({"lowerleg" + std::string(sd), {side("lowerleg01", sd), side("lowerleg02", sd)},
                   false, {{l + "knee", l + "ankle"}}});
      s.push_back({"foot" + std::string(sd), {side("foot", sd)}, true, {{l + "heel", l + "toe"}}});
    }
    // Neck and head scale together (neck length and head size): the head of a heavy subject
    // is not larger than an average one's, and a neck of the wrong length makes the pose fit
    // zigzag neck and head to reach the chin and the top of the head.
    s.push_back({"head", {"neck01"}, true, {{"head_top", "chin"}, {"neck_back", "head_top"}}});
    s.push_back({"torso", {"spine05", "spine04", "spine03", "spine02", "spine01"}, false,
                 {{"navel", "sternum"}}});
    s.push_back({"hips", {"pelvis.L", "pelvis.R"}, false, {{"l_hip", "r_hip"}}});
    s.push_back({"shoulders", {"clavicle.L", "clavicle.R"}, false, {{"l_shoulder", "r_shoulder"}}});
    return s;
  }();
  return segments;
}

Proportions estimate_proportions(const Eigen::MatrixX3d& V, const std::vector<Landmark>& landmarks,
                                 const ProportionOptions& o) {
  const auto& segments = o.segments.empty() ? default_proportion_segments() : o.segments;
  Proportions p;
  if (landmarks.size() < 3) return p;
  std::map<std::string, const Landmark*> by_name;
  for (const Landmark& l : landmarks) by_name[l.name] = &l;
  // Segment lengths (scan, template); the global scale is the ratio of their sums (the
  // similarity transform of all landmarks underestimates it in a posed scan).
  std::vector<double> scan_len, tpl_len;
  std::vector<std::string> names;
  for (const auto& seg : segments) {
    double a_len = 0, b_len = 0;
    for (const auto& [a, b] : seg.landmark_pairs) {
      auto ia = by_name.find(a), ib = by_name.find(b);
      if (ia == by_name.end() || ib == by_name.end()) continue;
      a_len += (ia->second->target - ib->second->target).norm();
      b_len += (V.row(ia->second->vertex) - V.row(ib->second->vertex)).norm();
    }
    if (!(b_len > 0) || !(a_len > 0)) continue;
    names.push_back(seg.name);
    scan_len.push_back(a_len);
    tpl_len.push_back(b_len);
  }
  double sa = 0, sb = 0;
  for (size_t k = 0; k < names.size(); ++k) sa += scan_len[k], sb += tpl_len[k];
  if (!(sb > 0) || !std::isfinite(sa / sb)) return p;
  p.global_scale = sa / sb;
  for (size_t k = 0; k < names.size(); ++k) {
    p.segment.push_back(names[k]);
    p.ratio.push_back(
        std::clamp(scan_len[k] / (p.global_scale * tpl_len[k]), o.min_ratio, o.max_ratio));
  }
  return p;
}

void apply_proportions(const Eigen::MatrixX3d& V, const Skeleton& sk, const SkinWeights& W,
                       const Proportions& p, const ProportionOptions& o, Eigen::MatrixX3d* V_out,
                       Skeleton* sk_out) {
  const auto& segments = o.segments.empty() ? default_proportion_segments() : o.segments;
  const int nb = sk.bone_count();
  std::vector<double> axial(nb, 1.0), iso(nb, 0.0);  // iso > 0: isotropic root with that scale
  for (size_t k = 0; k < p.segment.size(); ++k) {
    auto it = std::find_if(segments.begin(), segments.end(),
                           [&](const ProportionSegment& s) { return s.name == p.segment[k]; });
    if (it == segments.end()) continue;
    for (size_t j = 0; j < it->bones.size(); ++j) {
      const int b = sk.find(it->bones[j]);
      if (b < 0) continue;
      if (it->isotropic) {
        if (j == 0) iso[b] = p.ratio[k];
      } else {
        axial[b] = p.ratio[k];
      }
    }
  }
  // Rest stretch of every bone: x ↦ h'_b + S_b (x − h_b), parents first.
  std::vector<Eigen::Matrix3d> S(nb);
  std::vector<Eigen::Vector3d> h(nb);
  std::vector<char> inherit(nb, 0);
  Skeleton out = sk;
  for (int b = 0; b < nb; ++b) {
    const int pa = sk.parents[b];
    const Eigen::Vector3d hb = sk.heads.row(b).transpose();
    if (pa < 0) {
      h[b] = hb;
    } else {
      h[b] = h[pa] + S[pa] * (hb - sk.heads.row(pa).transpose());
    }
    if (pa >= 0 && inherit[pa]) {
      S[b] = S[pa];
      inherit[b] = 1;
    } else if (iso[b] > 0) {
      S[b] = iso[b] * Eigen::Matrix3d::Identity();
      inherit[b] = 1;
    } else {
      const Eigen::Vector3d d = (sk.tails.row(b) - sk.heads.row(b)).transpose();
      const Eigen::Vector3d a = d.norm() > 1e-12 ? Eigen::Vector3d(d.normalized()) : Eigen::Vector3d::Zero();
      S[b] = Eigen::Matrix3d::Identity() + (axial[b] - 1.0) * a * a.transpose();
    }
    out.heads.row(b) = h[b].transpose();
    out.tails.row(b) = (h[b] + S[b] * (sk.tails.row(b).transpose() - hb)).transpose();
  }
  Eigen::MatrixX3d Vo = Eigen::MatrixX3d::Zero(V.rows(), 3);
  for (int i = 0; i < W.outerSize(); ++i) {
    double wsum = 0;
    Eigen::Vector3d acc = Eigen::Vector3d::Zero();
    const Eigen::Vector3d x = V.row(i).transpose();
    for (SkinWeights::InnerIterator it(W, i); it; ++it) {
      const int b = int(it.col());
      acc += it.value() * (h[b] + S[b] * (x - sk.heads.row(b).transpose()));
      wsum += it.value();
    }
    Vo.row(i) = (wsum > 0 ? Eigen::Vector3d(acc / wsum) : x).transpose();
  }
  *V_out = Vo;
  *sk_out = out;
}

}  // namespace bodymodel
