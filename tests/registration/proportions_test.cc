#include "registration/proportions.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "core/landmarks.h"
#include "core/makehuman.h"

namespace bodymodel {
namespace {

std::vector<Landmark> landmarks_of(const Eigen::MatrixX3d& V, double scale) {
  std::vector<Landmark> out;
  for (const auto& [name, v] : body_landmarks())
    out.push_back({v, scale * V.row(v).transpose(), name});
  return out;
}

// A template with known segment proportions (stretched by apply_proportions itself) and a global
// scale: estimate_proportions must recover the ratios from the landmarks, and re-proportioning
// the template with the estimate must bring the limbs within a few millimetres of the subject's.
TEST(Proportions, RecoversKnownSegmentRatios) {
  MakeHuman mh = MakeHuman::load();
  MakeHuman::Body body = mh.body(MacroSettings{});
  const Eigen::MatrixX3d& V = body.mesh.V;

  // Identity: all ratios 1 leaves the template and skeleton unchanged.
  Proportions unit;
  for (const auto& s : default_proportion_segments()) {
    unit.segment.push_back(s.name);
    unit.ratio.push_back(1.0);
  }
  Eigen::MatrixX3d V1;
  Skeleton sk1;
  apply_proportions(V, body.skeleton, body.weights, unit, {}, &V1, &sk1);
  EXPECT_LT((V1 - V).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((sk1.heads - body.skeleton.heads).cwiseAbs().maxCoeff(), 1e-9);

  const std::map<std::string, double> truth = {
      {"upperarm.L", 1.10}, {"upperarm.R", 1.10}, {"lowerleg.L", 0.92}, {"lowerleg.R", 0.92},
      {"upperleg.L", 1.05}, {"upperleg.R", 1.05}, {"head", 0.93}};
  Proportions p = unit;
  for (size_t k = 0; k < p.segment.size(); ++k)
    if (truth.count(p.segment[k])) p.ratio[k] = truth.at(p.segment[k]);
  Eigen::MatrixX3d Vs;
  Skeleton sks;
  apply_proportions(V, body.skeleton, body.weights, p, {}, &Vs, &sks);
  // The stretched upper arm is longer by the ratio (bone length, head to tail).
  const int ua = body.skeleton.index("upperarm01.L");
  EXPECT_NEAR((sks.tails.row(ua) - sks.heads.row(ua)).norm() /
                  (body.skeleton.tails.row(ua) - body.skeleton.heads.row(ua)).norm(),
              1.10, 1e-9);

  const double global = 1.2;
  const Proportions est = estimate_proportions(V, landmarks_of(Vs, global));
  ASSERT_EQ(est.segment.size(), default_proportion_segments().size());
  // The global scale is the ratio of summed segment lengths (it absorbs part of the stretch).
  EXPECT_NEAR(est.global_scale, global, 0.05 * global);
  for (size_t k = 0; k < est.segment.size(); ++k) {
    const double want = truth.count(est.segment[k]) ? truth.at(est.segment[k]) : 1.0;
    const double relative = est.ratio[k] * est.global_scale / global;
    std::printf("  %-12s true %.3f estimated %.3f\n", est.segment[k].c_str(), want, relative);
    // Landmarks sit on the surface and blend across joints: a few per cent.
    EXPECT_NEAR(relative, want, 0.04) << est.segment[k];
  }
  // Re-proportioned template vs the subject, both at the subject's size: limbs line up.
  Eigen::MatrixX3d Ve;
  Skeleton ske;
  apply_proportions(V, body.skeleton, body.weights, est, {}, &Ve, &ske);
  const Eigen::RowVector3d o = body.skeleton.heads.row(0);
  const double err_before = ((((V.rowwise() - o) * global).rowwise() + o) -
                             (((Vs.rowwise() - o) * global).rowwise() + o))
                                .rowwise().norm().mean();
  const double err_after = ((((Ve.rowwise() - o) * est.global_scale).rowwise() + o) -
                            (((Vs.rowwise() - o) * global).rowwise() + o))
                               .rowwise().norm().mean();
  std::printf("mean vertex distance to the subject: %.2f mm global scale only, %.2f mm with "
              "proportions\n", err_before, err_after);
  EXPECT_LT(err_after, 0.5 * err_before);
}

TEST(Proportions, TooFewLandmarksKeepTheTemplate) {
  MakeHuman mh = MakeHuman::load();
  MakeHuman::Body body = mh.body(MacroSettings{});
  const Proportions p = estimate_proportions(body.mesh.V, {});
  EXPECT_TRUE(p.segment.empty());
  EXPECT_EQ(p.global_scale, 1.0);
}

}  // namespace
}  // namespace bodymodel
