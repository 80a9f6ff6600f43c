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

}  // namespace bodymodel
