#include "assets/rig_carry.h"

#include <algorithm>
#include <map>
#include <string>

#include "core/error.h"

namespace bodymodel {

namespace {

// Output row i mixes source rows src(i, k) with weights w(i, k) (zero weights skipped).
SkinningRig mix_rows(const SkinningRig& rig, const Eigen::MatrixX3i& src, const Eigen::MatrixX3d& w,
                     const Eigen::MatrixX3d& rest, const char* what) {
  if (rig.method == SkinningMethod::animation_space)
    throw InputError(std::string(what) + ": an Animation Space rig cannot be carried (its coefficients embed "
                     "each vertex's rest position); carry an ssd, dqs or mwe rig");
  rig.validate(what);
  const int c = coefficients_per_influence(rig.method);
  const bool weights = rig.method != SkinningMethod::mwe;
  const Eigen::Index n = src.rows();
  std::vector<std::map<int, Eigen::VectorXd>> rows(n);
  size_t K = 1;
  for (Eigen::Index i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      if (w(i, k) == 0) continue;
      const int v = src(i, k);
      if (v < 0 || v >= rig.vertex_count())
        throw InputError(std::string(what) + ": row " + std::to_string(i) + " reads vertex " + std::to_string(v) +
                         " but the rig has " + std::to_string(rig.vertex_count()) + " vertices");
      for (int s = 0; s < rig.max_influences(); ++s) {
        const int b = rig.influences(v, s);
        if (b < 0) continue;
        auto it = rows[i].try_emplace(b, Eigen::VectorXd::Zero(c)).first;
        it->second += w(i, k) * rig.coefficients.row(v).segment(s * c, c).transpose();
      }
    }
    if (weights) {  // weights: no negative mix, rows sum to one
      double sum = 0;
      for (auto it = rows[i].begin(); it != rows[i].end();)
        if (it->second[0] <= 0) it = rows[i].erase(it);
        else sum += (it++)->second[0];
      if (sum > 0) {
        for (auto& [b, x] : rows[i]) x /= sum;
      } else {  // nothing positive left: the weights of the row's heaviest source vertex
        int k_best = 0;
        for (int k = 1; k < 3; ++k) if (w(i, k) > w(i, k_best)) k_best = k;
        const int v = src(i, k_best);
        for (int s = 0; s < rig.max_influences(); ++s)
          if (rig.influences(v, s) >= 0) rows[i][rig.influences(v, s)] = rig.coefficients.row(v).segment(s * c, c).transpose();
      }
    }
    K = std::max(K, rows[i].size());
  }
  SkinningRig out;
  out.method = rig.method;
  out.bone_count = rig.bone_count;
  out.rest = rest;
  out.influences = Eigen::MatrixXi::Constant(n, static_cast<Eigen::Index>(K), -1);
  out.coefficients = Eigen::MatrixXd::Zero(n, static_cast<Eigen::Index>(K) * c);
  for (Eigen::Index i = 0; i < n; ++i) {
    int s = 0;
    for (const auto& [b, x] : rows[i]) {
      out.influences(i, s) = b;
      out.coefficients.row(i).segment(s * c, c) = x.transpose();
      ++s;
    }
  }
  return out;
}

}  // namespace

SkinningRig carry_rig(const AssetBinding& binding, const SkinningRig& body_rig, const Eigen::MatrixX3d& asset_rest) {
  if (asset_rest.rows() != binding.vertex_count())
    throw InputError("carry_rig: " + std::to_string(asset_rest.rows()) + " rest positions for an asset of " +
                     std::to_string(binding.vertex_count()) + " vertices");
  return mix_rows(body_rig, binding.vertices, binding.weights, asset_rest, "carry_rig");
}

SkinningRig extend_rig_to_helpers(const SkinningRig& skin_rig, const HelperBinding& h, const Eigen::MatrixX3d& full_rest) {
  if (skin_rig.vertex_count() != h.body_vertex_count || full_rest.rows() != h.vertex_count)
    throw InputError("extend_rig_to_helpers: expected a rig of " + std::to_string(h.body_vertex_count) +
                     " skin vertices and " + std::to_string(h.vertex_count) + " rest positions");
  const Eigen::Index nb = h.body_vertex_count, nh = h.triangle.rows();
  Eigen::MatrixX3i src(nb + nh, 3);
  Eigen::MatrixX3d w(nb + nh, 3);
  for (Eigen::Index v = 0; v < nb; ++v) {
    src.row(v) << static_cast<int>(v), 0, 0;
    w.row(v) << 1, 0, 0;
  }
  src.bottomRows(nh) = h.triangle;
  w.bottomRows(nh) = h.bary;
  return mix_rows(skin_rig, src, w, full_rest, "extend_rig_to_helpers");
}

}  // namespace bodymodel
