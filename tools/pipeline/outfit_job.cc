#include "tools/pipeline/outfit_job.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "assets/lod.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/makehuman.h"
#include "skinning/gltf_export.h"
#include "tools/pipeline/animate_job.h"

namespace bodymodel {

namespace fs = std::filesystem;

OutfitKit load_outfit_kit(const std::string& outfits, const fs::path& makehuman_dir, bool fit_helpers,
                          const HelperRegressorOptions& helper_options) {
  OutfitKit kit;
  kit.spec = outfits == "default" ? default_outfits() : parse_outfits(read_text_file(outfits), outfits);
  const fs::path root = makehuman_dir / "assets";
  for (const auto& [entry, name] : each_outfit_asset(kit.spec)) {
    if (kit.assets.count(name)) continue;
    fs::path file;
    try {
      file = find_asset(root, name);
    } catch (const InputError& e) {
      throw InputError(fmt::format("'{}': {}: {}", kit.spec.source, entry, e.what()));
    }
    Asset a = load_asset(file);
    if (a.binding.proxy)
      throw InputError(fmt::format("'{}': {}: '{}' is a proxy (a replacement body), not something to wear",
                                   kit.spec.source, entry, name));
    kit.assets.emplace(name, std::move(a));
  }
  kit.dress.skin_weights_near = 10;
  kit.dress.skin_weights_far = 30;
  if (fit_helpers) {
    const MakeHuman mh = MakeHuman::load(makehuman_dir);
    kit.regressor = fit_helper_regressor(mh, helper_options);
    kit.tie = bind_helpers(mh.build_vertices(MacroSettings{}), mh.body_faces());
    for (const char* name : {"female1605", "male1591", "proxy741"})
      kit.proxies.emplace(name, load_asset(find_asset(root, name)));
  }
  return kit;
}

bool outfit_sex_is_male(const BodyModel& model, Sex conditioned, const Eigen::VectorXd& encoding, uint64_t seed) {
  if (conditioned != Sex::unknown) return conditioned == Sex::male;
  const int k = model.shape.regression.find("sex");
  if (k >= 0 && encoding.size() == model.shape.pca.dimension())
    return model.shape.regression.predict(model.shape.pca.project(encoding))[k] >= 0.5;
  return (seed * 0x9e3779b97f4a7c15ull) >> 63;
}

std::optional<OutfitKit> outfit_kit_if_asked(const std::string& outfits, const fs::path& makehuman_dir,
                                             const std::string& lods) {
  if (lods != "default" && lods != "none")
    throw InputError("--lods: expected 'default' or 'none', found '" + lods + "'");
  if (outfits.empty()) return std::nullopt;
  OutfitKit kit = load_outfit_kit(outfits, makehuman_dir);
  kit.lods = lods == "default";
  return kit;
}

namespace {

// The largest `keep` weights of each row, renormalised: what a glTF player (4 joints a vertex)
// applies, so the penetration measured is the one the glb shows.
SkinWeights largest_weights(const SkinWeights& W, int keep) {
  std::vector<Eigen::Triplet<double>> t;
  for (int r = 0; r < W.outerSize(); ++r) {
    std::vector<std::pair<double, int>> row;
    for (SkinWeights::InnerIterator it(W, r); it; ++it) row.emplace_back(it.value(), static_cast<int>(it.col()));
    std::sort(row.rbegin(), row.rend());
    row.resize(std::min<size_t>(row.size(), keep));
    double sum = 0;
    for (auto& [w, b] : row) sum += w;
    for (auto& [w, b] : row) t.emplace_back(r, b, w / sum);
  }
  SkinWeights out(W.rows(), W.cols());
  out.setFromTriplets(t.begin(), t.end());
  return out;
}

// One skinned mesh of the parts, a primitive and material per part (as `bodymodel dress`).
GltfLevel dressed_level(const std::string& name, const std::vector<DressedPart>& parts, int bones) {
  GltfLevel l;
  l.name = name;
  Eigen::Index nv = 0, nf = 0;
  for (const DressedPart& p : parts) nv += p.V.rows(), nf += p.F.rows();
  l.V.resize(nv, 3);
  l.F.resize(nf, 3);
  std::vector<Eigen::Triplet<double>> t;
  Eigen::Index v0 = 0, f0 = 0;
  for (const DressedPart& p : parts) {
    l.V.middleRows(v0, p.V.rows()) = p.V;
    l.F.middleRows(f0, p.F.rows()) = p.F.array() + static_cast<int>(v0);
    for (int r = 0; r < p.weights.outerSize(); ++r)
      for (SkinWeights::InnerIterator it(p.weights, r); it; ++it) t.emplace_back(v0 + r, it.col(), it.value());
    l.parts.push_back({p.name, static_cast<int>(f0), static_cast<int>(p.F.rows()), p.colour.cwiseMin(1.0), p.roughness});
    v0 += p.V.rows(), f0 += p.F.rows();
  }
  l.W.resize(nv, bones);
  l.W.setFromTriplets(t.begin(), t.end());
  return l;
}

// A level's corrections at the keys only (no samples between them).
SampledCorrections keys_only(const ClipCorrections& c) {
  SampledCorrections s;
  for (size_t f = 0; f < c.frames.size(); ++f) s.times.push_back(static_cast<double>(f));
  s.corrections = c;
  return s;
}

// The samples of `s` at the keys: what clip_penetration measures at the keys.
ClipCorrections at_keys(const SampledCorrections& s) {
  ClipCorrections c;
  c.uncorrected = s.corrections.uncorrected;
  for (size_t i = 0; i < s.times.size(); ++i)
    if (s.times[i] == std::floor(s.times[i])) c.frames.push_back(s.corrections.frames[i]);
  return c;
}

// A level's clip corrections as its morph targets (its parts concatenated in order): one target
// per sample with a correction, weight 1 at that sample's time and 0 at the others' (the keys'
// times, or the samples' own when some lie between keys).
void add_clip_targets(GltfLevel& l, const std::vector<DressedPart>& parts, const SampledCorrections& s,
                      size_t keys, double frame_time) {
  const ClipCorrections& c = s.corrections;
  std::vector<int> first(parts.size() + 1, 0);
  for (size_t k = 0; k < parts.size(); ++k) first[k + 1] = first[k] + static_cast<int>(parts[k].V.rows());
  std::vector<size_t> keyed;
  for (size_t f = 0; f < c.frames.size(); ++f) {
    if (c.frames[f].empty()) continue;
    GltfMorphTarget t;
    t.name = s.times[f] == std::floor(s.times[f]) ? fmt::format("frame_{}", static_cast<long>(s.times[f]))
                                                  : fmt::format("frame_{:g}", s.times[f]);
    Eigen::Index n = 0;
    for (const GarmentCorrection& g : c.frames[f]) n += g.delta.rows();
    t.delta.resize(n, 3);
    n = 0;
    for (const GarmentCorrection& g : c.frames[f]) {   // parts in increasing order, rows increasing
      for (int v : g.vertex) t.vertex.push_back(first[g.part] + v);
      t.delta.middleRows(n, g.delta.rows()) = g.delta;
      n += g.delta.rows();
    }
    l.targets.push_back(std::move(t));
    keyed.push_back(f);
  }
  if (l.targets.empty()) return;
  l.target_weights.setZero(static_cast<Eigen::Index>(c.frames.size()), static_cast<Eigen::Index>(keyed.size()));
  for (size_t k = 0; k < keyed.size(); ++k) l.target_weights(static_cast<Eigen::Index>(keyed[k]), k) = 1;
  if (s.times.size() != keys)
    for (double t : s.times) l.target_times.push_back(t * frame_time);
}

// The levels (the full one first) as one glb sharing the skeleton and the clip; each level's clip
// corrections (when given: corrections[k] for level k) as its morph targets.
size_t write_dressed_glb(const fs::path& path, const std::vector<const std::vector<DressedPart>*>& levels,
                         const Skeleton& skeleton, const std::vector<BoneTransforms>& frames, double frame_time,
                         const std::vector<const SampledCorrections*>& corrections) {
  std::vector<GltfLevel> meshes;
  for (size_t k = 0; k < levels.size(); ++k)
    meshes.push_back(dressed_level(levels.size() == 1 ? "dressed" : fmt::format("dressed_LOD{}", k), *levels[k],
                                   skeleton.bone_count()));
  for (size_t k = 0; k < corrections.size() && k < levels.size(); ++k)
    if (corrections[k] && !frames.empty())
      add_clip_targets(meshes[k], *levels[k], *corrections[k], frames.size(), frame_time);
  GltfAnimation clip;
  clip.frame_time = frame_time;
  clip.frames = frames;
  const std::string bytes = skinned_lods_gltf_bytes(meshes, skeleton, frames.empty() ? nullptr : &clip);
  write_atomically(path, [&](std::ostream& os) { os.write(bytes.data(), static_cast<std::streamsize>(bytes.size())); });
  return bytes.size();
}

// Levels 1 and 2 of a dressed character (OutfitKit::lods), weights limited as the glb plays them.
std::vector<std::vector<DressedPart>> dressed_lods(const OutfitKit& kit, const std::vector<DressedPart>& parts,
                                                   const DressedSkinBody& d, bool male) {
  for (const char* name : {"female1605", "male1591", "proxy741"})
    if (!kit.proxies.count(name))
      throw InputError(std::string("levels of detail need the proxy '") + name +
                       "': load the outfit kit with its helpers (load_outfit_kit fit_helpers), or set lods false");
  LodSpec one{kit.lod1_triangles, &kit.proxies.at(male ? "male1591" : "female1605"), {"eyelashes", "teeth"},
              kit.lod1_error_mm};
  LodSpec two{kit.lod2_triangles, &kit.proxies.at("proxy741"), {"eyebrows", "eyelashes", "teeth"},
              kit.lod2_error_mm};
  std::vector<std::vector<DressedPart>> lods = {level_of_detail(parts, d, one), level_of_detail(parts, d, two)};
  for (auto& level : lods)
    for (DressedPart& p : level) p.weights = largest_weights(p.weights, 4);
  return lods;
}

// The skin faces the outfit hides (any hidden corner) over the vertices they use, with their
// weights: OutfitKit::keep_hidden_skin's debug part.
DressedPart hidden_skin_part(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const SkinWeights& W,
                             const std::vector<char>& hidden, const Eigen::Vector3d& colour) {
  DressedPart p;
  p.name = "body_hidden";
  p.kind = "body";
  p.colour = colour;
  p.roughness = 0.6;
  std::vector<int> faces, map(static_cast<size_t>(V.rows()), -1);
  int n = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (hidden[F(f, 0)] || hidden[F(f, 1)] || hidden[F(f, 2)]) {
      faces.push_back(static_cast<int>(f));
      for (int k = 0; k < 3; ++k)
        if (map[F(f, k)] < 0) map[F(f, k)] = n++;
    }
  p.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t i = 0; i < faces.size(); ++i)
    for (int k = 0; k < 3; ++k) p.F(static_cast<Eigen::Index>(i), k) = map[F(faces[i], k)];
  p.V.resize(n, 3);
  std::vector<Eigen::Triplet<double>> t;
  for (Eigen::Index v = 0; v < V.rows(); ++v)
    if (map[v] >= 0) {
      p.V.row(map[v]) = V.row(v);
      for (SkinWeights::InnerIterator it(W, v); it; ++it) t.emplace_back(map[v], it.col(), it.value());
    }
  p.weights.resize(n, W.cols());
  p.weights.setFromTriplets(t.begin(), t.end());
  p.weights = largest_weights(p.weights, 4);
  return p;
}

// The closed proxy surface level k (1 or 2) is measured and corrected against, weights as played.
ProxySurface level_body(const OutfitKit& kit, const DressedSkinBody& d, bool male, size_t k) {
  ProxySurface s = proxy_surface(kit.proxies.at(k == 1 ? (male ? "male1591" : "female1605") : "proxy741"), d);
  s.weights = largest_weights(s.weights, 4);
  return s;
}

// A level's corrections at the keys, sampled finer between them as the kit asks (with the measure
// half-way between samples into `between`, when refined).
SampledCorrections sampled_corrections(const OutfitKit& kit, const std::vector<DressedPart>& parts,
                                       const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const SkinWeights& W,
                                       const std::vector<char>& hidden, const Skeleton& skeleton,
                                       const std::vector<BoneTransforms>& frames, const ClipCorrectionOptions& co,
                                       double limit) {
  const ClipCorrections keys = clip_corrections(parts, V, F, W, hidden, frames, co);
  if (kit.between_key_halvings <= 0 || frames.size() < 2) return keys_only(keys);
  RefineOptions ro;
  ro.correction = co;
  ro.limit = limit;
  ro.max_halvings = kit.between_key_halvings;
  return refine_between_keys(parts, V, F, W, hidden, skeleton, frames, keys, ro);
}

// OutfitKit::lod_corrections: LOD1's and LOD2's garments pushed out of their proxy bodies frame by
// frame, as LOD0's are out of the skin (and sampled between keys as LOD0's).
std::vector<SampledCorrections> level_corrections(const OutfitKit& kit, const Skeleton& skeleton,
                                                  const DressedSkinBody& d, bool male,
                                                  const std::vector<BoneTransforms>& frames,
                                                  const ClipCorrectionOptions& co, DressedCharacterResult& r) {
  std::vector<SampledCorrections> out;
  for (size_t k = 0; k < r.lods.size(); ++k) {
    const ProxySurface s = level_body(kit, d, male, k + 1);
    out.push_back(sampled_corrections(kit, r.lods[k], s.V, s.F, s.weights, s.hidden, skeleton, frames, co, r.limit));
    for (const auto& f : out.back().corrections.frames) r.lod_morph_targets += !f.empty();
    r.lod_samples_added += out.back().added;
    if (out.back().between.fraction.rows() > 0) r.lod_between.push_back(out.back().between);
    if (out.back().between.fraction.rows() > 0) r.between_keys_unrefined.push_back(out.back().between_keys);
  }
  return out;
}

// Half-way between the keys with the corrections blended half and half (or none).
ClipPenetration halfway_between_keys(const std::vector<DressedPart>& parts, const Eigen::MatrixX3d& V,
                                     const Eigen::MatrixX3i& F, const SkinWeights& W, const std::vector<char>& hidden,
                                     const Skeleton& skeleton, const std::vector<BoneTransforms>& frames,
                                     const ClipCorrections* corr, double depth_mm) {
  std::vector<BoneTransforms> mid;
  for (size_t f = 0; f + 1 < frames.size(); ++f) mid.push_back(pose_between_keys(skeleton, frames[f], frames[f + 1], 0.5));
  std::optional<ClipCorrections> blended;
  if (corr) blended = corrections_between_keys(*corr, 0.5);
  return clip_penetration(parts, V, F, W, hidden, mid, depth_mm, blended ? &*blended : nullptr);
}

// OutfitKit::measure_levels: half-way between keys (LOD0 with the blended corrections) and LOD1,
// LOD2 at the keys against their proxies' closed surfaces (the proxy as fitted; LOD2's body is
// that proxy simplified when it takes over half the budget, so there the measure approximates),
// with their corrections when given.
void measure_levels(const OutfitKit& kit, const CharacterRigFile& ch, const SkinWeights& W, const DressedSkinBody& d,
                    bool male, const std::vector<BoneTransforms>& frames, const ClipCorrections* corr,
                    const std::vector<SampledCorrections>& lod_corr, DressedCharacterResult& r) {
  if (r.between_keys.fraction.rows() == 0)   // not refined: half-way between the keys
    r.between_keys = halfway_between_keys(r.parts, ch.lbs.rest, ch.F, W, d.hidden, ch.skeleton, frames, corr, r.depth_mm);
  const bool lod_between = r.lod_between.empty();
  for (size_t k = 0; k < r.lods.size(); ++k) {
    const ProxySurface s = level_body(kit, d, male, k + 1);
    std::optional<ClipCorrections> c;
    if (k < lod_corr.size()) c = at_keys(lod_corr[k]);
    r.lod_penetration.push_back(clip_penetration(r.lods[k], s.V, s.F, s.weights, s.hidden, frames, r.depth_mm, c ? &*c : nullptr));
    r.lod_uncorrected.push_back(c ? c->uncorrected : r.lod_penetration.back());
    if (lod_between)
      r.lod_between.push_back(halfway_between_keys(r.lods[k], s.V, s.F, s.weights, s.hidden, ch.skeleton, frames,
                                                   c ? &*c : nullptr, r.depth_mm));
  }
}

nlohmann::json penetration_json(const ClipPenetration& p, double limit) {
  return {{"frames", p.fraction.rows()},
          {"frames_over_limit", p.frames_over(limit)},
          {"worst_fraction", p.fraction.size() ? p.fraction.maxCoeff() : 0.0}};
}

nlohmann::json outfit_json(const DressedCharacterResult& r) {
  nlohmann::json lod_triangles = {triangle_count(r.parts)};
  for (const auto& l : r.lods) lod_triangles.push_back(triangle_count(l));
  nlohmann::json items = nlohmann::json::array();
  for (const DrawnItem& i : r.drawn.items)
    items.push_back({{"slot", i.slot}, {"asset", i.asset}, {"palette", i.palette}, {"srgb", i.hex},
                     {"linear", {i.colour[0], i.colour[1], i.colour[2]}}});
  nlohmann::json j = {{"sex", r.drawn.male ? "male" : "female"},
          {"skin", {{"srgb", r.drawn.skin_hex}, {"linear", {r.drawn.skin[0], r.drawn.skin[1], r.drawn.skin[2]}}}},
          {"items", items},
          {"penetration", {{"depth_mm", r.depth_mm},
                           {"limit", r.limit},
                           {"frames", r.penetration.fraction.rows()},
                           {"frames_over_limit", r.penetration.frames_over(r.limit)},
                           {"worst_fraction", r.penetration.fraction.size() ? r.penetration.fraction.maxCoeff() : 0.0},
                           {"uncorrected_frames_over_limit", r.uncorrected.frames_over(r.limit)},
                           {"uncorrected_worst_fraction",
                            r.uncorrected.fraction.size() ? r.uncorrected.fraction.maxCoeff() : 0.0}}},
          {"clip_corrections", {{"morph_targets", r.morph_targets},
                                {"garment_frames", r.corrected_garment_frames},
                                {"vertices", r.corrected_vertices}}},
          {"lod_triangles", lod_triangles},
          {"glb_bytes", r.glb_bytes}};
  if (r.between_keys.fraction.rows() > 0) {
    j["between_keys"] = penetration_json(r.between_keys, r.limit);
    j["between_keys"]["samples_added"] = r.samples_added;
  }
  for (size_t k = 0; k < r.lod_penetration.size(); ++k) {
    nlohmann::json l = penetration_json(r.lod_penetration[k], r.limit);
    l["uncorrected_frames_over_limit"] = r.lod_uncorrected[k].frames_over(r.limit);
    if (k < r.lod_between.size()) l["between_keys"] = penetration_json(r.lod_between[k], r.limit);
    j["lods"].push_back(l);
  }
  if (r.lod_morph_targets > 0) j["clip_corrections"]["lod_morph_targets"] = r.lod_morph_targets;
  if (r.lod_samples_added > 0) j["clip_corrections"]["lod_samples_added"] = r.lod_samples_added;
  return j;
}

}  // namespace

DressedCharacterResult write_dressed_character(const OutfitKit& kit, const CharacterRigFile& ch, bool male,
                                               uint64_t seed, const std::vector<BoneTransforms>& frames,
                                               double frame_time, const fs::path& dir) {
  DressedCharacterResult r;
  r.drawn = draw_outfit(kit.spec, male, seed);
  std::vector<Asset> outfit;
  for (const DrawnItem& i : r.drawn.items) outfit.push_back(kit.assets.at(i.asset));
  const SkinWeights W = skin_weights_of(ch.lbs);
  DressOptions o = kit.dress;
  o.skin_colour = r.drawn.skin;
  o.depth_mm = r.depth_mm;
  DressedSkinBody d = dress_skin_body(ch.lbs.rest, ch.F, W, kit.regressor, kit.tie, outfit, o);
  for (size_t k = 0; k < r.drawn.items.size(); ++k) d.parts[k + 1].colour = r.drawn.items[k].colour;
  for (DressedPart& p : d.parts) p.weights = largest_weights(p.weights, 4);
  r.parts = std::move(d.parts);
  r.hidden = d.hidden;
  if (kit.lods) r.lods = dressed_lods(kit, r.parts, d, male);
  const std::vector<BoneTransforms> measured =
      frames.empty() ? std::vector<BoneTransforms>{BoneTransforms(ch.skeleton.bone_count(), Eigen::Affine3d::Identity())}
                     : frames;
  std::optional<ClipCorrections> corr;   // at the keys
  std::optional<SampledCorrections> sampled;
  std::vector<SampledCorrections> lod_corr;
  ClipCorrectionOptions co;
  co.push = kit.dress.push;
  co.depth_mm = r.depth_mm;
  if (kit.clip_corrections && kit.lod_corrections && !frames.empty())
    lod_corr = level_corrections(kit, ch.skeleton, d, male, measured, co, r);
  if (kit.clip_corrections && !frames.empty()) {
    sampled = sampled_corrections(kit, r.parts, ch.lbs.rest, ch.F, W, d.hidden, ch.skeleton, measured, co, r.limit);
    corr = at_keys(*sampled);
    r.uncorrected = corr->uncorrected;
    r.corrected_garment_frames = sampled->corrections.garment_frames;
    r.corrected_vertices = sampled->corrections.vertices;
    for (const auto& f : sampled->corrections.frames) r.morph_targets += !f.empty();
    r.samples_added = sampled->added;
    r.between_keys = sampled->between;
    if (r.between_keys.fraction.rows() > 0)   // LOD0 first
      r.between_keys_unrefined.insert(r.between_keys_unrefined.begin(), sampled->between_keys);
  }
  r.penetration = clip_penetration(r.parts, ch.lbs.rest, ch.F, W, d.hidden, measured, r.depth_mm, corr ? &*corr : nullptr);
  if (!corr) r.uncorrected = r.penetration;
  if (kit.measure_levels) measure_levels(kit, ch, W, d, male, measured, corr ? &*corr : nullptr, lod_corr, r);
  // After the levels and the corrections (the parts' indices stay those the corrections name).
  if (kit.keep_hidden_skin) r.parts.push_back(hidden_skin_part(ch.lbs.rest, ch.F, W, d.hidden, r.parts[0].colour));
  std::vector<const std::vector<DressedPart>*> levels = {&r.parts};
  for (const auto& l : r.lods) levels.push_back(&l);
  std::vector<const SampledCorrections*> level_corr = {sampled ? &*sampled : nullptr};
  for (const SampledCorrections& c : lod_corr) level_corr.push_back(&c);
  r.glb_bytes = write_dressed_glb(dir / "dressed.glb", levels, ch.skeleton, frames, frame_time, level_corr);
  std::string csv = "frame";
  for (const std::string& g : r.penetration.garments) csv += fmt::format(",{0}_inside_fraction,{0}_max_depth_mm", g);
  for (const std::string& g : r.penetration.garments) csv += fmt::format(",{0}_uncorrected_inside_fraction", g);
  csv += "\n";
  for (Eigen::Index f = 0; f < r.penetration.fraction.rows(); ++f) {
    csv += std::to_string(f);
    for (Eigen::Index g = 0; g < r.penetration.fraction.cols(); ++g)
      csv += fmt::format(",{:.5f},{:.2f}", r.penetration.fraction(f, g), r.penetration.max_depth_mm(f, g));
    for (Eigen::Index g = 0; g < r.penetration.fraction.cols(); ++g)
      csv += fmt::format(",{:.5f}", r.uncorrected.fraction(f, g));
    csv += "\n";
  }
  write_text_file(dir / "penetration.csv", csv);
  write_text_file(dir / "outfit.json", outfit_json(r).dump(2) + "\n");
  return r;
}

}  // namespace bodymodel
