// Cleaning a dense-marker capture (markers/clean.h) and simulating one (markers/simulate.h):
// known answers on a synthetic moving body, then the figures on the Vlasic "jumping"
// capture (long tests; the crane sequence is kept for the final figure in docs/markers.md).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/mesh_io.h"
#include "markers/c3d.h"
#include "markers/clean.h"
#include "markers/simulate.h"

namespace bodymodel {
namespace {

TEST(MarkerSpline, NaturalSplineIsExactOnLinesAndLeavesTheEndsOpen) {
  Eigen::VectorXd x(10);
  for (int t = 0; t < 10; ++t) x(t) = 3 + 2 * t;
  Eigen::VectorXd holed = x;
  holed(0) = holed(4) = holed(5) = holed(9) = std::nan("");
  const Eigen::VectorXd s = spline_fill(holed);
  EXPECT_TRUE(std::isnan(s(0)) && std::isnan(s(9))) << "no extrapolation";
  for (int t = 1; t < 9; ++t) EXPECT_NEAR(s(t), x(t), 1e-12);
}

// A body of two "limbs" (markers on two spheres) that moves, turns and bends at a joint: the
// second sphere swings about a point between them, so the motion is not one rigid motion.
MarkerData moving_body(int frames, std::mt19937& rng) {
  const int per = 60;
  // Evenly spread (a Fibonacci sphere), as dense markers are placed; a random twist per body.
  const double twist = std::uniform_real_distribution<double>(0, 6.28)(rng);
  std::vector<Eigen::Vector3d> dirs;
  for (int k = 0; k < per; ++k) {
    const double z = 1 - 2 * (k + 0.5) / per, r = std::sqrt(1 - z * z), phi = twist + k * 2.399963;
    dirs.emplace_back(r * std::cos(phi), z, r * std::sin(phi));
  }
  MarkerData d;
  for (int m = 0; m < 2 * per; ++m) d.labels.push_back("M" + std::to_string(m + 1));
  d.rate = 120;
  d.xyz.resize(frames, 6 * per);
  for (int t = 0; t < frames; ++t) {
    const double a = 0.03 * t, swing = 0.6 * std::sin(0.05 * t);
    const Eigen::Matrix3d R = Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()).toRotationMatrix();
    const Eigen::Matrix3d S = Eigen::AngleAxisd(swing, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d move(300 * std::sin(0.02 * t), 50 * std::sin(0.1 * t), 2 * t);
    for (int k = 0; k < per; ++k) {
      d.set(t, k, R * (150 * dirs[k]) + move);
      const Eigen::Vector3d limb = S * (Eigen::Vector3d(0, -320, 0) + 140 * dirs[k]) + Eigen::Vector3d(0, -100, 0);
      d.set(t, per + k, R * limb + move);
    }
  }
  return d;
}

// The truth cut into a capture: gaps of 5–60 frames, the sample after each gap an unlabelled
// piece, 1 mm noise.
MarkerData gappy(const MarkerData& truth, double missing, std::mt19937& rng) {
  const int T = truth.frame_count(), M = truth.marker_count();
  std::vector<std::vector<char>> seen(T, std::vector<char>(M, 1));
  std::uniform_int_distribution<int> marker(0, M - 1), len(5, 60);
  long gone = 0;
  while (gone < missing * T * M) {
    const int m = marker(rng), l = len(rng), s = std::uniform_int_distribution<int>(1, T - l)(rng);
    for (int t = s; t < s + l; ++t) gone += seen[t][m], seen[t][m] = 0;
  }
  std::normal_distribution<double> noise(0, 1);
  MarkerData c = truth;
  std::vector<Eigen::VectorXd> pieces;
  for (int m = 0; m < M; ++m) {
    bool first = true;
    for (int t = 0; t < T; ++t) {
      if (!seen[t][m]) {
        c.clear(t, m);
        continue;
      }
      if (t > 0 && !seen[t - 1][m]) first = false, pieces.push_back(Eigen::VectorXd::Constant(3 * T, std::nan("")));
      const Eigen::Vector3d p = truth.at(t, m) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      if (first) c.set(t, m, p);
      else c.clear(t, m), pieces.back().segment<3>(3 * t) = p;
    }
  }
  c.xyz.conservativeResize(Eigen::NoChange, 3 * (M + pieces.size()));
  for (size_t p = 0; p < pieces.size(); ++p) {
    c.labels.push_back("*" + std::to_string(p + 1));
    for (int t = 0; t < T; ++t) c.xyz.block<1, 3>(t, 3 * (M + p)) = pieces[p].segment<3>(3 * t).transpose();
  }
  return c;
}

TEST(MarkerClean, MergesEveryPieceAndFillsBetterThanSplinesOnAMovingBody) {
  std::mt19937 rng(7);
  const MarkerData truth = moving_body(250, rng);
  const MarkerData capture = gappy(truth, 0.2, rng);
  const CleanResult r = clean_markers(capture);
  const CleanEvaluation e = evaluate_cleaning(capture, r, truth);
  EXPECT_EQ(e.wrong_merges, 0);
  EXPECT_EQ(e.missed_pieces, 0);
  EXPECT_EQ(r.report.merged, r.report.pieces);
  EXPECT_EQ(r.report.gaps_left, 0);
  EXPECT_GT(e.filled, 0.15 * 250 * 120);
  EXPECT_LT(e.median_fill_mm, 3.0) << "two rigid parts and a joint: the neighbours predict a hole within noise";
  EXPECT_LT(e.ratio_to_spline, 0.5);
  ASSERT_TRUE(r.cleaned.xyz.allFinite());
}

TEST(MarkerClean, LeavesGhostsAndRefusesAnIncompleteReferenceFrame) {
  std::mt19937 rng(8);
  const MarkerData truth = moving_body(120, rng);
  MarkerData capture = gappy(truth, 0.1, rng);
  const int g = capture.marker_count();
  capture.labels.push_back("*ghost");
  capture.xyz.conservativeResize(Eigen::NoChange, 3 * (g + 1));
  for (int t = 0; t < capture.frame_count(); ++t)
    if (t >= 30 && t < 40) capture.set(t, g, truth.at(t, 5) + Eigen::Vector3d(0, 0, 120));
    else capture.clear(t, g);
  const CleanResult r = clean_markers(capture);
  EXPECT_NE(std::find(r.report.unmerged.begin(), r.report.unmerged.end(), "*ghost"), r.report.unmerged.end());
  EXPECT_EQ(evaluate_cleaning(capture, r, truth).wrong_merges, 0);
  capture.clear(0, 3);
  try {
    clean_markers(capture);
    ADD_FAILURE() << "a labelled marker missing in the reference frame must be refused";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'M4' is missing in the reference frame"), std::string::npos) << e.what();
  }
}

// The report's gaps (the pictures and the viewer draw the filled samples from them): every run of
// missing samples after merging, per marker, once; they cover exactly the samples the cleaning filled.
TEST(MarkerClean, ReportListsEveryGapAfterMerging) {
  MarkerData d;
  d.labels = {"A", "B"};
  d.xyz = Eigen::MatrixXd::Zero(10, 6);
  for (int t : {2, 3, 4, 9}) d.clear(t, 0);
  d.clear(0, 1);
  const std::vector<GapRecord> g = find_gaps(d);
  ASSERT_EQ(g.size(), 3u);
  EXPECT_EQ(g[0].marker, "A"); EXPECT_EQ(g[0].first, 2); EXPECT_EQ(g[0].last, 4);
  EXPECT_EQ(g[1].marker, "A"); EXPECT_EQ(g[1].first, 9); EXPECT_EQ(g[1].last, 9);
  EXPECT_EQ(g[2].marker, "B"); EXPECT_EQ(g[2].first, 0); EXPECT_EQ(g[2].last, 0);

  std::mt19937 rng(8);
  const MarkerData truth = moving_body(120, rng);
  const CleanResult r = clean_markers(gappy(truth, 0.1, rng));
  long samples = 0;
  for (const GapRecord& gap : r.report.gaps) {
    samples += gap.last - gap.first + 1;
    const int i = static_cast<int>(std::find(r.merged.labels.begin(), r.merged.labels.end(), gap.marker) - r.merged.labels.begin());
    ASSERT_LT(i, r.merged.marker_count());
    for (int t = gap.first; t <= gap.last; ++t) EXPECT_FALSE(r.merged.present(t, i));
    if (gap.first > 0) EXPECT_TRUE(r.merged.present(gap.first - 1, i));
    if (gap.last + 1 < r.merged.frame_count()) EXPECT_TRUE(r.merged.present(gap.last + 1, i));
  }
  EXPECT_GT(samples, 0);
  EXPECT_EQ(samples, r.report.samples_missing);
  EXPECT_EQ(static_cast<int>(r.report.gaps.size()), r.report.gaps_after_merge);
  EXPECT_EQ(clean_report_json(r.report)["gaps"].size(), r.report.gaps.size());
}

// A known answer for the neighbourhood-model check: markers A and B are both missing over frames
// 100–129 and one piece carries B's samples there. A's samples just before and after the gap were
// swapped onto B's place (a confusion), so A's rigid prediction follows B exactly; B's own samples
// there are 40 mm off (a glitch), so B's prediction misses the piece by more than a1. The rigid test
// gives the piece to A (checked with the check off), A's models, which learnt where A sits among its
// neighbours, disagree by a spacing and B's models agree: the merge into A is undone.
TEST(MarkerClean, UndoesAMergeTheNeighbourhoodModelsDisagreeWith) {
  std::mt19937 rng(11);
  const MarkerData truth = moving_body(250, rng);
  const int a = 5;
  int b = -1;
  for (int m = 0; m < 60; ++m)
    if (m != a && (b < 0 || (truth.at(0, m) - truth.at(0, a)).norm() < (truth.at(0, b) - truth.at(0, a)).norm())) b = m;
  MarkerData capture = truth;
  std::normal_distribution<double> noise(0, 1);
  for (int t = 0; t < capture.frame_count(); ++t)
    for (int m = 0; m < capture.marker_count(); ++m)
      capture.set(t, m, truth.at(t, m) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  const int M = truth.marker_count();
  capture.labels.push_back("*1");
  capture.xyz.conservativeResize(Eigen::NoChange, 3 * (M + 1));
  for (int t = 0; t < capture.frame_count(); ++t) capture.clear(t, M);
  for (int t = 100; t < 130; ++t) {
    capture.set(t, M, capture.at(t, b));
    capture.clear(t, a), capture.clear(t, b);
  }
  for (int t : {99, 130}) {
    const Eigen::Vector3d away = (truth.at(t, b) - truth.at(t, a)).normalized();
    capture.set(t, a, truth.at(t, b));
    capture.set(t, b, truth.at(t, b) + 40 * away);
  }
  const std::string A = truth.labels[a], B = truth.labels[b];
  auto went_to = [](const CleanReport& r, const std::string& marker) {
    return std::any_of(r.merges.begin(), r.merges.end(), [&](const MergeRecord& m) { return m.piece == "*1" && m.marker == marker; });
  };
  CleanOptions o;
  o.ambiguity = 0;  // the ambiguity test would leave the piece alone: the model check is what is tested
  o.part_check = 0;  // the parts' check refuses it too (its own test below)
  o.model_tolerance = 0;
  const CleanResult unchecked = clean_markers(capture, o);
  ASSERT_TRUE(went_to(unchecked.report, A)) << "the setup must fool the rigid prediction";
  EXPECT_EQ(evaluate_cleaning(capture, unchecked, truth).wrong_merges, 1);
  o.model_tolerance = CleanOptions{}.model_tolerance;
  const CleanResult r = clean_markers(capture, o);
  EXPECT_FALSE(went_to(r.report, A));
  ASSERT_EQ(r.report.undone.size(), 1u);
  EXPECT_EQ(r.report.undone[0].piece, "*1");
  EXPECT_EQ(r.report.undone[0].marker, A);
  EXPECT_GT(r.report.undone[0].mean_distance_mm, 40) << "the models put A where it was, a spacing from B";
  EXPECT_EQ(evaluate_cleaning(capture, r, truth).wrong_merges, 0);
}

// A known answer for the parts' check of merges (refusal): the setup of the test above, A's samples
// next to the gap swapped onto B's place so that A's rigid prediction follows B's piece. With the
// model check off, the merge into A is made without the parts' check and refused with it: the piece
// keeps B's distances to B's part (both spheres are rigid: within noise) and strays from A's by
// tens of millimetres.
TEST(MarkerClean, PartCheckRefusesAPieceThatKeepsAnotherMarkersPartDistances) {
  std::mt19937 rng(11);
  const MarkerData truth = moving_body(250, rng);
  const int a = 5, M = truth.marker_count();
  int b = -1;
  for (int m = 0; m < 60; ++m)
    if (m != a && (b < 0 || (truth.at(0, m) - truth.at(0, a)).norm() < (truth.at(0, b) - truth.at(0, a)).norm())) b = m;
  MarkerData capture = truth;
  std::normal_distribution<double> noise(0, 1);
  for (int t = 0; t < capture.frame_count(); ++t)
    for (int m = 0; m < M; ++m) capture.set(t, m, truth.at(t, m) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  capture.labels.push_back("*1");
  capture.xyz.conservativeResize(Eigen::NoChange, 3 * (M + 1));
  for (int t = 0; t < capture.frame_count(); ++t) capture.clear(t, M);
  for (int t = 100; t < 130; ++t) capture.set(t, M, capture.at(t, b)), capture.clear(t, a), capture.clear(t, b);
  for (int t : {99, 130}) {
    const Eigen::Vector3d away = (truth.at(t, b) - truth.at(t, a)).normalized();
    capture.set(t, a, truth.at(t, b));
    capture.set(t, b, truth.at(t, b) + 40 * away);
  }
  const std::string A = truth.labels[a];
  auto went_to_a = [&](const CleanReport& r) {
    return std::any_of(r.merges.begin(), r.merges.end(), [&](const MergeRecord& m) { return m.piece == "*1" && m.marker == A; });
  };
  CleanOptions o;
  o.ambiguity = 0;
  o.model_tolerance = 0;
  o.part_check = 0;
  const CleanResult unchecked = clean_markers(capture, o);
  ASSERT_TRUE(went_to_a(unchecked.report)) << "the setup must fool the rigid prediction";
  EXPECT_EQ(evaluate_cleaning(capture, unchecked, truth).wrong_merges, 1);
  o.part_check = CleanOptions{}.part_check;
  const CleanResult r = clean_markers(capture, o);
  EXPECT_FALSE(went_to_a(r.report));
  EXPECT_TRUE(r.report.undone.empty()) << "refused before it is merged, not undone";
  EXPECT_EQ(evaluate_cleaning(capture, r, truth).wrong_merges, 0);
}

// A known answer for the parts' check of merges (ghost): marker A is missing over frames 100–105
// and a ghost piece of those frames sits 60 mm off A (outward from the sphere), moving with the body; A's
// samples at 99 and 106 are glitched onto the ghost's place, so A's rigid prediction follows the
// ghost. No other marker is missing, so the neighbourhood models' check has no better marker and
// keeps the merge (checked with the parts' check off); the ghost's distances to A's part stray by
// more than 3 · part_rigidity and it is taken out.
TEST(MarkerClean, PartCheckTakesOutAGhostNoOtherMarkerExplains) {
  std::mt19937 rng(14);
  const MarkerData truth = moving_body(250, rng);
  const int a = 7, M = truth.marker_count();
  MarkerData capture = truth;
  std::normal_distribution<double> noise(0, 1);
  for (int t = 0; t < capture.frame_count(); ++t)
    for (int m = 0; m < M; ++m) capture.set(t, m, truth.at(t, m) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  capture.labels.push_back("*ghost");
  capture.xyz.conservativeResize(Eigen::NoChange, 3 * (M + 1));
  for (int t = 0; t < capture.frame_count(); ++t) capture.clear(t, M);
  // Outward from the sphere at A (its centre: the mean of its 60 markers).
  auto ghost_at = [&](int t) {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int m = 0; m < 60; ++m) centre += truth.at(t, m) / 60;
    const Eigen::Vector3d radial = (truth.at(t, a) - centre).normalized();
    return Eigen::Vector3d(truth.at(t, a) + 60 * radial);
  };
  for (int t = 100; t < 106; ++t) capture.set(t, M, ghost_at(t)), capture.clear(t, a);
  for (int t : {99, 106}) capture.set(t, a, ghost_at(t));
  auto merged = [](const CleanReport& r) {
    return std::any_of(r.merges.begin(), r.merges.end(), [](const MergeRecord& m) { return m.piece == "*ghost"; });
  };
  CleanOptions o;
  o.part_check = 0;
  const CleanResult unchecked = clean_markers(capture, o);
  ASSERT_TRUE(merged(unchecked.report)) << "the setup must fool the rigid prediction and the model check";
  EXPECT_EQ(evaluate_cleaning(capture, unchecked, truth).wrong_merges, 1);
  const CleanResult r = clean_markers(capture);
  EXPECT_FALSE(merged(r.report));
  ASSERT_EQ(r.report.undone.size(), 1u);
  EXPECT_EQ(r.report.undone[0].piece, "*ghost");
  EXPECT_EQ(r.report.unmerged, std::vector<std::string>{"*ghost"});
  EXPECT_EQ(evaluate_cleaning(capture, r, truth).wrong_merges, 0);
}

// A known answer for the matching by the neighbourhood models: marker B is missing over frames
// 100–129 and one piece carries its samples there, but B's samples just before and after the gap
// are 50 mm off (a glitch), so B's rigid prediction misses the piece by more than a1 and nothing
// takes it (checked with the model rounds off; the rounds against the filled trajectories are off
// too, to test the model rounds alone). B's models, fitted on the frames where B and its neighbours
// are all seen, place the piece within noise: it goes to B.
TEST(MarkerClean, NeighbourhoodModelsMergeAPieceTheRigidPredictionMisses) {
  std::mt19937 rng(12);
  const MarkerData truth = moving_body(250, rng);
  const int b = 17, M = truth.marker_count();
  MarkerData capture = truth;
  std::normal_distribution<double> noise(0, 1);
  for (int t = 0; t < capture.frame_count(); ++t)
    for (int m = 0; m < M; ++m) capture.set(t, m, truth.at(t, m) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  capture.labels.push_back("*1");
  capture.xyz.conservativeResize(Eigen::NoChange, 3 * (M + 1));
  for (int t = 0; t < capture.frame_count(); ++t) capture.clear(t, M);
  for (int t = 100; t < 130; ++t) capture.set(t, M, capture.at(t, b)), capture.clear(t, b);
  for (int t : {99, 130}) capture.set(t, b, truth.at(t, b) + Eigen::Vector3d(0, 50, 0));
  CleanOptions o;
  o.rounds = 0;
  o.model_rounds = 0;
  o.part_rigidity = 0;  // the rigid parts would merge it too (their own test): the model rounds alone
  const CleanResult unmatched = clean_markers(capture, o);
  ASSERT_EQ(unmatched.report.unmerged, std::vector<std::string>{"*1"}) << "the setup must defeat the rigid prediction";
  o.model_rounds = 1;
  const CleanResult r = clean_markers(capture, o);
  ASSERT_EQ(r.report.merges.size(), 1u);
  EXPECT_EQ(r.report.merges[0].marker, truth.labels[b]);
  EXPECT_LT(r.report.merges[0].mean_distance_mm, 5) << "the models place the piece within noise";
  const CleanEvaluation e = evaluate_cleaning(capture, r, truth);
  EXPECT_EQ(e.wrong_merges, 0);
  EXPECT_EQ(e.missed_pieces, 0);
}

// A known answer for the rigid parts: a torso (60 markers on a sphere) and a hand (6 markers on a
// small sphere) resting against its side in the reference frame, which then swings about a pivot
// above it, so the hand's nearest markers in the reference frame are partly the torso's. Hand marker
// H is missing over frames 100–219 and its samples over 160–219 come as one piece. The hand's own
// markers (the part found from the capture: their distances stay fixed) carry H; the one-ring, which
// must take torso markers to have six, does not (checked with the parts off).
MarkerData torso_and_hand(int frames, std::mt19937& rng) {
  const int torso = 60, hand = 6;
  std::vector<Eigen::Vector3d> dirs;
  for (int k = 0; k < torso; ++k) {
    const double z = 1 - 2 * (k + 0.5) / torso, r = std::sqrt(1 - z * z), phi = k * 2.399963;
    dirs.emplace_back(r * std::cos(phi), z, r * std::sin(phi));
  }
  const std::vector<Eigen::Vector3d> hdirs = {{-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}, {1, 0, 0}};
  MarkerData d;
  for (int m = 0; m < torso + hand; ++m) d.labels.push_back("M" + std::to_string(m + 1));
  d.rate = 120;
  d.xyz.resize(frames, 3 * (torso + hand));
  std::normal_distribution<double> noise(0, 1);
  const Eigen::Vector3d pivot(0, 350, 0), centre0(195, 0, 0);
  for (int t = 0; t < frames; ++t) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.01 * t, Eigen::Vector3d::UnitY()).toRotationMatrix();
    const Eigen::Matrix3d S = Eigen::AngleAxisd(0.7 * std::sin(0.04 * t), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d move(200 * std::sin(0.02 * t), 30 * std::sin(0.1 * t), 2 * t);
    auto jitter = [&] { return Eigen::Vector3d(noise(rng), noise(rng), noise(rng)); };
    for (int k = 0; k < torso; ++k) d.set(t, k, R * (150 * dirs[k]) + move + jitter());
    for (int k = 0; k < hand; ++k) d.set(t, torso + k, R * (pivot + S * (centre0 + 45 * hdirs[k] - pivot)) + move + jitter());
  }
  return d;
}

TEST(MarkerClean, RigidPartPredictsAMarkerOnASwingingHandTheOneRingMisses) {
  std::mt19937 rng(13);
  const MarkerData truth = torso_and_hand(320, rng);
  const int h = 60, M = truth.marker_count();  // H: the hand marker facing the torso
  MarkerData capture = truth;
  capture.labels.push_back("*1");
  capture.xyz.conservativeResize(Eigen::NoChange, 3 * (M + 1));
  for (int t = 0; t < capture.frame_count(); ++t) capture.clear(t, M);
  for (int t = 100; t < 220; ++t) {
    if (t >= 160) capture.set(t, M, capture.at(t, h));
    capture.clear(t, h);
  }
  CleanOptions o;
  o.part_rigidity = 0;
  const CleanResult without = clean_markers(capture, o);
  const CleanEvaluation ew = evaluate_cleaning(capture, without, truth);
  EXPECT_GT(ew.median_fill_mm, 10) << "the setup must defeat the one-ring's prediction";
  const CleanResult r = clean_markers(capture);
  const CleanEvaluation e = evaluate_cleaning(capture, r, truth);
  ASSERT_EQ(r.report.merges.size(), 1u) << "the piece goes to H";
  EXPECT_EQ(r.report.merges[0].marker, truth.labels[h]);
  EXPECT_EQ(e.wrong_merges, 0);
  EXPECT_EQ(e.filled, 60) << "frames 100–159";
  EXPECT_LT(e.median_fill_mm, 3.0) << "the hand's own markers carry H within noise";
  std::cout << "one-ring: " << evaluation_json(ew).dump() << "\nparts: " << evaluation_json(e).dump() << "\n";
}

// ---- the Vlasic "jumping" capture (long tests) ---------------------------------------------------

struct Jumping {
  std::vector<Eigen::MatrixX3d> frames;
  Eigen::MatrixX3i F;
};

const Jumping& jumping() {
  static const Jumping j = [] {
    Jumping j;
    std::vector<std::filesystem::path> files;
    for (const auto& e : std::filesystem::directory_iterator(data_root() / "animations" / "vlasic-jumping"))
      if (e.path().extension() == ".obj") files.push_back(e.path());
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      Mesh m = read_mesh(f);
      j.frames.push_back(m.V);
      j.F = m.F;
    }
    return j;
  }();
  return j;
}

const SimulatedCapture& jumping_capture() {
  static const SimulatedCapture s = simulate_capture(jumping().frames, jumping().F, SimulateOptions{});
  return s;
}

TEST(MarkersJumping, SimulatedCaptureIsRealisticAndItsPiecesAreTheirMarkers) {
  const SimulatedCapture& s = jumping_capture();
  EXPECT_EQ(s.truth.marker_count(), 350);
  EXPECT_EQ(s.truth.frame_count(), 29 * 12 + 1) << "10 fps meshes at 120 Hz";
  EXPECT_GE(s.missing, 0.15);
  EXPECT_GT(s.occluded, 0.01) << "the cameras miss some markers by themselves";
  EXPECT_EQ(s.broken, 18);
  EXPECT_GT(s.spacing_mm, 40);
  EXPECT_LT(s.spacing_mm, 110);
  for (int m = 0; m < 350; ++m) ASSERT_TRUE(s.capture.present(0, m)) << "the reference frame is complete";
  int ghosts = 0;
  for (size_t p = 0; p < s.pieces.size(); ++p) {
    const int col = 350 + static_cast<int>(p);
    ASSERT_EQ(s.capture.labels[col], s.pieces[p].label);
    if (s.pieces[p].marker < 0) {
      ++ghosts;
      continue;
    }
    for (int t = s.pieces[p].first; t <= s.pieces[p].last; ++t)
      ASSERT_LT((s.capture.at(t, col) - s.truth.at(t, s.pieces[p].marker)).norm(), 8.0) << "1 mm noise per axis";
  }
  EXPECT_EQ(ghosts, 5);
  const MarkerData again = parse_c3d(c3d_bytes(s.capture), "capture.c3d");
  EXPECT_EQ(again.labels, s.capture.labels);
}

// The figures on the development capture (crane is measured once, in docs/markers.md).
// Reached: holes of 5–60 frames filled within a median 5 mm and under half the spline's error.
// Not reached yet (asserted at what the method does, so a regression fails): no wrong merges (2
// since the rigid parts, which merge 29 more pieces: docs/markers.md), every piece merged, and every
// hole's median within 5 mm.
TEST(MarkersJumping, CleaningMergesAndFillsHolesOfFiveToSixtyFramesWithinFiveMillimetres) {
  const SimulatedCapture& s = jumping_capture();
  const CleanResult r = clean_markers(s.capture);
  const CleanEvaluation e = evaluate_cleaning(s.capture, r, s.truth);
  EXPECT_EQ(e.wrong_merges, 0);
  EXPECT_LE(e.missed_pieces, 31);
  EXPECT_GE(r.report.merged, r.report.pieces * 95 / 100);
  EXPECT_GE(double(r.report.samples_missing) / (350.0 * s.truth.frame_count()), 0.15);
  EXPECT_GT(e.gap_5_60, 5000);
  EXPECT_LE(e.median_5_60_mm, 5.0);
  EXPECT_LT(e.ratio_5_60, 0.5);
  EXPECT_LE(e.median_fill_mm, 6.0) << "every hole, including those running to the end of the capture";
  EXPECT_EQ(r.report.gaps_left, 0);
  ASSERT_TRUE(r.cleaned.xyz.allFinite());
  std::cout << clean_summary_line(r.report) << "\n" << evaluation_json(e).dump() << "\n";
}

}  // namespace
}  // namespace bodymodel
