#include "assets/outfits.h"

#include <fmt/format.h>

#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <random>

#include "core/error.h"

namespace bodymodel {

namespace {

// Our palettes (sRGB). Skin: eight tones from light to deep; hair: black, browns, blond, auburn,
// grey; cloth: the muted colours of a street (navy, charcoal, denim, olive, burgundy, beige, off-
// white, black) and a few brighter ones; shoes: black, browns, white, grey. Eyes colour the whole
// low-poly eye (no texture): dark iris-like tones read better at crowd distance than white.
const std::map<std::string, std::vector<std::string>>& palettes() {
  static const std::map<std::string, std::vector<std::string>> p = {
      {"skin", {"#F3D5C0", "#E8BEA0", "#D9A37E", "#C68A63", "#A86D4B", "#8A5237", "#6B3E28", "#4B2C1E"}},
      {"hair", {"#1B1614", "#2E2019", "#4A3224", "#6B4A30", "#A07A4E", "#C9A66B", "#7A3B1E", "#8E8A86"}},
      {"cloth", {"#2B3A55", "#3A3A3E", "#4B6A8C", "#5B6339", "#6E2632", "#BBA886", "#E2DFD6", "#1E1E22",
                 "#A83A32", "#C49A2C", "#2E6F6B", "#7F8489"}},
      {"shoes", {"#161616", "#3E2A1E", "#6B4429", "#E0DFDA", "#55565C"}},
      {"hat", {"#2A2A2C", "#4A3A2C", "#6F6456", "#23304A"}},
      {"eyes", {"#3B2A1E", "#5A3D22", "#4E5A64", "#3F5A48"}},
      {"dark", {"#0F0D0C", "#1E1713", "#2A1E17"}},
  };
  return p;
}

[[noreturn]] void bad(const std::string& source, const std::string& where, const std::string& what) {
  throw InputError(fmt::format("'{}': {}: {}", source, where, what));
}

OutfitChoice parse_choice(const nlohmann::ordered_json& c, const std::string& source, const std::string& where) {
  if (!c.is_object()) bad(source, where, "expected an object {\"asset\": NAME, \"weight\": W, \"palette\": P}");
  OutfitChoice o;
  for (const auto& [key, value] : c.items()) {
    if (key == "asset") {
      if (!value.is_string() || value.get<std::string>().empty()) bad(source, where, "\"asset\" must be a name or \"none\"");
      o.asset = value.get<std::string>() == "none" ? "" : value.get<std::string>();
    } else if (key == "weight") {
      if (!value.is_number() || !std::isfinite(value.get<double>()) || value.get<double>() < 0)
        bad(source, where, "\"weight\" must be a number ≥ 0");
      o.weight = value.get<double>();
    } else if (key == "palette") {
      if (!value.is_string()) bad(source, where, "\"palette\" must be a palette name or \"match:SLOT\"");
      o.palette = value.get<std::string>();
    } else {
      bad(source, where, "unknown key '" + key + "' (expected asset, weight, palette)");
    }
  }
  if (!c.contains("asset")) bad(source, where, "no \"asset\" (a name or \"none\")");
  if (o.palette.rfind("match:", 0) != 0 && !palettes().count(o.palette))
    bad(source, where, "unknown palette '" + o.palette + "'");
  return o;
}

std::vector<OutfitSlot> parse_sex(const nlohmann::ordered_json& j, const std::string& source, const std::string& sex) {
  if (!j.contains(sex)) bad(source, sex, "missing (the file needs \"female\" and \"male\")");
  const nlohmann::ordered_json& s = j.at(sex);
  if (!s.is_object()) bad(source, sex, "expected an object of slots {\"hair\": [...], ...}");
  std::vector<OutfitSlot> slots;
  for (const auto& [name, list] : s.items()) {
    const std::string where = sex + "." + name;
    if (!list.is_array() || list.empty()) bad(source, where, "expected a non-empty list of choices");
    OutfitSlot slot{name, {}};
    double total = 0;
    for (size_t k = 0; k < list.size(); ++k) {
      slot.choices.push_back(parse_choice(list[k], source, fmt::format("{}[{}]", where, k)));
      const std::string& p = slot.choices.back().palette;
      if (p.rfind("match:", 0) == 0) {
        const std::string other = p.substr(6);
        bool earlier = false;
        for (const OutfitSlot& e : slots) earlier |= e.name == other;
        if (!earlier) bad(source, fmt::format("{}[{}]", where, k), "'" + p + "' names no earlier slot of " + sex);
      }
      total += slot.choices.back().weight;
    }
    if (!(total > 0)) bad(source, where, "the weights sum to 0");
    slots.push_back(std::move(slot));
  }
  return slots;
}

}  // namespace

OutfitSpec parse_outfits(const std::string& text, const std::string& source) {
  nlohmann::ordered_json j;
  try {
    // Keys keep the file's order: slots are drawn in that order ("match:" refers to earlier ones).
    j = nlohmann::ordered_json::parse(text);
  } catch (const std::exception& e) {
    throw InputError(fmt::format("'{}': not JSON ({})", source, e.what()));
  }
  if (!j.is_object()) bad(source, "top level", "expected {\"female\": {...}, \"male\": {...}}");
  for (const auto& [key, value] : j.items())
    if (key != "female" && key != "male") bad(source, key, "unknown key (expected female, male)");
  OutfitSpec spec;
  spec.source = source;
  spec.female = parse_sex(j, source, "female");
  spec.male = parse_sex(j, source, "male");
  return spec;
}

const std::string& default_outfits_json() {
  // A street: everyone in a suit (MakeHuman's suits are top and trousers or skirt in one mesh)
  // and shoes, hair for most, a hat for a few, brows the colour of the hair, lashes and eyes.
  static const std::string text = R"({
  "female": {
    "suit": [{"asset": "female_casualsuit01", "weight": 3}, {"asset": "female_casualsuit02", "weight": 3},
             {"asset": "female_sportsuit01", "weight": 2}, {"asset": "female_elegantsuit01", "weight": 1}],
    "shoes": [{"asset": "shoes01", "palette": "shoes"}, {"asset": "shoes02", "palette": "shoes"},
              {"asset": "shoes03", "palette": "shoes"}, {"asset": "shoes04", "palette": "shoes"},
              {"asset": "shoes05", "palette": "shoes"}, {"asset": "shoes06", "palette": "shoes"}],
    "hair": [{"asset": "bob01", "weight": 2, "palette": "hair"}, {"asset": "bob02", "weight": 2, "palette": "hair"},
             {"asset": "long01", "weight": 2, "palette": "hair"}, {"asset": "ponytail01", "weight": 2, "palette": "hair"},
             {"asset": "braid01", "weight": 1, "palette": "hair"}, {"asset": "short03", "weight": 1, "palette": "hair"},
             {"asset": "afro01", "weight": 1, "palette": "hair"}],
    "hat": [{"asset": "none", "weight": 9}, {"asset": "fedora", "weight": 1, "palette": "hat"}],
    "eyebrows": [{"asset": "eyebrow001", "palette": "match:hair"}, {"asset": "eyebrow002", "palette": "match:hair"},
                 {"asset": "eyebrow003", "palette": "match:hair"}, {"asset": "eyebrow004", "palette": "match:hair"}],
    "eyelashes": [{"asset": "eyelashes01", "palette": "dark"}, {"asset": "eyelashes02", "palette": "dark"}],
    "eyes": [{"asset": "low-poly", "palette": "eyes"}]
  },
  "male": {
    "suit": [{"asset": "male_casualsuit01", "weight": 2}, {"asset": "male_casualsuit02", "weight": 2},
             {"asset": "male_casualsuit03", "weight": 2}, {"asset": "male_casualsuit04", "weight": 2},
             {"asset": "male_casualsuit05", "weight": 2}, {"asset": "male_casualsuit06", "weight": 2},
             {"asset": "male_elegantsuit01", "weight": 1}, {"asset": "male_worksuit01", "weight": 1}],
    "shoes": [{"asset": "shoes01", "palette": "shoes"}, {"asset": "shoes02", "palette": "shoes"},
              {"asset": "shoes03", "palette": "shoes"}, {"asset": "shoes04", "palette": "shoes"},
              {"asset": "shoes05", "palette": "shoes"}, {"asset": "shoes06", "palette": "shoes"}],
    "hair": [{"asset": "short01", "weight": 3, "palette": "hair"}, {"asset": "short02", "weight": 3, "palette": "hair"},
             {"asset": "short04", "weight": 3, "palette": "hair"}, {"asset": "afro01", "weight": 1, "palette": "hair"},
             {"asset": "none", "weight": 1}],
    "hat": [{"asset": "none", "weight": 8}, {"asset": "fedora", "weight": 1, "palette": "hat"},
            {"asset": "fedora_cocked", "weight": 1, "palette": "hat"}],
    "eyebrows": [{"asset": "eyebrow005", "palette": "match:hair"}, {"asset": "eyebrow006", "palette": "match:hair"},
                 {"asset": "eyebrow007", "palette": "match:hair"}, {"asset": "eyebrow008", "palette": "match:hair"}],
    "eyelashes": [{"asset": "eyelashes03", "palette": "dark"}, {"asset": "eyelashes04", "palette": "dark"}],
    "eyes": [{"asset": "low-poly", "palette": "eyes"}]
  }
})";
  return text;
}

OutfitSpec default_outfits() { return parse_outfits(default_outfits_json(), "default"); }

std::vector<std::pair<std::string, std::string>> each_outfit_asset(const OutfitSpec& spec) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto* sex : {&spec.female, &spec.male})
    for (const OutfitSlot& s : *sex)
      for (size_t k = 0; k < s.choices.size(); ++k)
        if (!s.choices[k].asset.empty())
          out.emplace_back(fmt::format("{}.{}[{}]", sex == &spec.female ? "female" : "male", s.name, k),
                           s.choices[k].asset);
  return out;
}

std::vector<std::string> outfit_palette_names() {
  std::vector<std::string> n;
  for (const auto& [name, colours] : palettes()) n.push_back(name);
  return n;
}

const std::vector<std::string>& outfit_palette(const std::string& name) {
  const auto it = palettes().find(name);
  if (it == palettes().end()) throw InputError("unknown palette '" + name + "'");
  return it->second;
}

Eigen::Vector3d srgb_hex_to_linear(const std::string& hex) {
  if (hex.size() != 7 || hex[0] != '#') throw InputError("colour '" + hex + "': expected #RRGGBB");
  Eigen::Vector3d c;
  for (int k = 0; k < 3; ++k) {
    const double s = std::stoi(hex.substr(1 + 2 * k, 2), nullptr, 16) / 255.0;
    c[k] = s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4);  // the sRGB transfer
  }
  return c;
}

DrawnOutfit draw_outfit(const OutfitSpec& spec, bool male, uint64_t seed) {
  // Its own stream (not the body's): the outfit does not change when the body generator draws
  // a different number of values.
  std::mt19937_64 rng(seed ^ 0x6f75746669747321ull);
  auto uniform = [&] { return (rng() >> 11) * (1.0 / 9007199254740992.0); };
  auto pick = [&](const std::vector<std::string>& p) { return p[std::min(p.size() - 1, size_t(uniform() * p.size()))]; };
  DrawnOutfit d;
  d.male = male;
  d.skin_hex = pick(outfit_palette("skin"));
  d.skin = srgb_hex_to_linear(d.skin_hex);
  for (const OutfitSlot& slot : male ? spec.male : spec.female) {
    double total = 0;
    for (const OutfitChoice& c : slot.choices) total += c.weight;
    double u = uniform() * total;
    size_t k = 0;
    while (k + 1 < slot.choices.size() && (u >= slot.choices[k].weight || slot.choices[k].weight == 0))
      u -= slot.choices[k++].weight;
    const OutfitChoice& c = slot.choices[k];
    std::string hex;
    if (c.palette.rfind("match:", 0) == 0) {
      for (const DrawnItem& e : d.items)
        if (e.slot == c.palette.substr(6)) hex = e.hex;
      if (hex.empty()) hex = pick(outfit_palette("hair"));
    } else {
      hex = pick(outfit_palette(c.palette));
    }
    if (c.asset.empty()) continue;
    d.items.push_back({slot.name, c.asset, c.palette, hex, srgb_hex_to_linear(hex)});
  }
  return d;
}

}  // namespace bodymodel
