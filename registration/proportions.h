// Per-segment proportions of the template from the scan's landmarks. Subjects differ in limb
// length relative to their size, not only in global scale; a template with only a global scale
// leaves limbs too short or too long, the pose fit bends joints to compensate and the non-rigid
// fit slides vertices along the limbs (the correspondence error the evaluation measures). Before
// the pose fit, each segment's length is estimated from the distance between two landmarks on
// it (pose-independent: both ends move with the same segment), relative to the global scale of
// the landmarks, and the rest template is stretched along the segment's bones (or scaled about
// the segment's first joint for the head, hands and feet).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/skeleton.h"
#include "registration/landmarks.h"

namespace bodymodel {

// A body segment: its bones (MakeHuman names; the first is its root), whether it scales
// isotropically with all its descendants (head, hand, foot) or stretches along each bone's axis
// (limbs, spine), and landmark name pairs whose distance measures it (left/right averaged).
struct ProportionSegment {
  std::string name;
  std::vector<std::string> bones;
  bool isotropic = false;
  std::vector<std::pair<std::string, std::string>> landmark_pairs;
};

// The default segments for the MakeHuman skeleton and core/landmarks.h body_landmarks():
// upper arm, forearm, thigh, shank, torso, hip and shoulder width (axial), neck with head and
// foot (isotropic).
const std::vector<ProportionSegment>& default_proportion_segments();

struct ProportionOptions {
  std::vector<ProportionSegment> segments;  // empty: default_proportion_segments()
  double min_ratio = 0.8, max_ratio = 1.25;  // clamp of each segment's relative scale
};

struct Proportions {
  std::vector<std::string> segment;  // names of the measured segments
  std::vector<double> ratio;         // their length relative to the template × global scale
  double global_scale = 1.0;         // scan / template, ratio of the summed segment lengths
};

// Estimates the segment ratios from landmarks (template vertex → scan position). Segments whose
// landmarks are missing keep ratio 1.
Proportions estimate_proportions(const Eigen::MatrixX3d& V_rest, const std::vector<Landmark>& landmarks,
                                 const ProportionOptions& options = {});

// The template with these proportions in its rest pose: V (#V by 3) and skeleton (same unit),
// by linear blend skinning of per-bone rest stretches. Bones not found are ignored.
void apply_proportions(const Eigen::MatrixX3d& V_rest, const Skeleton& skeleton,
                       const SkinWeights& weights, const Proportions& proportions,
                       const ProportionOptions& options, Eigen::MatrixX3d* V_out,
                       Skeleton* skeleton_out);

}  // namespace bodymodel
