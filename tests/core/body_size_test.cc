// The unit check of a body mesh (core/body_size.h): a body's size in mm passes; metres,
// kilometres and collapsed meshes are refused, naming the mesh and the unit option to fix.
#include <gtest/gtest.h>

#include "core/body_size.h"
#include "core/error.h"
#include "support/fixtures.h"

namespace bodymodel {
namespace {

std::string message_of(const Eigen::MatrixX3d& V, const std::string& option = "", double scale = 1,
                       bool from_model = false) {
  try {
    check_body_size(V, "'b.off'", option, scale, from_model);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(BodySize, ABodyInMillimetresPassesWhateverAxisItStandsAlong) {
  const Mesh body = fixtures::cylinder(150, 1700, 12, 10);
  EXPECT_EQ(message_of(body.V), "");
  Eigen::MatrixX3d lying = body.V;
  lying.col(0).swap(lying.col(1));
  EXPECT_EQ(message_of(lying), "");
  EXPECT_EQ(message_of(fixtures::cylinder(100, 450, 12, 10).V), "");   // an infant
  EXPECT_EQ(message_of(fixtures::cylinder(200, 2900, 12, 10).V), "");  // taller than anyone
  EXPECT_TRUE(bounding_box_sides(body.V).isApprox(Eigen::Vector3d(1700, 300, 300), 1e-12)) << bounding_box_sides(body.V);
}

TEST(BodySize, WrongUnitsAreRefusedWithTheScaleThatFits) {
  const Mesh body = fixtures::cylinder(150, 1700, 12, 10);
  // Metres read as millimetres: 1.7 mm; the suggestion is the factor that makes it a body.
  std::string m = message_of(body.V / 1000, "--scale", 1);
  EXPECT_NE(m.find("'b.off': the body is 1.7 mm tall"), std::string::npos) << m;
  EXPECT_NE(m.find("after --scale 1;"), std::string::npos) << m;
  EXPECT_NE(m.find("use --scale 1000"), std::string::npos) << m;
  // Millimetres scaled by the model's 1000: 1.7 km.
  m = message_of(body.V * 1000, "--scale", 1000, true);
  EXPECT_NE(m.find("1.7e+06 mm tall"), std::string::npos) << m;
  EXPECT_NE(m.find("after the model's --scale 1000"), std::string::npos) << m;
  EXPECT_NE(m.find("use --scale 1 "), std::string::npos) << m;
  // Centimetres.
  EXPECT_NE(message_of(body.V / 10, "--scale", 1).find("centimetres: use --scale 10"), std::string::npos);
  // No unit option (the verb takes mm): says so.
  m = message_of(body.V / 1000);
  EXPECT_NE(m.find("must be in millimetres (it looks like metres)"), std::string::npos) << m;
  // No factor of 1, 10 or 1000 fits: the option is still named.
  m = message_of(body.V * 1e6, "--truth-scale", 1);
  EXPECT_NE(m.find("wrong --truth-scale?"), std::string::npos) << m;
}

TEST(BodySize, CollapsedMeshesAreNotBodies) {
  EXPECT_NE(message_of(Eigen::MatrixX3d::Zero(10, 3)).find("lie on one point"), std::string::npos);
  Eigen::MatrixX3d line = Eigen::MatrixX3d::Zero(3, 3);
  line.col(1) << 0, 900, 1700;
  EXPECT_NE(message_of(line).find("lie on a line"), std::string::npos);
  Mesh flat = fixtures::cylinder(150, 1700, 12, 10);
  flat.V.col(2).setZero();
  EXPECT_NE(message_of(flat.V).find("lie on a plane"), std::string::npos) << message_of(flat.V);
  Eigen::MatrixX3d nan = fixtures::cylinder(150, 1700, 12, 10).V;
  nan(3, 1) = std::nan("");
  EXPECT_NE(message_of(nan).find("NaN"), std::string::npos);
  EXPECT_NE(message_of(Eigen::MatrixX3d(0, 3)).find("one point"), std::string::npos);
}

}  // namespace
}  // namespace bodymodel
