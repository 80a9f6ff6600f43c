// Finger grasp in the pose fit: the hand stage (per-finger curls fitted after the body) on the
// MakeHuman template posed with the fists of MakeHuman's 'fight03' pose.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdio>
#include <map>

#include "core/geometry.h"
#include "core/io/bvh.h"
#include "core/makehuman.h"
#include "core/point_index.h"
#include "core/retarget.h"
#include "core/rotation.h"
#include "registration/fixtures.h"
#include "registration/pose_fit.h"

namespace bodymodel {
namespace {

using test::rot;

// The points of a dense sampling (unit normals) that one of four pillars at 45°, 135°, … sees
// along horizontal rays (y up): in front in a 3 mm depth buffer of 4 mm cells, hit at less than
// 75° from the normal. Like the synthetic database's scanner: the inside of a fist is a hole.
PointCloud pillar_scan(const PointCloud& dense) {
  const Eigen::Vector3d centre = dense.P.colwise().mean().transpose();
  std::vector<char> seen(dense.P.rows(), 0);
  for (int k = 0; k < 4; ++k) {
    const double a = (45.0 + 90.0 * k) * M_PI / 180.0;
    const Eigen::Vector3d dir(std::cos(a), 0, std::sin(a));  // pillar → subject is −dir
    const Eigen::Vector3d side(-dir.z(), 0, dir.x());
    std::map<std::pair<int, int>, double> depth;  // nearest depth per cell
    auto cell = [&](const Eigen::Vector3d& q) {
      return std::make_pair(int(std::floor(q.dot(side) / 4.0)), int(std::floor(q.y() / 4.0)));
    };
    for (Eigen::Index j = 0; j < dense.P.rows(); ++j) {
      const Eigen::Vector3d q = dense.P.row(j).transpose() - centre;
      const double d = 1200.0 - q.dot(dir);
      auto [it, fresh] = depth.emplace(cell(q), d);
      if (!fresh) it->second = std::min(it->second, d);
    }
    for (Eigen::Index j = 0; j < dense.P.rows(); ++j) {
      const Eigen::Vector3d q = dense.P.row(j).transpose() - centre;
      const double d = 1200.0 - q.dot(dir);
      const Eigen::Vector3d to_pillar = (1200.0 * dir - q).normalized();
      if (d <= depth[cell(q)] + 3.0 && dense.N.row(j).dot(to_pillar) > std::cos(75.0 * M_PI / 180.0))
        seen[j] = 1;
    }
  }
  PointCloud out;
  const int m = int(std::count(seen.begin(), seen.end(), 1));
  out.P.resize(m, 3);
  out.N.resize(m, 3);
  for (Eigen::Index j = 0, r = 0; j < dense.P.rows(); ++j)
    if (seen[j]) out.P.row(r) = dense.P.row(j), out.N.row(r++) = dense.N.row(j);
  return out;
}

struct HandCase {
  MakeHuman mh = MakeHuman::load();
  MakeHuman::Body body = mh.body(MacroSettings{});
  Pose truth;
  Mesh posed;
  PointCloud scan;
  std::vector<Landmark> landmarks;
  std::vector<int> phalanges;  // every finger bone (finger1-1 … finger5-3, both hands)

  // fists: the fingers of 'fight03'; else the fingers stay at rest (open hands). whole: all of
  // 'fight03' (fists raised before the face). points: scanned with that many points evenly over
  // the surface, ≤ 0: by the synthetic database's scanner.
  // subject: the scanned body's sliders (the template stays the default body).
  // right_forearm_twist_deg: the right forearm twisted about its bone (lowerarm02.R).
  explicit HandCase(bool fists = true, bool whole = false, int points = 60000,
                    const MacroSettings& subject = MacroSettings{},
                    double right_forearm_twist_deg = 0.0) {
    const Skeleton& sk = body.skeleton;
    const MakeHuman::Body scanned = mh.body(subject);
    truth = Pose::rest(sk.bone_count());
    truth.rotations[0] = rot(10, {0, 1, 0});
    truth.root_translation = {20, 0, -10};
    truth.rotations[sk.index("lowerarm01.L")] = rot(30, {0, 1, 0.4});
    truth.rotations[sk.index("upperarm01.R")] = rot(20, {1, 0, 0.5});
    // The fists of 'fight03' (70–90° per phalanx), fingers and thumbs.
    const Pose fight = poses_from_bvh(read_bvh(mh.pose_file("fight03")), sk, mh.directory())[0];
    for (int b = 0; b < sk.bone_count(); ++b)
      if (sk.names[b].rfind("finger", 0) == 0) {
        if (fists) truth.rotations[b] = fight.rotations[b];
        phalanges.push_back(b);
      } else if (whole && b > 0) {
        truth.rotations[b] = fight.rotations[b];
      }
    if (right_forearm_twist_deg != 0.0) {
      const int b = sk.index("lowerarm02.R");
      truth.rotations[b] =
          rot(right_forearm_twist_deg, (sk.tails.row(b) - sk.heads.row(b)).transpose());
    }
    posed = scanned.mesh;
    posed.V = pose_template(scanned.mesh.V, scanned.skeleton, scanned.weights, 1.0, truth);
    if (points > 0) {
      scan = test::scan_of(posed, points, 5, 1.0);
    } else {  // seen from four pillars, as the synthetic database's scanner
      scan = pillar_scan(test::scan_of(posed, -points, 5, 1.0));
    }
    for (const auto& [name, b] : std::vector<std::pair<const char*, const char*>>{
             {"head", "head"}, {"l_wrist", "wrist.L"}, {"r_wrist", "wrist.R"},
             {"l_foot", "foot.L"}, {"r_foot", "foot.R"}, {"l_elbow", "lowerarm01.L"},
             {"r_elbow", "lowerarm01.R"}, {"l_knee", "lowerleg01.L"},
             {"r_knee", "lowerleg01.R"}, {"spine", "spine03"}, {"l_hip", "upperleg02.L"},
             {"r_hip", "upperleg02.R"}, {"l_fingertip", "finger3-3.L"},
             {"r_fingertip", "finger3-3.R"}}) {
      const int bone = sk.index(b);
      int best = -1;
      double best_w = 0;
      for (int k = 0; k < body.weights.outerSize(); ++k)
        for (SkinWeights::InnerIterator it(body.weights, k); it; ++it)
          if (it.col() == bone && it.value() > best_w) best_w = it.value(), best = int(it.row());
      landmarks.push_back({best, posed.V.row(best).transpose(), name});
    }
  }

  // Median and max world-orientation error of the phalanges (degrees), mean vertex error of the
  // hands (mm).
  void errors(const PoseFitResult& r, double* median, double* max, double* hand_mm) const {
    const auto Qt = world_rotations(body.skeleton, truth), Qe = world_rotations(body.skeleton, r.pose);
    std::vector<double> e;
    for (int b : phalanges) e.push_back(rotation_angle_deg(Qe[b], Qt[b]));
    std::sort(e.begin(), e.end());
    *median = e[e.size() / 2];
    *max = e.back();
    double sum = 0;
    int count = 0;
    for (int i = 0; i < body.weights.outerSize(); ++i) {
      double w = 0;
      for (SkinWeights::InnerIterator it(body.weights, i); it; ++it)
        if (body.skeleton.names[it.col()].rfind("finger", 0) == 0) w += it.value();
      if (w >= 0.5) sum += (r.V.row(i) - posed.V.row(i)).norm(), ++count;
    }
    *hand_mm = sum / std::max(count, 1);
  }

  // The pose fit of the template to this case's scan.
  PoseFitResult fit(const PoseFitOptions& o, PoseFitSummary* summary) const {
    return fit_pose(body.mesh, body.skeleton, body.weights, scan, landmarks, o, summary);
  }

  // A fit with its summary and errors (as errors()).
  struct Measured {
    PoseFitResult r;
    PoseFitSummary s;
    double median = 0, max = 0, hand_mm = 0;
  };
  Measured measure(const PoseFitOptions& o) const {
    Measured m;
    m.r = fit(o, &m.s);
    errors(m.r, &m.median, &m.max, &m.hand_mm);
    return m;
  }

  // The largest world-orientation error over the named bones (degrees).
  double max_bone_error(const PoseFitResult& r, std::initializer_list<const char*> bones) const {
    const Skeleton& sk = body.skeleton;
    const auto Qt = world_rotations(sk, truth), Qe = world_rotations(sk, r.pose);
    double e = 0;
    for (const char* b : bones) e = std::max(e, rotation_angle_deg(Qe[sk.index(b)], Qt[sk.index(b)]));
    return e;
  }

  // Triangles of the fitted template whose normal opposes the truth's (as eval-registration).
  int flipped(const PoseFitResult& r) const {
    const Eigen::MatrixX3d Ne = face_normals(r.V, body.mesh.F), Nt = face_normals(posed.V, body.mesh.F);
    int count = 0;
    for (Eigen::Index f = 0; f < Nt.rows(); ++f) count += Ne.row(f).dot(Nt.row(f)) < 0;
    return count;
  }
};

TEST(PoseFitHands, RecoversFistCurl) {
  const HandCase c;
  PoseFitOptions with;
  with.parameters = hand_stage_pose_parameters();
  PoseFitOptions without = with;
  without.hand_iterations = 0;  // the fingers stay open
  PoseFitSummary s0, s1;
  const PoseFitResult r0 = c.fit(without, &s0);
  const PoseFitResult r1 = c.fit(with, &s1);
  double med0, max0, mm0, med1, max1, mm1;
  c.errors(r0, &med0, &max0, &mm0);
  c.errors(r1, &med1, &max1, &mm1);
  std::printf("open hands: phalanx error median %.1f°, max %.1f°, finger vertices %.1f mm\n",
              med0, max0, mm0);
  std::printf("hand stage (%d solves, %.2f s total): median %.1f°, max %.1f°, %.1f mm\n",
              s1.hand_iterations, s1.seconds, med1, max1, mm1);
  EXPECT_GT(med0, 60.0);  // the fists are really there
  EXPECT_LT(med1, 20.0);  // measured 16.3° (17.9° before the tied phase and wrist refit)
  EXPECT_LT(mm1, 10.0);  // measured 7.7 mm (52 mm with the fingers open)
}

// The fists fitted with the grasp groups (one rotation for the four fingers of a hand) and
// with the hand stage: the hand stage must leave fewer flipped triangles (a finger curled the
// wrong way flips its faces against the truth's).
TEST(PoseFitHands, HandStageFlipsFewerTrianglesThanTheGraspGroups) {
  const HandCase c;
  PoseFitOptions grasp;
  grasp.parameters = segment_pose_parameters();
  PoseFitOptions hands;
  hands.parameters = hand_stage_pose_parameters();
  PoseFitSummary s;
  const PoseFitResult r0 = c.fit(grasp, nullptr);
  const PoseFitResult r1 = c.fit(hands, &s);
  const int f0 = c.flipped(r0), f1 = c.flipped(r1);
  std::printf("flipped triangles on fists: grasp groups %d, hand stage %d (%d reverted, hand "
              "two-sided %.2f -> %.2f mm)\n",
              f0, f1, s.hand_reverted, s.hand_accept_before, s.hand_accept_after);
  EXPECT_LT(f1, f0);
  EXPECT_LE(f1, 75);  // measured 67 (grasp groups 70)
  EXPECT_LE(s.hand_accept_after, s.hand_accept_before);
}

// Open hands whose scan misses two fingers of the left hand (occluded): the hand stage must not
// curl the hand (the tied phase and the per-finger acceptance keep it open).
TEST(PoseFitHands, OpenHandsWithAnOccludedFingerStayOpen) {
  HandCase c(false);
  const Skeleton& sk = c.body.skeleton;
  std::vector<char> hidden_bone(sk.bone_count(), 0);
  for (const char* b : {"finger4-1.L", "finger4-2.L", "finger4-3.L", "finger5-1.L",
                        "finger5-2.L", "finger5-3.L"})
    hidden_bone[sk.index(b)] = 1;
  std::vector<char> hidden_vertex(c.posed.V.rows(), 0);
  for (int i = 0; i < c.body.weights.outerSize(); ++i) {
    double w = 0;
    for (SkinWeights::InnerIterator it(c.body.weights, i); it; ++it)
      if (hidden_bone[it.col()]) w += it.value();
    hidden_vertex[i] = w >= 0.5;
  }
  PointIndex vertices(c.posed.V);
  PointCloud holed;
  std::vector<int> keep;
  for (Eigen::Index j = 0; j < c.scan.P.rows(); ++j)
    if (!hidden_vertex[vertices.nearest(c.scan.P.row(j).transpose())]) keep.push_back(int(j));
  ASSERT_LT(keep.size(), size_t(c.scan.P.rows()) - 100);  // the hole is there
  holed.P.resize(keep.size(), 3);
  holed.N.resize(keep.size(), 3);
  for (size_t k = 0; k < keep.size(); ++k) {
    holed.P.row(k) = c.scan.P.row(keep[k]);
    holed.N.row(k) = c.scan.N.row(keep[k]);
  }
  PoseFitOptions o;
  o.parameters = hand_stage_pose_parameters();
  const PoseFitResult r = fit_pose(c.body.mesh, sk, c.body.weights, holed, c.landmarks, o);
  double med, max, mm;
  c.errors(r, &med, &max, &mm);
  std::printf("open hands, two fingers occluded: phalanx median %.1f°, max %.1f°, finger "
              "vertices %.1f mm, %d flipped\n", med, max, mm, c.flipped(r));
  EXPECT_LT(med, 2.0);   // measured 0.4°
  EXPECT_LT(max, 10.0);  // measured 4.7°
  EXPECT_LE(c.flipped(r), 3);  // measured 0
}

// Fists raised before the face (all of 'fight03'), seen by the pillar scanner so that the
// inside of each fist is a hole (s008_p3 of the synthetic database, where the open start alone
// turned the right wrist 58° and flipped 700 hand triangles). With the fist start the hands
// must be at least as good as from the open start alone, and within the measured bounds.
TEST(PoseFitHands, FistsWithUnscannedInside) {
  const HandCase c(true, true, -60000);
  PoseFitOptions open;
  open.parameters = hand_stage_pose_parameters();
  open.hand_start_curls_deg = {0.0};
  PoseFitOptions starts = open;
  starts.hand_start_curls_deg = PoseFitOptions{}.hand_start_curls_deg;
  ASSERT_GE(starts.hand_start_curls_deg.size(), 2u);
  PoseFitSummary s0, s1;
  const PoseFitResult r0 = c.fit(open, &s0);
  const PoseFitResult r1 = c.fit(starts, &s1);
  auto wrist_error = [&](const PoseFitResult& r) { return c.max_bone_error(r, {"wrist.L", "wrist.R"}); };
  double med0, max0, mm0, med1, max1, mm1;
  c.errors(r0, &med0, &max0, &mm0);
  c.errors(r1, &med1, &max1, &mm1);
  const int f0 = c.flipped(r0), f1 = c.flipped(r1);
  ASSERT_EQ(s1.hand_start_choice.size(), 2u);
  std::printf("fists, pillar scan (%d points): open start: wrists %.1f deg, phalanx median %.1f "
              "deg, finger vertices %.1f mm, %d flipped; with the fist start (kept %d/%d): wrists "
              "%.1f deg, median %.1f deg, %.1f mm, %d flipped\n",
              int(c.scan.P.rows()), wrist_error(r0), med0, mm0, f0, s1.hand_start_choice[0],
              s1.hand_start_choice[1], wrist_error(r1), med1, mm1, f1);
  std::printf("pose fit %.2f s with one start, %.2f s with the fist start (%d and %d hand solves)\n",
              s0.seconds, s1.seconds, s0.hand_iterations, s1.hand_iterations);
  EXPECT_LE(f1, f0);
  EXPECT_LT(wrist_error(r1), 24.0);  // measured 18.3
  EXPECT_LT(med1, 32.0);             // measured 27.8 (open hands: > 60)
  EXPECT_LE(f1, 122);                // measured 103
}

// The same fists: 'fight03' tucks each thumb across the palm (finger1-2 18°, finger1-3 65°),
// inside the fist where the pillar scanner does not see it (s008_p3 of the synthetic database,
// where the right thumb left straight flipped ~100 triangles). With the fist kept, its variant
// with tucked thumbs (third start, PoseFitOptions::hand_start_tucks_deg) must replace it and
// bring the thumb near the truth. Margin 0: these fists beat the open hand by less than the
// default margin (kept 0/0 above), which leaves the fist start nothing to do.
TEST(PoseFitHands, FistsTuckTheUnscannedThumb) {
  const HandCase c(true, true, -60000);
  PoseFitOptions straight;
  straight.parameters = hand_stage_pose_parameters();
  straight.hand_start_margin = 0.0;
  // The tuck alone (as before the forearms' twist): with it refitted, these fists at margin 0
  // are kept only on the left (the right hand kept the open start, then its twisted variant).
  straight.hand_forearm_twist = false;
  straight.wrist_twist_prior = 0.0;
  straight.hand_start_twists_deg = {};
  straight.hand_start_curls_deg = {0.0, 80.0};  // open and fist starts, thumbs straight
  straight.hand_start_tucks_deg = {};
  PoseFitOptions tucked = straight;
  tucked.hand_start_curls_deg = PoseFitOptions{}.hand_start_curls_deg;
  tucked.hand_start_tucks_deg = PoseFitOptions{}.hand_start_tucks_deg;
  ASSERT_GE(tucked.hand_start_curls_deg.size(), 3u);
  ASSERT_EQ(tucked.hand_start_tucks_deg[2], 40.0);
  PoseFitSummary s0, s1;
  const PoseFitResult r0 = c.fit(straight, &s0);
  const PoseFitResult r1 = c.fit(tucked, &s1);
  const Skeleton& sk = c.body.skeleton;
  // Right thumb: the larger world-orientation error of its two outer bones; thumb triangles:
  // faces whose three vertices are mostly on a thumb's bones (either hand).
  auto thumb_error = [&](const PoseFitResult& r) { return c.max_bone_error(r, {"finger1-2.R", "finger1-3.R"}); };
  std::vector<char> on_thumb(c.posed.V.rows(), 0);
  for (int i = 0; i < c.body.weights.outerSize(); ++i) {
    double w = 0;
    for (SkinWeights::InnerIterator it(c.body.weights, i); it; ++it)
      if (sk.names[it.col()].rfind("finger1", 0) == 0) w += it.value();
    on_thumb[i] = w >= 0.5;
  }
  auto thumb_flipped = [&](const PoseFitResult& r) {
    const Eigen::MatrixX3d Ne = face_normals(r.V, c.body.mesh.F);
    const Eigen::MatrixX3d Nt = face_normals(c.posed.V, c.body.mesh.F);
    int count = 0;
    for (Eigen::Index f = 0; f < Nt.rows(); ++f)
      if (on_thumb[c.body.mesh.F(f, 0)] && on_thumb[c.body.mesh.F(f, 1)] &&
          on_thumb[c.body.mesh.F(f, 2)])
        count += Ne.row(f).dot(Nt.row(f)) < 0;
    return count;
  };
  const double e0 = thumb_error(r0), e1 = thumb_error(r1);
  const int t0 = thumb_flipped(r0), t1 = thumb_flipped(r1);
  ASSERT_EQ(s0.hand_start_choice.size(), 2u);
  ASSERT_EQ(s1.hand_start_choice.size(), 2u);
  std::printf("fists, pillar scan: thumbs straight (starts kept %d/%d): right thumb error %.1f "
              "deg, %d thumb / %d flipped; with the tucked start (kept %d/%d): %.1f deg, %d / %d "
              "flipped; pose fit %.2f s and %.2f s\n",
              s0.hand_start_choice[0], s0.hand_start_choice[1], e0, t0, c.flipped(r0),
              s1.hand_start_choice[0], s1.hand_start_choice[1], e1, t1, c.flipped(r1), s0.seconds,
              s1.seconds);
  EXPECT_EQ(s0.hand_start_choice[1], 1);  // the right fist is kept
  EXPECT_EQ(s1.hand_start_choice[1], 2);  // and its thumbs tucked
  EXPECT_GT(e0, 60.0);                    // the thumb really is tucked
  EXPECT_LT(e1, 44.0);                    // measured 37.9 (straight: 91.1)
  EXPECT_LE(t1, 40);                      // measured 35 (straight: 81)
  EXPECT_LT(t1, t0);
  EXPECT_LT(c.flipped(r1), c.flipped(r0));
}

// Open hands of a subject unlike the template, seen by the pillar scanner: the fist start must
// not replace them (s003_p0: compared as posed, a hand 10 mm off looked closer to the scan
// curled into a fist, and 1137 hand triangles flipped).
TEST(PoseFitHands, OpenHandsKeepTheOpenStart) {
  MacroSettings subject;
  subject.weight = 0.2;
  subject.gender = 1.0;
  subject.muscle = 0.9;
  const HandCase c(false, false, -60000, subject);
  PoseFitOptions o;
  o.parameters = hand_stage_pose_parameters();
  PoseFitSummary s;
  const PoseFitResult r = c.fit(o, &s);
  double med, max, mm;
  c.errors(r, &med, &max, &mm);
  ASSERT_EQ(s.hand_start_choice.size(), 2u);
  std::printf("open hands, other subject, pillar scan: starts kept %d/%d, phalanx median %.1f, "
              "max %.1f deg, %.1f mm, %d flipped\n", s.hand_start_choice[0], s.hand_start_choice[1],
              med, max, mm, c.flipped(r));
  // Neither the fist nor the fist with tucked thumbs: the open start or the body stage's
  // (open) hand, index 5 (PoseFitOptions::hand_compare_body_stage).
  for (int h = 0; h < 2; ++h)
    EXPECT_TRUE(s.hand_start_choice[h] == 0 || s.hand_start_choice[h] == 5) << h;
  EXPECT_LT(med, 10.0);  // measured 7.9 (a fist: > 60)
  EXPECT_LE(c.flipped(r), 3);  // measured 0
}

// An open right hand turned palm out by its forearm (lowerarm02.R twisted 110°): the surface of
// the near-cylindrical forearm hardly shows the twist, and the hand stage started from the body
// stage's untwisted forearm ends in a local minimum (s017_p4 of the synthetic database: the right
// forearm 90° off, 2 700 flipped triangles). The starts with the forearm twisted ±90°
// (PoseFitOptions::hand_start_twists_deg) must find it.
TEST(PoseFitHands, TwistStartsTurnAPalmOutHand) {
  const HandCase c(false, false, -60000, MacroSettings{}, 110.0);
  PoseFitOptions twisted;  // the defaults
  twisted.parameters = hand_stage_pose_parameters();
  ASSERT_TRUE(twisted.hand_forearm_twist);
  ASSERT_EQ(twisted.hand_start_twists_deg, (std::vector<double>{0.0, 0.0, 0.0, 90.0, -90.0}));
  PoseFitOptions untwisted = twisted;  // the three starts before the twisted ones
  untwisted.hand_start_curls_deg = {0.0, 80.0, 80.0};
  untwisted.hand_start_tucks_deg = {0.0, 0.0, 40.0};
  untwisted.hand_start_twists_deg = {};
  PoseFitSummary s0, s1;
  const PoseFitResult r0 = c.fit(untwisted, &s0);
  const PoseFitResult r1 = c.fit(twisted, &s1);
  auto hand_error = [&](const PoseFitResult& r) {
    return c.max_bone_error(r, {"wrist.R", "finger3-1.R", "finger1-1.R"});
  };
  const double e0 = hand_error(r0), e1 = hand_error(r1);
  const int f0 = c.flipped(r0), f1 = c.flipped(r1);
  ASSERT_EQ(s1.hand_start_choice.size(), 2u);
  std::printf("right forearm twisted 110 deg: untwisted starts: right hand %.1f deg, %d flipped; "
              "with the twist starts (kept %d/%d): %.1f deg, %d flipped; pose fit %.2f s and "
              "%.2f s\n", e0, f0, s1.hand_start_choice[0], s1.hand_start_choice[1], e1, f1,
              s0.seconds, s1.seconds);
  EXPECT_GT(e0, 60.0);  // the untwisted starts miss it: measured 124.9°, 3 006 flipped
  EXPECT_LT(e1, 20.0);  // measured 17.8°
  EXPECT_LE(f1, 10);    // measured 0
  EXPECT_LT(f1, f0);
}

// The hand stage's result is kept only if it brings the hand closer to the scan than the body
// stage's hand (PoseFitOptions::hand_compare_body_stage). Open hands fitted from fist starts
// only (a start set that leads every hand astray) end as fists; the comparison must give back
// the body stage's open hands.
TEST(PoseFitHands, BodyStageHandWhenTheHandStageGoesAstray) {
  const HandCase c(false, false, -60000);
  PoseFitOptions o;
  o.parameters = hand_stage_pose_parameters();
  ASSERT_TRUE(o.hand_compare_body_stage);  // on by default
  o.hand_start_curls_deg = {80.0, 80.0};   // the fist, and the fist with tucked thumbs
  o.hand_start_tucks_deg = {0.0, 40.0};
  o.hand_start_twists_deg = {};
  PoseFitOptions without = o;
  without.hand_compare_body_stage = false;
  const HandCase::Measured m0 = c.measure(without), m1 = c.measure(o);
  ASSERT_EQ(m1.s.hand_start_choice.size(), 2u);
  std::printf("open hands from fist starts: without the comparison phalanx median %.1f deg, hands "
              "%.1f mm, %d flipped; with it (kept %d/%d) %.1f deg, %.1f mm, %d flipped\n",
              m0.median, m0.hand_mm, c.flipped(m0.r), m1.s.hand_start_choice[0],
              m1.s.hand_start_choice[1], m1.median, m1.hand_mm, c.flipped(m1.r));
  EXPECT_GT(m0.median, 60.0);  // fists: measured 108.5°, 50.2 mm, 1 176 flipped
  EXPECT_EQ(m1.s.hand_start_choice[0], 2);  // index 2 = the number of starts: the body stage
  EXPECT_EQ(m1.s.hand_start_choice[1], 2);
  EXPECT_LT(m1.median, 5.0);  // measured 1.1°, 1.1 mm, 0 flipped
  EXPECT_LT(m1.hand_mm, 5.0);
  EXPECT_LE(c.flipped(m1.r), 3);
}

}  // namespace
}  // namespace bodymodel
