// Named anatomical landmarks of the hm08 body template (vertex indices into vertices 0…13379).
//
// Chosen once on the MakeHuman base mesh: the body vertex nearest to a skeleton joint (or to a
// fixed offset from it, e.g. the front of the knee), symmetric left/right ('l' = +x, the
// character's left). The synthetic scan database places its noisy landmarks at these vertices of
// the posed true mesh; registration pulls the same template vertices towards them.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace bodymodel {

inline const std::vector<std::pair<std::string, int>>& body_landmarks() {
  static const std::vector<std::pair<std::string, int>> table = {
      {"head_top", 881},      {"chin", 747},          {"neck_back", 1491},
      {"sternum", 1890},      {"navel", 4367},        {"l_shoulder", 8226},
      {"r_shoulder", 1547},   {"l_elbow", 10025},     {"r_elbow", 3357},
      {"l_wrist", 10548},     {"r_wrist", 3883},      {"l_fingertip", 8813},
      {"r_fingertip", 2145},  {"l_hip", 10926},       {"r_hip", 4296},
      {"l_knee", 11242},      {"r_knee", 4624},       {"l_ankle", 12836},
      {"r_ankle", 6239},      {"l_heel", 12815},      {"r_heel", 6218},
      {"l_toe", 13133},       {"r_toe", 6537}};
  return table;
}

// Face landmarks a landmark file may add to body_landmarks() (the synthetic database does not
// place them), chosen by rule on MakeHuman's default body:
//   nose_tip  the most forward vertex of the head's midline (|x| < 8 mm).
// Without a face landmark the face is placed by head_top and chin alone, and a chin annotated
// on the lips slides the whole face up (docs/real-registration.md).
inline const std::vector<std::pair<std::string, int>>& face_landmarks() {
  static const std::vector<std::pair<std::string, int>> table = {{"nose_tip", 5054}};
  return table;
}

// Every name a landmark file may use: body_landmarks(), then face_landmarks().
inline const std::vector<std::pair<std::string, int>>& registration_landmarks() {
  static const std::vector<std::pair<std::string, int>> table = [] {
    std::vector<std::pair<std::string, int>> t = body_landmarks();
    for (const auto& f : face_landmarks()) t.push_back(f);
    return t;
  }();
  return table;
}

// Landmarks behind the survey measurements (NHANES definitions, core/measure.h), on the
// character's RIGHT side (-x) as NHANES measures. Each is a point on the template surface: the
// mean of the listed body vertices, so it moves with the body's shape. Chosen once on
// MakeHuman's default human (165.9 cm, A-pose) with tools that are not part of the build:
//   iliac_crest   the lateral (min-x) torso vertices of the two vertex rings around 0.58 of the
//                 stature (0.573 h and 0.587 h); MakeHuman has no pelvis bone there, so the
//                 height is a typical adult proportion for the top of the iliac crest, an
//                 APPROXIMATION of the palpated landmark.
//   crotch        the lowest midline (|x| < 1 mm) torso vertex (0.472 h): the hip search starts
//                 above it.
//   acromion      the top of the shoulder straight above the shoulder joint (upperarm01.R head):
//                 the highest vertex within 15 mm of the joint's vertical line (0.826 h).
//   olecranon     the back of the elbow: the most posterior vertex within 12 mm (horizontally)
//                 of the elbow joint (lowerarm01.R head); it is body_landmarks()'s r_elbow.
//   inguinal      the front of the hip crease over the hip joint (upperleg01.R head): the most
//                 anterior vertex within 6 mm of the joint's height and 10 mm of its x.
//   patella_top   the front of the thigh 0.025 h above the knee joint (lowerleg01.R head), i.e.
//                 the proximal border of the kneecap: the most anterior vertex there.
//   upper_arm_ring  the template's quad edge loop around the right upper arm nearest the
//                 acromion-olecranon midpoint (20 vertices, all within 8 mm of the plane
//                 perpendicular to that line through the midpoint on the default body). A ring of
//                 the mesh, not a plane section, so on heavy bodies whose arm presses into the
//                 torso the girth still goes round the arm only.
//   hip_l, hip_r, navel  body_landmarks()'s l_hip, r_hip and navel: the horizontal direction
//                 from r_hip to l_hip is the body's left-right axis and the navel marks the front,
//                 which orients "posterior" for the hip search.
struct SurveyLandmarks {
  std::vector<int> iliac_crest, crotch, acromion, olecranon, inguinal, patella_top, upper_arm_ring;
  int hip_l = 10926, hip_r = 4296, navel = 4367;
};

inline const SurveyLandmarks& survey_landmarks() {
  static const SurveyLandmarks table{{4272, 4395}, {4372}, {1557}, {3357}, {4339}, {4594},
      {1428, 1427, 3762, 1426, 1425, 1457, 1424, 1657, 1656, 1655,
       1654, 1658, 1659, 1688, 3785, 3848, 1660, 1661, 1662, 1429}};
  return table;
}

// Landmarks behind the ANSUR II measurements (core/ansur_measure.h; definitions in
// docs/measurements.md). Right side (-x) as ANSUR measures, with the left mirror where a breadth
// or span needs both (the mirror is the vertex nearest (-x, y, z), exact on the symmetric base
// mesh). Chosen once on MakeHuman's default human (all macros 0.5, 165.9 cm, A-pose) with tools
// that are not part of the build:
//   nipple         the tail vertex of the breast.R / breast.L bones (MakeHuman's nipple/bust point).
//   omphalion      body_landmarks()'s navel.
//   buttock        the most posterior vertex of each buttock between crotch and iliac crest: the
//                  level of the maximum protrusion of the buttocks, FIXED to the template vertex
//                  where it lies on the default body (an approximation of ANSUR's search).
//   gluteal_furrow the back-of-thigh vertex where the posterior profile bends from buttock to
//                  thigh, a little below the crotch.
//   calf           the most posterior vertex of the right calf (fixed, as the buttock).
//   axilla         the highest vertex of the right armpit with a downward normal.
//   acromion       the lateral tip of the acromion, which lies over the humeral head: the
//                  top-of-shoulder vertex (upward normal) about a humeral-head radius (25 mm)
//                  lateral of the shoulder joint (upperarm01.R head). survey_landmarks()'s
//                  acromion, straight above the joint, falls well short of ANSUR's biacromial
//                  breadth (docs/measurements.md).
//   lateral_deltoid  the most lateral vertex of the right arm halfway between acromion and
//                  axilla heights: the tape's path over the shoulder for the sleeve outseam.
//   radiale, stylion  the lateral elbow vertex at the elbow joint (lowerarm01.R head) and the
//                  thumb-side wrist vertex at the wrist joint (towards finger1-1.R).
//   olecranon      survey_landmarks()'s olecranon (back of the elbow).
//   cervicale      the back-midline vertex at the base of the neck (body_landmarks()'s neck_back).
//   neck_base_ring the template's quad edge loop round the neck nearest to both the cervicale and
//                  the jugular notch (the deepest front-midline vertex at the neck's base): 42
//                  vertices in order, just above the cervicale at the back and just below the
//                  notch in front (the loop through the cervicale itself flares onto the
//                  trapezius: docs/measurements.md).
//   crotch, iliac_crest  survey_landmarks()'s.
//   knee_front, patella_top  the front of the knee at the joint's height (body_landmarks()'s
//                  r_knee) and survey_landmarks()'s patella_top: mid-patella is their midpoint.
//   fingertip      body_landmarks()'s l_/r_fingertip (tips of the middle fingers).
struct AnsurLandmarks {
  int nipple_r = 1779, nipple_l = 8451, omphalion = 4367, buttock_r = 4218, buttock_l = 10854;
  int gluteal_furrow = 4262, calf = 4740, axilla_r = 1445, axilla_l = 8133;
  int acromion_r = 1604, acromion_l = 8276, lateral_deltoid = 1676, radiale = 3387, stylion = 3922;
  int olecranon = 3357, cervicale = 1491, crotch = 4372, knee_front = 4624, patella_top = 4594;
  int fingertip_r = 2145, fingertip_l = 8813;
  std::vector<int> iliac_crest{4272, 4395};
  std::vector<int> neck_base_ring;
};

inline const AnsurLandmarks& ansur_landmarks() {
  static const AnsurLandmarks table = [] {
    AnsurLandmarks a;
    a.neck_base_ring = {1496, 8180, 8179, 8181, 8182, 8183, 8184, 8185, 8187, 8188, 8189, 8196, 8152, 8151,
                        8150, 10355, 8195, 8148, 8149, 8194, 8205, 1522, 1521, 1510, 1461, 1460, 1511, 3687,
                        1462, 1463, 1464, 1512, 1505, 1504, 1503, 1501, 1500, 1499, 1498, 1497, 1494, 1495};
    return a;
  }();
  return table;
}

}  // namespace bodymodel
