#include "assets/dress.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <map>

#include "core/error.h"
#include "registration/correspondence.h"

namespace bodymodel {

std::string asset_kind(const Asset& a) {
  static const std::vector<std::string> kinds = {"clothes", "hair", "eyebrows", "eyelashes",
                                                 "eyes", "teeth", "proxymeshes"};
  for (std::filesystem::path p = a.file.parent_path(); !p.empty() && p != p.parent_path(); p = p.parent_path())
    for (const std::string& k : kinds)
      if (p.filename() == k) return k;
  return "";
}

Eigen::Vector3d asset_colour(const Asset& a) {
  if (a.material && a.material->diffuse_color.minCoeff() < 0.99) return a.material->diffuse_color;
  // Our palette: a muted blue for garments, dark brown shoes and hair, near-black brows and lashes.
  static const std::map<std::string, Eigen::Vector3d> by_kind = {
      {"clothes", {0.25, 0.33, 0.45}}, {"hair", {0.23, 0.15, 0.09}},   {"eyebrows", {0.12, 0.09, 0.07}},
      {"eyelashes", {0.05, 0.05, 0.05}}, {"eyes", {0.92, 0.92, 0.90}}, {"teeth", {0.93, 0.91, 0.84}}};
  if (a.file.stem().string().rfind("shoes", 0) == 0) return {0.16, 0.12, 0.10};
  const auto it = by_kind.find(asset_kind(a));
  return it == by_kind.end() ? Eigen::Vector3d(0.6, 0.6, 0.6) : it->second;
}

std::filesystem::path find_asset(const std::filesystem::path& root, const std::string& name) {
  std::string known;
  for (const auto& f : find_asset_files(root)) {
    if (f.stem() == name) return f;
    known += " " + f.stem().string();
  }
  throw InputError("unknown asset '" + name + "' under '" + root.string() + "' (known:" + known + ")");
}

namespace {

// The body's visible faces over the vertices they use (renumbered), with those vertices' weights.
DressedPart body_part(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const SkinWeights& W,
                      const std::vector<char>& hidden, const Eigen::Vector3d& colour) {
  DressedPart p;
  p.name = p.kind = "body";
  p.colour = colour;
  const Eigen::MatrixX3i vis = visible_faces(F, hidden);
  std::vector<int> map(V.rows(), -1);
  int n = 0;
  for (Eigen::Index i = 0; i < vis.size(); ++i)
    if (map[vis.data()[i]] < 0) map[vis.data()[i]] = n++;
  p.V.resize(n, 3);
  for (Eigen::Index v = 0; v < V.rows(); ++v)
    if (map[v] >= 0) p.V.row(map[v]) = V.row(v);
  p.F.resize(vis.rows(), 3);
  for (Eigen::Index f = 0; f < vis.rows(); ++f)
    for (int k = 0; k < 3; ++k) p.F(f, k) = map[vis(f, k)];
  std::vector<Eigen::Triplet<double>> t;
  for (Eigen::Index v = 0; v < V.rows(); ++v)
    if (map[v] >= 0)
      for (SkinWeights::InnerIterator it(W, v); it; ++it) t.emplace_back(map[v], it.col(), it.value());
  p.weights.resize(n, W.cols());
  p.weights.setFromTriplets(t.begin(), t.end());
  p.roughness = 0.6;
  return p;
}

}  // namespace

std::vector<DressedPart> dress_body(const Eigen::MatrixX3d& rest_full, const Eigen::MatrixX3i& body_F,
                                    const SkinWeights& W, const BoneTransforms* pose,
                                    const std::vector<Asset>& outfit, const DressOptions& options) {
  if (W.rows() != rest_full.rows())
    throw InputError("dress_body: " + std::to_string(W.rows()) + " weight rows for " +
                     std::to_string(rest_full.rows()) + " body vertices");
  std::vector<const AssetBinding*> bindings;
  for (const Asset& a : outfit) {
    if (a.binding.proxy)
      throw InputError("'" + a.file.string() + "' is a proxy (a replacement body), not something to wear");
    bindings.push_back(&a.binding);
  }
  const std::vector<char> hidden = hidden_body_vertices(bindings, static_cast<int>(rest_full.rows()));
  const Eigen::MatrixX3d posed = pose ? linear_blend_skinning(rest_full, W, *pose) : rest_full;
  std::vector<DressedPart> parts = {body_part(posed, body_F, W, hidden, options.skin_colour)};
  for (const Asset& a : outfit) {
    DressedPart p;
    p.name = a.file.stem().string();
    p.kind = asset_kind(a);
    p.colour = asset_colour(a);
    if (a.material) p.roughness = a.material->roughness();
    p.F = a.faces;
    p.V = fit_asset(a.binding, rest_full);
    p.weights = asset_skin_weights(a.binding, W);
    if (pose) p.V = linear_blend_skinning(p.V, p.weights, *pose);
    p.garment = p.kind == "clothes";
    if (p.garment) {
      if (options.fix_penetration) {
        PushOutResult r = push_garment_out(p.V, p.F, posed, body_F, hidden, options.push, options.depth_mm);
        p.V = std::move(r.V);
        p.before = r.before;
        p.after = r.after;
      } else {
        p.before = p.after = penetration_of(body_distance(p.V, posed, body_F, hidden), options.depth_mm);
      }
    }
    parts.push_back(std::move(p));
  }
  return parts;
}

namespace {

// Weights of all 19158 rows: the skin's, then each helper's skin triangle's mixed by the tie's
// barycentric coordinates (non-negative: closest points lie in their triangle).
SkinWeights weights_with_helpers(const SkinWeights& skin_W, const HelperBinding& tie) {
  std::vector<Eigen::Triplet<double>> t;
  for (int v = 0; v < skin_W.outerSize(); ++v)
    for (SkinWeights::InnerIterator it(skin_W, v); it; ++it) t.emplace_back(v, it.col(), it.value());
  for (Eigen::Index h = 0; h < tie.triangle.rows(); ++h)
    for (int k = 0; k < 3; ++k)
      for (SkinWeights::InnerIterator it(skin_W, tie.triangle(h, k)); it; ++it)
        t.emplace_back(tie.body_vertex_count + h, it.col(), tie.bary(h, k) * it.value());
  SkinWeights W(tie.vertex_count, skin_W.cols());
  W.setFromTriplets(t.begin(), t.end());  // duplicates are summed
  return W;
}

}  // namespace

SkinWeights skin_weights_at(const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& body_V, const Eigen::MatrixX3i& body_F,
                            const SkinWeights& W, Eigen::VectorXd* distance) {
  const std::vector<SurfaceLocation> loc = locate_on_surface(P, body_V, body_F);
  std::vector<Eigen::Triplet<double>> t;
  if (distance) distance->resize(P.rows());
  for (Eigen::Index i = 0; i < P.rows(); ++i) {
    for (int k = 0; k < 3; ++k)
      for (SkinWeights::InnerIterator it(W, body_F(loc[i].face, k)); it; ++it)
        t.emplace_back(i, it.col(), loc[i].bary[k] * it.value());
    if (distance) (*distance)[i] = loc[i].distance;
  }
  SkinWeights out(P.rows(), W.cols());
  out.setFromTriplets(t.begin(), t.end());
  return out;
}

DressedSkinBody dress_skin_body(const Eigen::MatrixX3d& skin_rest, const Eigen::MatrixX3i& skin_F,
                                const SkinWeights& skin_W, const HelperRegressor& regressor,
                                const HelperBinding& tie, const std::vector<Asset>& outfit,
                                const DressOptions& options) {
  if (skin_rest.rows() != regressor.body_vertex_count || skin_rest.rows() != tie.body_vertex_count ||
      skin_W.rows() != skin_rest.rows())
    throw InputError(fmt::format("dress_skin_body: a body of {} vertices and {} weight rows; the helpers need {}",
                                 skin_rest.rows(), skin_W.rows(), regressor.body_vertex_count));
  DressedSkinBody d;
  d.full_rest = complete_with_helpers(regressor, skin_rest);
  d.full_weights = weights_with_helpers(skin_W, tie);
  d.parts = dress_body(d.full_rest, skin_F, d.full_weights, nullptr, outfit, options);
  std::vector<const AssetBinding*> bindings;
  for (const Asset& a : outfit) bindings.push_back(&a.binding);
  d.full_hidden = hidden_body_vertices(bindings, static_cast<int>(d.full_rest.rows()));
  d.hidden = d.full_hidden;
  d.hidden.resize(skin_rest.rows());
  if (options.skin_weights_near >= 0)
    for (DressedPart& p : d.parts) {
      if (!p.garment) continue;
      Eigen::VectorXd dist;
      const SkinWeights near = skin_weights_at(p.V, skin_rest, skin_F, skin_W, &dist);
      const double span = std::max(1e-9, options.skin_weights_far - options.skin_weights_near);
      const Eigen::VectorXd a = ((dist.array() - options.skin_weights_near) / span).min(1.0).max(0.0);
      p.weights = SkinWeights((Eigen::VectorXd(1.0 - a.array())).asDiagonal() * near + a.asDiagonal() * p.weights);
    }
  return d;
}

int ClipPenetration::frames_over(double limit) const {
  int n = 0;
  for (Eigen::Index f = 0; f < fraction.rows(); ++f) n += fraction.cols() > 0 && fraction.row(f).maxCoeff() > limit;
  return n;
}

namespace {

// The part's rest vertices with the frame's bind-space corrections of that part added.
Eigen::MatrixX3d corrected_rest(const DressedPart& p, int part, const ClipCorrections* c, size_t frame) {
  Eigen::MatrixX3d V = p.V;
  if (!c || frame >= c->frames.size()) return V;
  for (const GarmentCorrection& g : c->frames[frame])
    if (g.part == part)
      for (size_t i = 0; i < g.vertex.size(); ++i) V.row(g.vertex[i]) += g.delta.row(static_cast<Eigen::Index>(i));
  return V;
}

// Blended linear part Σ_j w_j R_j of row `i`'s skinning transform.
Eigen::Matrix3d blended_linear(const SkinWeights& W, int i, const BoneTransforms& M) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  for (SkinWeights::InnerIterator it(W, i); it; ++it) A += it.value() * M[it.col()].linear();
  return A;
}

}  // namespace

ClipPenetration clip_penetration(const std::vector<DressedPart>& parts, const Eigen::MatrixX3d& skin_rest,
                                 const Eigen::MatrixX3i& skin_F, const SkinWeights& skin_W,
                                 const std::vector<char>& hidden, const std::vector<BoneTransforms>& frames,
                                 double depth_mm, const ClipCorrections* corrections) {
  ClipPenetration c;
  std::vector<int> garments;
  for (size_t k = 0; k < parts.size(); ++k)
    if (parts[k].garment) garments.push_back(static_cast<int>(k)), c.garments.push_back(parts[k].name);
  const Eigen::Index F = static_cast<Eigen::Index>(frames.size()), G = static_cast<Eigen::Index>(garments.size());
  c.fraction.setZero(F, G);
  c.max_depth_mm.setZero(F, G);
  for (Eigen::Index f = 0; f < F; ++f) {
    const Eigen::MatrixX3d body = linear_blend_skinning(skin_rest, skin_W, frames[f]);
    for (Eigen::Index g = 0; g < G; ++g) {
      const DressedPart& p = parts[garments[g]];
      const Eigen::MatrixX3d X =
          linear_blend_skinning(corrected_rest(p, garments[g], corrections, f), p.weights, frames[f]);
      const Penetration pen = penetration_of(body_distance(X, body, skin_F, hidden), depth_mm);
      c.fraction(f, g) = pen.fraction;
      c.max_depth_mm(f, g) = pen.max_depth;
    }
  }
  return c;
}

ClipCorrections clip_corrections(const std::vector<DressedPart>& parts, const Eigen::MatrixX3d& skin_rest,
                                 const Eigen::MatrixX3i& skin_F, const SkinWeights& skin_W,
                                 const std::vector<char>& hidden, const std::vector<BoneTransforms>& frames,
                                 const ClipCorrectionOptions& options) {
  ClipCorrections c;
  ClipPenetration& u = c.uncorrected;
  std::vector<int> garments;
  for (size_t k = 0; k < parts.size(); ++k)
    if (parts[k].garment) garments.push_back(static_cast<int>(k)), u.garments.push_back(parts[k].name);
  const Eigen::Index F = static_cast<Eigen::Index>(frames.size()), G = static_cast<Eigen::Index>(garments.size());
  u.fraction.setZero(F, G);
  u.max_depth_mm.setZero(F, G);
  c.frames.resize(frames.size());
  for (Eigen::Index f = 0; f < F; ++f) {
    const Eigen::MatrixX3d body = linear_blend_skinning(skin_rest, skin_W, frames[f]);
    for (Eigen::Index g = 0; g < G; ++g) {
      const DressedPart& p = parts[garments[g]];
      const Eigen::MatrixX3d X = linear_blend_skinning(p.V, p.weights, frames[f]);
      const Penetration pen = penetration_of(body_distance(X, body, skin_F, hidden), options.depth_mm);
      u.fraction(f, g) = pen.fraction;
      u.max_depth_mm(f, g) = pen.max_depth;
      if (pen.penetrating == 0) continue;
      const PushOutResult r = push_garment_out(X, p.F, body, skin_F, hidden, options.push, options.depth_mm);
      GarmentCorrection gc;
      gc.part = garments[g];
      std::vector<Eigen::RowVector3d> d;
      for (Eigen::Index i = 0; i < X.rows(); ++i) {
        const Eigen::Vector3d posed = (r.V.row(i) - X.row(i)).transpose();
        if (posed.norm() < options.min_move_mm) continue;
        const Eigen::Matrix3d A = blended_linear(p.weights, static_cast<int>(i), frames[f]);
        if (std::abs(A.determinant()) < 0.1) continue;
        gc.vertex.push_back(static_cast<int>(i));
        d.push_back(A.partialPivLu().solve(posed).transpose());
      }
      if (gc.vertex.empty()) continue;
      gc.delta.resize(static_cast<Eigen::Index>(d.size()), 3);
      for (size_t i = 0; i < d.size(); ++i) gc.delta.row(static_cast<Eigen::Index>(i)) = d[i];
      ++c.garment_frames;
      c.vertices += static_cast<long long>(d.size());
      c.frames[f].push_back(std::move(gc));
    }
  }
  return c;
}

BoneTransforms pose_between_keys(const Skeleton& skeleton, const BoneTransforms& a, const BoneTransforms& b, double s) {
  const int B = skeleton.bone_count();
  if (static_cast<int>(a.size()) != B || static_cast<int>(b.size()) != B)
    throw InputError(fmt::format("pose_between_keys: poses of {} and {} bones for a skeleton of {}", a.size(), b.size(), B));
  BoneTransforms out(static_cast<size_t>(B));
  std::vector<Eigen::Matrix3d> Q(static_cast<size_t>(B));
  std::vector<Eigen::Vector3d> at(static_cast<size_t>(B));   // posed joint heads
  for (int j = 0; j < B; ++j) {
    const int p = skeleton.parents[static_cast<size_t>(j)];
    const Eigen::Vector3d h = skeleton.heads.row(j).transpose();
    auto local = [&](const BoneTransforms& M, Eigen::Quaterniond& r, Eigen::Vector3d& t) {
      const Eigen::Matrix3d Qp = p < 0 ? Eigen::Matrix3d::Identity().eval() : Eigen::Matrix3d(M[p].linear());
      const Eigen::Vector3d hp = p < 0 ? Eigen::Vector3d::Zero() : Eigen::Vector3d(M[p] * skeleton.heads.row(p).transpose());
      r = Eigen::Quaterniond(Qp.transpose() * M[j].linear());
      t = Qp.transpose() * (M[j] * h - hp);
    };
    Eigen::Quaterniond ra, rb;
    Eigen::Vector3d ta, tb;
    local(a, ra, ta);
    local(b, rb, tb);
    const Eigen::Matrix3d R = ra.slerp(s, rb).toRotationMatrix();
    const Eigen::Vector3d t = (1 - s) * ta + s * tb;
    Q[j] = p < 0 ? R : Q[p] * R;
    at[j] = p < 0 ? t : at[p] + Q[p] * t;
    out[j].linear() = Q[j];
    out[j].translation() = at[j] - Q[j] * h;
  }
  return out;
}

ClipCorrections corrections_between_keys(const ClipCorrections& c, double s) {
  ClipCorrections out;
  if (c.frames.size() < 2) return out;
  out.frames.resize(c.frames.size() - 1);
  for (size_t f = 0; f + 1 < c.frames.size(); ++f)
    for (const auto& [key, w] : {std::pair<size_t, double>{f, 1 - s}, {f + 1, s}})
      for (GarmentCorrection g : c.frames[key]) {   // corrected_rest adds every entry of a part
        g.delta *= w;
        out.frames[f].push_back(std::move(g));
      }
  return out;
}

BoneTransforms pose_at(const Skeleton& skeleton, const std::vector<BoneTransforms>& frames, double t) {
  if (frames.empty()) throw InputError("pose_at: a clip without frames");
  if (frames.size() == 1 || t <= 0) return frames.front();
  const size_t f = std::min(static_cast<size_t>(std::floor(t)), frames.size() - 2);
  return pose_between_keys(skeleton, frames[f], frames[f + 1], std::min(1.0, t - static_cast<double>(f)));
}

namespace {

// What a player blends at fraction s from sample a to sample b (the weights channel is LINEAR).
std::vector<GarmentCorrection> blend_samples(const std::vector<GarmentCorrection>& a,
                                             const std::vector<GarmentCorrection>& b, double s) {
  std::vector<GarmentCorrection> out;
  for (const auto& [list, w] : {std::pair<const std::vector<GarmentCorrection>*, double>{&a, 1 - s}, {&b, s}})
    for (GarmentCorrection g : *list) {   // corrected_rest adds every entry of a part
      g.delta *= w;
      out.push_back(std::move(g));
    }
  return out;
}

}  // namespace

SampledCorrections refine_between_keys(const std::vector<DressedPart>& parts, const Eigen::MatrixX3d& skin_rest,
                                       const Eigen::MatrixX3i& skin_F, const SkinWeights& skin_W,
                                       const std::vector<char>& hidden, const Skeleton& skeleton,
                                       const std::vector<BoneTransforms>& frames, const ClipCorrections& at_keys,
                                       const RefineOptions& options) {
  if (at_keys.frames.size() != frames.size())
    throw InputError(fmt::format("refine_between_keys: corrections for {} keys of a clip of {}", at_keys.frames.size(),
                                 frames.size()));
  std::map<double, std::vector<GarmentCorrection>> samples;    // by time; dyadic times are exact
  for (size_t f = 0; f < frames.size(); ++f) samples[static_cast<double>(f)] = at_keys.frames[f];
  std::map<double, std::pair<Eigen::RowVectorXd, Eigen::RowVectorXd>> mid;   // by an interval's start
  std::vector<std::pair<double, double>> pending;
  for (size_t f = 0; f + 1 < frames.size(); ++f) pending.emplace_back(f, f + 1.0);
  SampledCorrections out;
  for (int round = 0; !pending.empty(); ++round) {
    std::vector<BoneTransforms> poses;
    ClipCorrections blended;
    for (const auto& [a, b] : pending) {
      poses.push_back(pose_at(skeleton, frames, 0.5 * (a + b)));
      blended.frames.push_back(blend_samples(samples[a], samples[b], 0.5));
    }
    const ClipPenetration p = clip_penetration(parts, skin_rest, skin_F, skin_W, hidden, poses,
                                               options.correction.depth_mm, &blended);
    out.between.garments = p.garments;
    if (round == 0) out.between_keys = p;
    std::vector<size_t> over;
    for (size_t i = 0; i < pending.size(); ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      mid[pending[i].first] = {p.fraction.row(r), p.max_depth_mm.row(r)};
      if (round < options.max_halvings && p.fraction.cols() > 0 && p.fraction.row(r).maxCoeff() > options.limit)
        over.push_back(i);
    }
    std::vector<BoneTransforms> at;
    for (size_t i : over) at.push_back(poses[i]);
    const ClipCorrections c = clip_corrections(parts, skin_rest, skin_F, skin_W, hidden, at, options.correction);
    std::vector<std::pair<double, double>> next;
    for (size_t k = 0; k < over.size(); ++k) {
      const auto [a, b] = pending[over[k]];
      samples[0.5 * (a + b)] = c.frames[k];
      ++out.added;
      next.emplace_back(a, 0.5 * (a + b));
      next.emplace_back(0.5 * (a + b), b);
    }
    pending = std::move(next);
  }
  const auto G = static_cast<Eigen::Index>(out.between.garments.size());
  out.between.fraction.setZero(static_cast<Eigen::Index>(mid.size()), G);
  out.between.max_depth_mm.setZero(static_cast<Eigen::Index>(mid.size()), G);
  out.corrections.uncorrected = at_keys.uncorrected;
  for (auto& [t, c] : samples) {
    if (const auto m = mid.find(t); m != mid.end()) {
      const auto r = static_cast<Eigen::Index>(out.times.size());
      out.between.fraction.row(r) = m->second.first;
      out.between.max_depth_mm.row(r) = m->second.second;
    }
    out.times.push_back(t);
    for (const GarmentCorrection& g : c) ++out.corrections.garment_frames, out.corrections.vertices += g.delta.rows();
    out.corrections.frames.push_back(std::move(c));
  }
  return out;
}

}  // namespace bodymodel
