#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "model/model_rig.h"
#include "model/morph.h"
#include "model/pose_edit.h"
#include "model_test_util.h"

namespace bodymodel {
namespace {

using testing::make_test_subjects;
using testing::shape_test_model;

TEST(Morph, SetHeightLandsWithinToleranceAcrossTheDataRange) {
  auto model = shape_test_model();
  ShapeMorpher morpher(model);
  auto probes = make_test_subjects(1, 99);  // not in the model
  const LabelInfo& h = model->shape.regression.labels[model->shape.regression.index("height_cm")];
  for (const auto& p : probes) {
    for (double X : {h.min, 0.5 * (h.min + h.max), h.max}) {
      MorphSummary sum;
      Eigen::MatrixX3d out = morpher.morph(p.V, {LabelCondition::exact("height_cm", X)}, {}, &sum);
      BodyMeasurements m = measure_body(out, model->tmpl->faces());
      EXPECT_NEAR(m.height_cm, X, 1.5) << sum.report();
      // A handful of sliver triangles (fingertips, toes) may face differently from the
      // template's after the rigid fit; more than 0.02% would mean a broken decode.
      EXPECT_LE(flipped_triangle_count(*model, out), 5);
    }
  }
}

TEST(Morph, SetWeightKeepHeight) {
  auto model = shape_test_model();
  ShapeMorpher morpher(model);
  auto probes = make_test_subjects(1, 98);
  for (const auto& p : probes) {
    for (double dw : {-12.0, 15.0}) {
      double Y = p.m.weight_kg + dw;
      MorphSummary sum;
      Eigen::MatrixX3d out = morpher.morph(
          p.V, {LabelCondition::exact("weight_kg", Y), LabelCondition::keep_current("height_cm")}, {}, &sum);
      BodyMeasurements m = measure_body(out, model->tmpl->faces());
      EXPECT_NEAR(m.weight_kg, Y, 2.0) << sum.report();
      EXPECT_NEAR(m.height_cm, p.m.height_cm, 1.0) << sum.report();
    }
  }
}


// Pose morphing skins the body in the rig's rest frame: a body turned about the vertical (a
// scan on a turntable) must be turned back, or every joint rotates about the wrong axes.
TEST(PoseMorph, CanonicalRotationUndoesATurnAboutTheVertical) {
  const MakeHuman& mh = bodymodel::testing::test_makehuman();
  ModelRigOptions ro;
  ro.training_bodies = 8;
  ModelRig rig = fit_makehuman_rig(mh, ro);
  auto subjects = make_test_subjects(2, 5);
  for (double angle : {0.0, 0.3, -1.2, 2.5}) {
    const Eigen::Matrix3d Ry = Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY()).toRotationMatrix();
    for (const auto& s : subjects) {
      const Eigen::MatrixX3d turned = s.V * Ry.transpose();
      const Eigen::Matrix3d G = canonical_rotation(rig, turned);
      // G · Ry should be the (near-identity) rotation of the unturned body.
      const Eigen::Matrix3d G0 = canonical_rotation(rig, s.V);
      const double deg = Eigen::AngleAxisd(G * Ry * G0.transpose()).angle() * 180 / M_PI;
      EXPECT_LT(deg, 0.01) << "turn " << angle;
      EXPECT_LT(Eigen::AngleAxisd(G0).angle() * 180 / M_PI, 1.0);  // MakeHuman's rest frame is world
    }
  }
}

}  // namespace
}  // namespace bodymodel
