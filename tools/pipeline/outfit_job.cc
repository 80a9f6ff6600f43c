#include "tools/pipeline/outfit_job.h"

#include <fmt/format.h>

#include <algorithm>
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

// The clip corrections as morph targets of the full level (its parts concatenated in order): one
// target per frame with a correction, weight 1 at that frame's key and 0 at the others.
void add_clip_targets(GltfLevel& l, const std::vector<DressedPart>& parts, const ClipCorrections& c) {
  std::vector<int> first(parts.size() + 1, 0);
  for (size_t k = 0; k < parts.size(); ++k) first[k + 1] = first[k] + static_cast<int>(parts[k].V.rows());
  std::vector<size_t> keyed;
  for (size_t f = 0; f < c.frames.size(); ++f) {
    if (c.frames[f].empty()) continue;
    GltfMorphTarget t;
    t.name = fmt::format("frame_{}", f);
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
}

// The levels (the full one first) as one glb sharing the skeleton and the clip; the clip
// corrections (when given) as morph targets of the full level.
size_t write_dressed_glb(const fs::path& path, const std::vector<const std::vector<DressedPart>*>& levels,
                         const Skeleton& skeleton, const std::vector<BoneTransforms>& frames, double frame_time,
                         const ClipCorrections* corrections) {
  std::vector<GltfLevel> meshes;
  for (size_t k = 0; k < levels.size(); ++k)
    meshes.push_back(dressed_level(levels.size() == 1 ? "dressed" : fmt::format("dressed_LOD{}", k), *levels[k],
                                   skeleton.bone_count()));
  if (corrections && !frames.empty()) add_clip_targets(meshes[0], *levels[0], *corrections);
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

nlohmann::json outfit_json(const DressedCharacterResult& r) {
  nlohmann::json lod_triangles = {triangle_count(r.parts)};
  for (const auto& l : r.lods) lod_triangles.push_back(triangle_count(l));
  nlohmann::json items = nlohmann::json::array();
  for (const DrawnItem& i : r.drawn.items)
    items.push_back({{"slot", i.slot}, {"asset", i.asset}, {"palette", i.palette}, {"srgb", i.hex},
                     {"linear", {i.colour[0], i.colour[1], i.colour[2]}}});
  return {{"sex", r.drawn.male ? "male" : "female"},
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
  std::optional<ClipCorrections> corr;
  if (kit.clip_corrections && !frames.empty()) {
    ClipCorrectionOptions co;
    co.push = kit.dress.push;
    co.depth_mm = r.depth_mm;
    corr = clip_corrections(r.parts, ch.lbs.rest, ch.F, W, d.hidden, measured, co);
    r.uncorrected = corr->uncorrected;
    r.corrected_garment_frames = corr->garment_frames;
    r.corrected_vertices = corr->vertices;
    for (const auto& f : corr->frames) r.morph_targets += !f.empty();
  }
  r.penetration = clip_penetration(r.parts, ch.lbs.rest, ch.F, W, d.hidden, measured, r.depth_mm, corr ? &*corr : nullptr);
  if (!corr) r.uncorrected = r.penetration;
  std::vector<const std::vector<DressedPart>*> levels = {&r.parts};
  for (const auto& l : r.lods) levels.push_back(&l);
  r.glb_bytes = write_dressed_glb(dir / "dressed.glb", levels, ch.skeleton, frames, frame_time, corr ? &*corr : nullptr);
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
