// Dressed characters for `crowd` and `character` (--outfits FILE|default; docs/assets.md#outfits):
// an outfit drawn per character (assets/outfits.h), its assets fitted to the character's body by
// their bindings (helpers rebuilt from the skin), hidden skin removed, garments pushed out of the
// skin at rest, everything skinned with the character's SSD rig (the weights carried through the
// bindings) and written as one glb with a material (base colour, roughness) per part and the
// clip; the body-through-cloth penetration of every frame as the glb plays it.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "assets/dress.h"
#include "assets/helpers.h"
#include "assets/outfits.h"
#include "core/measure.h"
#include "core/progress.h"
#include "model/body_model.h"
#include "tools/pipeline/character_file.h"

namespace bodymodel {

// What every character of a run shares: the outfit file, its assets read once, the helpers.
struct OutfitKit {
  OutfitSpec spec;
  std::map<std::string, Asset> assets;   // by name
  HelperRegressor regressor;
  HelperBinding tie;
  // How each character is dressed: garments within 1 cm of the skin take the skin's weights
  // (DressOptions::skin_weights_near) and are pushed `push.clearance` (1 mm) out at rest. Set by
  // load_outfit_kit (figures: docs/assets.md#outfits).
  DressOptions dress;
  // Levels of detail in dressed.glb (docs/assets.md#levels-of-detail): LOD1 the MakeHuman proxy of
  // the character's sex (female1605 / male1591) with the assets simplified to lod1_triangles,
  // LOD2 the low-poly proxy (proxy741) and the assets but brows, lashes and teeth within
  // lod2_triangles. false = the full level only (`--lods none`).
  bool lods = true;
  int lod1_triangles = 8000, lod2_triangles = 2000;
  double lod1_error_mm = 4, lod2_error_mm = 12;   // how far a simplified vertex may leave the part
  std::map<std::string, Asset> proxies;  // by name; read by load_outfit_kit with the helpers
  // With a clip: each frame's garments pushed out of the posed skin (clip_corrections, assets/dress.h)
  // and baked into LOD0 as morph targets, one per corrected frame, selected by a `weights`
  // channel (docs/assets.md#penetration). LOD1 and LOD2 only with lod_corrections. false = the rest fix only.
  bool clip_corrections = true;
  // Debug: also write the skin the outfit hides, as a part "body_hidden" after the others in LOD0
  // (the body's colour), so that a render has a closed body. The browser pixel check of "no body
  // colour through a jacket" needs it to tell a ray that leaves the body from one that enters a
  // garment inside it (tests/tools/outfit_pixels_test.cc). Not for export: that skin is meant to
  // stay under the clothes, and nothing keeps it there. The measure is unchanged.
  bool keep_hidden_skin = false;
  // Also measure the penetration half-way between keys (as a player interpolates the clip and
  // blends the corrections) and on LOD1 and LOD2 against their proxy bodies (slower: about twice
  // the measure). Figures in outfit.json ("between_keys", "lods").
  bool measure_levels = false;
  // With a clip and levels: LOD1 and LOD2 get per-frame corrections too (clip_corrections against
  // their proxy bodies' closed surfaces), baked as their own morph targets and weights channels.
  // Off in the kit by default; `crowd` turns it on unless --no-lod-corrections (measured in
  // docs/assets.md#between-keys-and-levels).
  bool lod_corrections = false;
  // With clip corrections: each corrected level's corrections sampled finer between keys where the
  // blend of two neighbouring samples leaves the body through a garment half-way between them
  // (refine_between_keys, assets/dress.h; the weights channel then has its own times). The measure
  // half-way between samples comes with it (DressedCharacterResult::between_keys). 0 = keys only
  // (the between-keys measure then needs measure_levels).
  int between_key_halvings = 3;
};

// `outfits` = a JSON file or "default". Reads every asset the file names (InputError "'FILE':
// female.hair[2]: unknown asset 'x' (known: ...)"), then fits the helper regressor (seconds).
// `fit_helpers` false skips the regressor and tie (to check a file before any work).
OutfitKit load_outfit_kit(const std::string& outfits, const std::filesystem::path& makehuman_dir,
                          bool fit_helpers = true, const HelperRegressorOptions& helper_options = {});

// load_outfit_kit for a verb's --outfits value; nothing when it is empty. `lods` is the verb's
// --lods: "default" (three levels) or "none" (the full level only); InputError otherwise.
std::optional<OutfitKit> outfit_kit_if_asked(const std::string& outfits, const std::filesystem::path& makehuman_dir,
                                             const std::string& lods = "default");

struct DressedCharacterResult {
  DrawnOutfit drawn;
  std::vector<DressedPart> parts;        // at rest; the drawn colours
  std::vector<std::vector<DressedPart>> lods;  // levels 1, 2 (empty when kit.lods is false)
  ClipPenetration penetration;           // per frame (the rest pose when there is no clip), as the glb plays it
  ClipPenetration uncorrected;           // the same without the clip corrections (= penetration without them)
  // Half-way between consecutive samples of the corrections as played (the keys and the samples
  // added between them; #samples − 1 rows): with the corrections refined between keys, or with
  // OutfitKit::measure_levels (then half-way between keys); else empty.
  ClipPenetration between_keys;
  std::vector<ClipPenetration> lod_between;       // the same for LOD1, LOD2 (when measured)
  // Half-way between the keys before samples were added (refined corrections only; LOD0, LOD1, LOD2).
  std::vector<ClipPenetration> between_keys_unrefined;
  std::vector<ClipPenetration> lod_penetration;   // OutfitKit::measure_levels: LOD1, LOD2 at the keys (as played)
  std::vector<ClipPenetration> lod_uncorrected;   // the same without LOD corrections
  int lod_morph_targets = 0;             // OutfitKit::lod_corrections: LOD1's and LOD2's targets
  int samples_added = 0, lod_samples_added = 0;   // corrections sampled between keys (LOD0; LOD1 + LOD2)
  std::vector<char> hidden;              // the skin vertices the outfit hides (#skin), as measured
  int morph_targets = 0;                 // LOD0's targets (samples with a correction)
  int corrected_garment_frames = 0;
  long long corrected_vertices = 0;      // displacements stored over all targets
  double depth_mm = 2.0, limit = 0.01;   // the bound reported: frames over `limit` at depth_mm
  size_t glb_bytes = 0;
};

// The body of a character file (ch.lbs.rest, ch.F, the SSD weights of ch.lbs, its skeleton)
// dressed in the outfit drawn for (male, seed), posed by `frames` (bone maps, as animated.glb;
// empty = the rest pose only). Writes DIR/dressed.glb (with the clip when there are frames; with
// kit.lods one mesh node per level, "dressed_LOD0".."dressed_LOD2", sharing the skin),
// DIR/outfit.json (what was drawn, colours) and DIR/penetration.csv (per frame and garment: as
// the glb plays it, then without the clip corrections).
DressedCharacterResult write_dressed_character(const OutfitKit& kit, const CharacterRigFile& ch, bool male,
                                               uint64_t seed, const std::vector<BoneTransforms>& frames,
                                               double frame_time, const std::filesystem::path& dir);

// The sex an outfit is drawn for: the conditions' when they fix it, else the shape model's
// "sex" label predicted from the body's encoding (≥ 0.5 male), else a coin from the seed.
bool outfit_sex_is_male(const BodyModel& model, Sex conditioned, const Eigen::VectorXd& encoding, uint64_t seed);

}  // namespace bodymodel
