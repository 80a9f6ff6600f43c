// The pose-space methods (PSD, EigenSkin, quadratic) on the bulging tube, whose pose-dependent
// swelling no SSD weights reproduce, their file round trip, and bad input.
#include <gtest/gtest.h>

#include <random>

#include "core/error.h"
#include "core/io/npz.h"
#include "skinning/fit_lbs.h"
#include "skinning/rig_io.h"
#include "skinning/skinning_model.h"
#include "support/fixtures.h"
#include "synthetic_tube.h"

namespace bodymodel {
namespace {

using testing::bulging_examples;
using testing::make_tube;

double rms_error(const FittedModel& m, const SkinningExamples& ex) {
  double s = 0;
  for (int p = 0; p < ex.pose_count(); ++p)
    s += (m.pose(ex.transforms[static_cast<size_t>(p)]) - ex.poses[static_cast<size_t>(p)]).rowwise().squaredNorm().sum();
  return std::sqrt(s / (double(ex.pose_count()) * ex.vertex_count()));
}

struct Tube {
  testing::SyntheticTube t = make_tube();
  SkinningExamples train = bulging_examples(t, 16, 21), test = bulging_examples(t, 10, 99);
  SkinningRig lbs = fit_lbs(train, {}, {});
};

const Tube& tube() {
  static const Tube t;
  return t;
}

TEST(PoseSpace, EveryMethodFitsTheTrainingBulgeAndBeatsSsdOnUnseenPoses) {
  const Tube& t = tube();
  FittedModel ssd;
  ssd.rig = t.lbs;
  const double ssd_train = rms_error(ssd, t.train), ssd_test = rms_error(ssd, t.test);
  for (SkinningModel m : {SkinningModel::psd, SkinningModel::eigenskin, SkinningModel::quadratic}) {
    ModelFitOptions o;
    o.pose_space.rbf_ridge = 1e-3;
    std::string brief;
    const FittedModel fit = fit_model(m, t.train, t.lbs, o, &brief);
    EXPECT_FALSE(brief.empty());
    const double train = rms_error(fit, t.train), test = rms_error(fit, t.test);
    // The examples are interpolated (up to the small ridge) and the bulge, a function of the
    // elbow angle only, carries over to new elbow angles.
    EXPECT_LT(train, 0.2 * ssd_train) << skinning_model_name(m);
    EXPECT_LT(test, 0.6 * ssd_test) << skinning_model_name(m) << " unseen " << test << " vs ssd " << ssd_test;
  }
}

TEST(PoseSpace, ExactInterpolationWithoutRidgeAndMeanFarFromTheExamples) {
  const Tube& t = tube();
  ModelFitOptions o;
  o.pose_space.rbf_ridge = 0;
  o.pose_space.inverse_damping = 0;
  const FittedModel psd = fit_model(SkinningModel::psd, t.train, t.lbs, o);
  for (int p = 0; p < t.train.pose_count(); ++p)
    EXPECT_LT((psd.pose(t.train.transforms[static_cast<size_t>(p)]) - t.train.poses[static_cast<size_t>(p)])
                  .cwiseAbs()
                  .maxCoeff(),
              1e-6)
        << "example " << p;
  // A pose whose relative rotations are far from every example: every kernel is ~0 and the
  // correction is the mean displacement d̄, so the result is the SSD pose plus L·d̄.
  BoneTransforms far(3, Eigen::Affine3d::Identity());
  far[1].linear() = Eigen::AngleAxisd(3.0, Eigen::Vector3d(0, 0, 1)).toRotationMatrix();
  far[2].linear() = Eigen::AngleAxisd(-3.0, Eigen::Vector3d(0, 1, 0)).toRotationMatrix();
  const Eigen::MatrixX3d X = psd.pose(far), S = evaluate_rig(t.lbs, far);
  EXPECT_TRUE(X.allFinite());
  EXPECT_LT((X - S).rowwise().norm().maxCoeff(), 5 * psd.pose_space.vertex_mean.rowwise().norm().maxCoeff() + 1e-9);
}

TEST(PoseSpace, EigenSkinWithEveryModeIsPsd) {
  const Tube& t = tube();
  ModelFitOptions o;
  o.pose_space.eigenskin_modes = 100;   // more than the examples: nothing truncated
  const FittedModel psd = fit_model(SkinningModel::psd, t.train, t.lbs, o);
  const FittedModel es = fit_model(SkinningModel::eigenskin, t.train, t.lbs, o);
  for (int p = 0; p < t.test.pose_count(); ++p)
    EXPECT_LT((psd.pose(t.test.transforms[static_cast<size_t>(p)]) - es.pose(t.test.transforms[static_cast<size_t>(p)]))
                  .cwiseAbs()
                  .maxCoeff(),
              1e-9);
  o.pose_space.eigenskin_modes = 1;   // truncated: a different (coarser) fit
  const FittedModel es1 = fit_model(SkinningModel::eigenskin, t.train, t.lbs, o);
  EXPECT_GT(rms_error(es1, t.train), rms_error(es, t.train));
}

TEST(PoseSpace, RigFilesRoundTripAndTheLinearLoaderRefusesThem) {
  const Tube& t = tube();
  fixtures::TempDir dir;
  for (SkinningModel m : {SkinningModel::psd, SkinningModel::eigenskin, SkinningModel::quadratic}) {
    const FittedModel fit = fit_model(m, t.train, t.lbs);
    const auto path = dir / (skinning_model_name(m) + ".npz");
    save_pose_space_rig(path, fit.pose_space, t.t.F, t.train.transforms);
    EXPECT_TRUE(is_pose_space_rig_file(path));
    Eigen::MatrixX3i F;
    FittedModel back;
    back.model = m;
    back.pose_space = load_pose_space_rig(path, &F);
    EXPECT_EQ(F, t.t.F);
    for (int p = 0; p < t.test.pose_count(); ++p)
      EXPECT_LT((back.pose(t.test.transforms[static_cast<size_t>(p)]) - fit.pose(t.test.transforms[static_cast<size_t>(p)]))
                    .cwiseAbs()
                    .maxCoeff(),
                1e-12)
          << skinning_model_name(m);
    try {
      load_rig(path);
      FAIL() << "load_rig accepted a pose-space rig";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(skinning_model_name(m) + " rig (pose-space"), std::string::npos) << e.what();
    }
    // A damaged array: one line naming the file and what is wrong.
    Npz z = Npz::load(path);
    z.put("vertex_mean", Eigen::MatrixXd(Eigen::MatrixXd::Zero(3, 3)));
    z.save(dir / "bad.npz");
    try {
      load_pose_space_rig(dir / "bad.npz");
      FAIL() << "a damaged rig loaded";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("bad.npz"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("vertex_mean"), std::string::npos) << e.what();
    }
  }
}

TEST(PoseSpace, BadInputIsRejected) {
  const Tube& t = tube();
  SkinningExamples one = t.train;
  one.poses.resize(1);
  one.transforms.resize(1);
  try {
    fit_model(SkinningModel::psd, one, t.lbs);
    FAIL() << "one example accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("at least 2"), std::string::npos) << e.what();
  }
  SkinningExamples sheared = t.train;
  sheared.transforms[3][1].linear() *= 1.2;
  EXPECT_THROW(fit_model(SkinningModel::quadratic, sheared, t.lbs), InputError);
  ModelFitOptions o;
  o.pose_space.kernel_width = 0;
  EXPECT_THROW(fit_model(SkinningModel::eigenskin, t.train, t.lbs, o), InputError);
  EXPECT_THROW(parse_skinning_model("pds"), InputError);
}

}  // namespace
}  // namespace bodymodel
