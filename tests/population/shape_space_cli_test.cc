// `bodymodel shape-space`: a space learned from soldiers, and the registration verbs refusing a
// file that is not one.
#include <gtest/gtest.h>

#include <filesystem>

#include "core/data_path.h"
#include "core/io/atomic_write.h"
#include "core/io/shape_space_file.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

// Twelve soldiers of each sex: a space of 5 components with falling spreads, the sexes apart.
TEST(ShapeSpaceCli, LearnsASpaceFromSoldiers) {
  const fs::path men = data_root() / "anthropometry" / "ansur2" / "ansur2_male.csv";
  if (!fs::exists(men)) GTEST_SKIP() << men << " not found";
  const fs::path dir = fs::temp_directory_path() / "bodymodel_shape_space_cli";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const auto r = fixtures::run_cli("shape-space --sample 12 --components 5 --jobs 2 --out '" +
                                   (dir / "space.json").string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const ShapeSpace s = read_shape_space(dir / "space.json");
  EXPECT_EQ(s.people, 24);
  ASSERT_EQ(s.components(), 5);
  for (int k = 1; k < 5; ++k) EXPECT_LE(s.sd[k], s.sd[k - 1]);
  EXPECT_GT(s.explained, 0.5);
  ASSERT_EQ(s.parameters.front(), "macro/gender");
  // The sexes are kept apart: the women's mean (gender 0), the men's one sex_direction away
  // (gender 1), and components learned within each sex, which do not move the gender slider.
  ASSERT_TRUE(s.has_sex());
  EXPECT_NEAR(s.mean[0], 0.0, 1e-9);
  EXPECT_NEAR(s.sex_direction[0], 1.0, 1e-9);
  EXPECT_LT(s.basis.row(0).norm(), 1e-6);
  EXPECT_EQ(s.dimension(), 6);

  // A file that is not a shape space: one line naming it, exit 2, before any registration.
  write_text_file(dir / "bad.json", "{\"format\": \"other\"}");
  write_text_file(dir / "lm.json", "{\"head_top\": 0}");
  const auto bad = fixtures::run_cli("register-mesh '" + (dir / "space.json").string() + "' --landmarks '" +
                                     (dir / "lm.json").string() + "' --shape-space '" + (dir / "bad.json").string() +
                                     "' --out '" + (dir / "reg").string() + "'");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("bad.json"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(dir / "reg"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bodymodel
