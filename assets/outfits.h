// Outfits for characters and crowds (issue 39): which MakeHuman assets a character wears and in
// which colours, drawn per character from a small JSON of choices with weights per sex, and the
// colour palettes the colours come from (upstream textures are Git LFS pointers, so every colour
// is ours; docs/assets.md#outfits).
//
// The file: {"female": {SLOT: [CHOICE, ...], ...}, "male": {...}}. A slot (any name: "suit",
// "shoes", "hair", "hat", ...) yields at most one asset; a choice is
//   {"asset": NAME | "none", "weight": w ≥ 0, "palette": PALETTE}
// with NAME a binding's stem (assets/dress.h find_asset), weight default 1, palette one of
// outfit_palette_names() or "match:SLOT" (the colour drawn for an earlier slot, e.g. eyebrows the
// colour of the hair; the "hair" palette when that slot drew nothing). Every slot needs a
// positive total weight. Bad files throw InputError "'FILE': female.hair[2]: what is wrong".
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace bodymodel {

struct OutfitChoice {
  std::string asset;              // binding stem; "" = nothing
  double weight = 1;
  std::string palette = "cloth";  // a palette name or "match:SLOT"
};

struct OutfitSlot {
  std::string name;
  std::vector<OutfitChoice> choices;
};

struct OutfitSpec {
  std::string source;                     // the file (or "default"), for messages
  std::vector<OutfitSlot> female, male;   // slots in file order
};

// Parses the JSON text; `source` names it in errors. Asset names are not checked here (the
// caller knows the asset folder: see each_outfit_asset).
OutfitSpec parse_outfits(const std::string& json_text, const std::string& source);
// The built-in street outfits (`--outfits default`) and their JSON text.
const std::string& default_outfits_json();
OutfitSpec default_outfits();

// Every (entry label "female.hair[2]", asset name) of the spec with an asset, for checks.
std::vector<std::pair<std::string, std::string>> each_outfit_asset(const OutfitSpec& spec);

// Palettes by name: "skin", "hair", "cloth", "shoes", "hat", "eyes", "dark". Colours are
// sRGB hex strings (documented in docs/assets.md); srgb_hex_to_linear gives the linear RGB glTF's
// baseColorFactor takes.
std::vector<std::string> outfit_palette_names();
const std::vector<std::string>& outfit_palette(const std::string& name);  // InputError if unknown
Eigen::Vector3d srgb_hex_to_linear(const std::string& hex);

struct DrawnItem {
  std::string slot, asset, palette;
  std::string hex;                 // the drawn palette colour (sRGB)
  Eigen::Vector3d colour;          // linear RGB
};

struct DrawnOutfit {
  bool male = false;
  std::string skin_hex;
  Eigen::Vector3d skin;            // linear RGB, from the "skin" palette
  std::vector<DrawnItem> items;    // one per slot that drew an asset, in slot order
};

// Draws one character's outfit: the skin tone, then per slot a choice by weight and a colour of
// its palette, uniformly. The same spec, sex and seed give the same outfit.
DrawnOutfit draw_outfit(const OutfitSpec& spec, bool male, uint64_t seed);

}  // namespace bodymodel
