// Outfit files and draws (assets/outfits.h): the parser's errors name the file and the entry,
// draws are reproducible and follow the weights, palettes convert to linear RGB.
#include <gtest/gtest.h>

#include <map>
#include <set>
#include <string>

#include "assets/outfits.h"
#include "core/error.h"

namespace bodymodel {
namespace {

std::string error_of(const std::string& text) {
  try {
    parse_outfits(text, "my.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Outfits, BadFilesNameTheFileAndTheEntry) {
  const std::string male = R"("male": {"hair": [{"asset": "short02"}]})";
  EXPECT_NE(error_of("{"), "");
  EXPECT_NE(error_of("{" + male + "}").find("'my.json': female: missing"), std::string::npos);
  auto f = [&](const std::string& female) { return error_of("{\"female\": " + female + ", " + male + "}"); };
  EXPECT_NE(f(R"({"hair": [{"asset": "bob01"}, {"asset": "x", "weight": -1}]})").find("'my.json': female.hair[1]: \"weight\""),
            std::string::npos);
  EXPECT_NE(f(R"({"hair": [{"asset": "bob01", "colour": 3}]})").find("female.hair[0]: unknown key 'colour'"),
            std::string::npos);
  EXPECT_NE(f(R"({"hair": [{"asset": "bob01", "palette": "neon"}]})").find("female.hair[0]: unknown palette 'neon'"),
            std::string::npos);
  EXPECT_NE(f(R"({"hair": [{"weight": 2}]})").find("female.hair[0]: no \"asset\""), std::string::npos);
  EXPECT_NE(f(R"({"hair": [{"asset": "none", "weight": 0}]})").find("female.hair: the weights sum to 0"),
            std::string::npos);
  EXPECT_NE(f(R"({"hair": []})").find("female.hair: expected a non-empty list"), std::string::npos);
  EXPECT_NE(f(R"({"brows": [{"asset": "eyebrow001", "palette": "match:hair"}]})").find("female.brows[0]: 'match:hair'"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"female": {}, "male": {}, "child": {}})").find("'my.json': child: unknown key"),
            std::string::npos);
  EXPECT_EQ(f(R"({"hair": [{"asset": "bob01"}]})"), "");
}

TEST(Outfits, DefaultIsAStreet) {
  const OutfitSpec d = default_outfits();
  for (const auto* sex : {&d.female, &d.male}) {
    std::set<std::string> slots;
    for (const OutfitSlot& s : *sex) slots.insert(s.name);
    for (const char* s : {"suit", "shoes", "hair", "hat", "eyebrows", "eyelashes", "eyes"}) EXPECT_TRUE(slots.count(s)) << s;
  }
  // Everyone wears a suit and shoes; most have hair, a few a hat.
  int hair = 0, hat = 0;
  const int n = 2000;
  for (int i = 0; i < n; ++i) {
    const DrawnOutfit o = draw_outfit(d, i % 2, 1000 + i);
    std::set<std::string> got;
    for (const DrawnItem& it : o.items) got.insert(it.slot);
    EXPECT_TRUE(got.count("suit") && got.count("shoes"));
    hair += got.count("hair"), hat += got.count("hat");
  }
  // Expected: hair 1 (women) and 10/11 (men) → 0.955; hat 0.1 (women), 0.2 (men) → 0.15.
  EXPECT_NEAR(double(hair) / n, 0.955, 0.03);
  EXPECT_NEAR(double(hat) / n, 0.15, 0.03);
}

TEST(Outfits, DrawsAreReproducibleFollowTheWeightsAndMatchColours) {
  const OutfitSpec s = parse_outfits(R"({
    "female": {"hair": [{"asset": "a", "weight": 3, "palette": "hair"}, {"asset": "b", "weight": 1, "palette": "hair"},
                        {"asset": "never", "weight": 0}],
               "brows": [{"asset": "eyebrow001", "palette": "match:hair"}]},
    "male": {"top": [{"asset": "none"}]}})", "t");
  const DrawnOutfit a = draw_outfit(s, false, 42), b = draw_outfit(s, false, 42);
  ASSERT_EQ(a.items.size(), 2u);
  EXPECT_EQ(a.items[0].asset, b.items[0].asset);
  EXPECT_EQ(a.items[0].hex, b.items[0].hex);
  EXPECT_EQ(a.skin_hex, b.skin_hex);
  EXPECT_TRUE(draw_outfit(s, true, 42).items.empty());
  std::map<std::string, int> count;
  std::set<std::string> skins;
  const int n = 4000;
  for (int i = 0; i < n; ++i) {
    const DrawnOutfit o = draw_outfit(s, false, i);
    count[o.items[0].asset]++;
    EXPECT_EQ(o.items[1].hex, o.items[0].hex);  // brows the colour of the hair
    const auto& hair = outfit_palette("hair");
    EXPECT_NE(std::find(hair.begin(), hair.end(), o.items[0].hex), hair.end());
    EXPECT_TRUE((o.items[0].colour - srgb_hex_to_linear(o.items[0].hex)).norm() == 0);
    skins.insert(o.skin_hex);
  }
  EXPECT_EQ(count["never"], 0);
  EXPECT_NEAR(double(count["a"]) / n, 0.75, 0.03);  // binomial sd 0.007
  EXPECT_EQ(skins.size(), outfit_palette("skin").size());
}

TEST(Outfits, SrgbToLinear) {
  EXPECT_NEAR((srgb_hex_to_linear("#FFFFFF") - Eigen::Vector3d::Ones()).norm(), 0, 1e-12);
  EXPECT_NEAR(srgb_hex_to_linear("#000000").norm(), 0, 1e-12);
  // 0x80 = 128/255: ((0.50196 + 0.055) / 1.055)^2.4 = 0.21586.
  EXPECT_NEAR(srgb_hex_to_linear("#808080")[1], 0.21586, 1e-5);
  EXPECT_THROW(srgb_hex_to_linear("808080"), InputError);
}

}  // namespace
}  // namespace bodymodel
