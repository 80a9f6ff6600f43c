// A small end-to-end registration (issue #3 "tests"): a MakeHuman subject unlike the template
// (male, taller, heavier, more muscular), posed with known joint rotations and turned on the
// platform, scanned with 1 mm noise and holes where a pillar scanner misses surface
// (downward-facing: soles, under the arms and chin, the crotch), with the 23 landmarks of
// core/landmarks.h placed with 5 mm noise. The default template is registered by register_scan
// (proportions, pose fit, non-rigid fit with a shortened fast schedule) and the result is
// compared with the truth by the evaluation's own metrics.
#include "registration/register_scan.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "core/landmarks.h"
#include "core/makehuman.h"
#include "registration/fixtures.h"
#include "registration/metrics.h"

namespace bodymodel {
namespace {

using test::rot;

double angle_deg(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  const Eigen::Matrix3d D = A * B.transpose();
  return std::acos(std::clamp((D.trace() - 1) / 2, -1.0, 1.0)) * 180.0 / M_PI;
}

// A male subject (non-default sliders) in a known pose, scanned with holes (no downward-facing
// surface), 1 mm noise and landmarks with 5 mm noise; registered with the given template.
struct EndToEnd {
  RegistrationErrors e;
  double p95 = 0, joint_median = 0;
  RegistrationResult r;
};

EndToEnd register_known_subject(const MakeHuman& mh, const RegistrationTemplate& tpl,
                                 RegistrationOptions options = {}) {
  MacroSettings ms;
  ms.gender = 1.0;
  ms.height = 0.7;
  ms.weight = 0.65;
  ms.muscle = 0.6;
  const MakeHuman::Body subject = mh.body(ms);
  const Skeleton& sk = subject.skeleton;

  Pose truth = Pose::rest(sk.bone_count());
  truth.rotations[0] = rot(20, {0, 1, 0});
  truth.root_translation = {30, 0, -20};
  const std::vector<std::pair<std::string, Eigen::Matrix3d>> joints = {
      {"upperarm01.L", rot(-35, {0, 0, 1})}, {"lowerarm01.L", rot(40, {0, 1, 0.3})},
      {"upperarm01.R", rot(25, {1, 0, 0.4})}, {"lowerarm01.R", rot(30, {1, 0, 0})},
      {"upperleg01.L", rot(-20, {1, 0, 0})},  {"lowerleg01.L", rot(35, {1, 0, 0})},
      {"upperleg01.R", rot(10, {0, 0, 1})},   {"spine03", rot(12, {1, 0, 0})},
      {"neck01", rot(15, {0, 1, 0})}};
  for (const auto& [name, R] : joints) truth.rotations[sk.index(name)] = R;
  Mesh posed = subject.mesh;
  posed.V = pose_template(subject.mesh.V, sk, subject.weights, 1.0, truth);

  // Scan: dense noisy samples minus the downward-facing surface (holes).
  // BODYMODEL_TEST_SEED draws another scan and other landmark noise (default 3), to measure
  // the spread the bounds below must cover.
  const char* seed_env = std::getenv("BODYMODEL_TEST_SEED");
  const unsigned seed = seed_env ? unsigned(std::strtoul(seed_env, nullptr, 10)) : 3u;
  const PointCloud dense = test::scan_of(posed, 70000, seed, 1.0);
  std::vector<int> keep;
  for (Eigen::Index i = 0; i < dense.P.rows(); ++i)
    if (dense.N(i, 1) > -0.6) keep.push_back(int(i));
  PointCloud scan;
  scan.P = dense.P(keep, Eigen::all);
  scan.N = dense.N(keep, Eigen::all);
  EXPECT_GT(scan.P.rows(), 50000);

  std::mt19937_64 rng(seed + 4);
  std::normal_distribution<double> noise(0.0, 5.0);
  std::vector<Landmark> landmarks;
  for (const auto& [name, v] : body_landmarks())
    landmarks.push_back(
        {v, posed.V.row(v).transpose() + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)), name});

  options.nonrigid.fast_steps = 20;  // half the default schedule: keeps the test short
  RegistrationSummary summary;
  EndToEnd out;
  out.r = register_scan(tpl, scan, landmarks, options, "test scan", &summary);
  out.e = registration_errors(out.r.V, posed.V, posed.F, scan.P);

  const auto Qt = world_rotations(sk, truth), Qe = world_rotations(tpl.skeleton, out.r.pose.pose);
  std::vector<double> joint_errors;
  for (const std::string& name : major_joints()) {
    joint_errors.push_back(angle_deg(Qe[sk.index(name)], Qt[sk.index(name)]));
    std::printf("  %-14s %6.2f deg\n", name.c_str(), joint_errors.back());
  }
  std::sort(joint_errors.begin(), joint_errors.end());
  std::vector<double> verr(out.e.vertex_errors.data(),
                           out.e.vertex_errors.data() + out.e.vertex_errors.size());
  std::sort(verr.begin(), verr.end());
  out.p95 = verr[size_t(0.95 * (verr.size() - 1))];
  out.joint_median = joint_errors[joint_errors.size() / 2];
  const RegistrationErrors& e = out.e;
  std::printf(
      "end to end%s: correspondence mean %.2f mm, p95 %.2f mm, surface %.2f mm, hole max %.2f mm "
      "(%d vertices), flipped %d, joint median %.2f deg; pose %.1f s, shape %.1f s (%d rounds), "
      "non-rigid %.1f s\n",
      tpl.shape_space ? " (shape fit)" : "", e.correspondence_mean, out.p95, e.surface_mean,
      e.hole_max, e.hole_vertices, e.flipped_triangles, out.joint_median, summary.pose.seconds,
      summary.shape_seconds, summary.shape_rounds, summary.nonrigid.seconds);
  return out;
}

TEST(RegisterScan, EndToEndSubjectInKnownPose) {
  MakeHuman mh = MakeHuman::load();
  const MakeHuman::Body tb = mh.body(MacroSettings{});
  const RegistrationTemplate tpl{tb.mesh, tb.skeleton, tb.weights, {}, {}, {}, {}};
  const EndToEnd t = register_known_subject(mh, tpl);
  const RegistrationErrors& e = t.e;
  // Bounds a little above what the pipeline reaches here: 7.10 mm, p95 21.2 mm, surface
  // 0.83 mm, hole max 14.6 mm, 10 flipped triangles, joint median 5.2°. The pipeline of the
  // previous session (weak landmark-stage prior, no anchor, no fold repair) gave 14.3 mm,
  // p95 66 mm, hole max 33 mm, 317 flipped triangles, 13.2°: every bound below fails for it.
  // Unchanged figures with the factorisation reuse (CG steps): the bounds keep ~12% margin.
  EXPECT_LT(e.correspondence_mean, 8.0);
  EXPECT_LT(t.p95, 24.0);
  EXPECT_LT(e.surface_mean, 1.0);
  EXPECT_LT(e.hole_max, 17.0);
  EXPECT_LE(e.flipped_triangles, 20);
  EXPECT_LT(t.joint_median, 7.0);
  EXPECT_FALSE(t.r.shape.has_value());
}

// The same subject with the template's shape space: the macro sliders fitted in the pose stage
// (registration/shape_fit.h). The subject is a MakeHuman body, so this is the favourable case
// (its shape is in the space); the bounds are the issue's targets, which the global scale and
// proportions above miss.
TEST(RegisterScan, EndToEndWithShapeFit) {
  MakeHuman mh = MakeHuman::load();
  const MakeHuman::Body tb = mh.body(MacroSettings{});
  RegistrationTemplate tpl{tb.mesh, tb.skeleton, tb.weights, mh, MacroSettings{}, {}, {}};
  const EndToEnd t = register_known_subject(mh, tpl);
  const RegistrationErrors& e = t.e;
  ASSERT_TRUE(t.r.shape.has_value());
  std::printf("fitted sliders: gender %.3f height %.3f weight %.3f muscle %.3f\n",
              t.r.shape->gender, t.r.shape->height, t.r.shape->weight, t.r.shape->muscle);
  // Bounds from the spread over 8 runs (BODYMODEL_TEST_SEED 3, 5, 11, 19; gcc and clang, whose
  // rounding differences alone move the fit as much as another seed): correspondence mean
  // 3.50–5.24 mm, p95 9.2–16.0, surface 0.59–0.67, hole max 5.9–12.2, flipped 0–2, joint median
  // 2.5–5.0°; sliders gender 0.64–0.87 (trades with muscle on an outline), height 0.60–0.70,
  // weight 0.54–0.67 for 1.0 / 0.7 / 0.65. Without the shape fit (seed 3): 7.25, 21.2, 0.84,
  // 14.6, 10 flipped, 5.2°, sliders at the start 0.5. Each bound but the joint median's sits
  // ~12% above the worst run and fails for the registration without the shape fit.
  EXPECT_LT(e.correspondence_mean, 6.0);
  EXPECT_LT(t.p95, 18.0);
  EXPECT_LT(e.surface_mean, 0.75);
  EXPECT_LT(e.hole_max, 13.5);
  EXPECT_LE(e.flipped_triangles, 4);
  EXPECT_LT(t.joint_median, 5.6);
  EXPECT_NEAR(t.r.shape->gender, 1.0, 0.45);
  EXPECT_NEAR(t.r.shape->height, 0.7, 0.12);
  EXPECT_NEAR(t.r.shape->weight, 0.65, 0.13);
}

// The pose and shape alternation stops after shape_rounds shape fits, the last of which moves
// the sliders away from the shape the pose was fitted on. RegistrationOptions::final_pose_fit
// fits the pose once more on the last shape: the pose-fitted template (before the non-rigid
// fit) must come closer to the truth. One round, so the alternation cannot converge.
TEST(RegisterScan, FinalPoseFitOnTheLastShape) {
  MakeHuman mh = MakeHuman::load();
  const MakeHuman::Body tb = mh.body(MacroSettings{});
  RegistrationTemplate tpl{tb.mesh, tb.skeleton, tb.weights, mh, MacroSettings{}, {}, {}};
  RegistrationOptions o;
  o.skip_nonrigid = true;
  o.shape_rounds = 1;
  o.pose.hand_iterations = 0;  // no hand stage: keeps the test short
  ASSERT_TRUE(o.final_pose_fit);  // on by default
  RegistrationOptions without = o;
  without.final_pose_fit = false;
  const EndToEnd a = register_known_subject(mh, tpl, without);
  const EndToEnd b = register_known_subject(mh, tpl, o);
  std::printf("one shape round, pose-fitted template: without the final pose fit %.2f mm (p95 "
              "%.2f), joint median %.2f deg; with it %.2f mm (p95 %.2f), %.2f deg\n",
              a.e.correspondence_mean, a.p95, a.joint_median, b.e.correspondence_mean, b.p95,
              b.joint_median);
  // Measured: 12.19 → 9.06 mm (p95 23.8 → 22.2), joint median 6.14 → 4.94°.
  EXPECT_LT(b.e.correspondence_mean, a.e.correspondence_mean - 1.0);
  EXPECT_LT(b.joint_median, a.joint_median);
}

}  // namespace
}  // namespace bodymodel
