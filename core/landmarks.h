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

}  // namespace bodymodel
