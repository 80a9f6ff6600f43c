// Body segments for contact-aware registration (issue 37, docs/real-registration.md#contacts):
// where a scan's limbs touch (a foot on a knee, hands on hips, crossed arms), the closest template
// vertex of a scan point can lie on the other limb, and the non-rigid fit then pulls that limb's
// vertices onto the wrong surface. Every template vertex gets a segment from the skinning
// weights, every scan point the segment of the posed template's surface it belongs to, and data
// pairs between segments that do not touch on the template are refused.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/skeleton.h"

namespace bodymodel {

struct BodySegments {
  std::vector<std::string> names;    // #S segment names
  Eigen::VectorXi vertex_segment;    // #V segment of each template vertex (0..#S-1)
  // #S by #S: 1 where two segments share a template edge (or are the same segment). Pairs of
  // adjacent segments are never refused: at a joint the boundary between them moves with the
  // fit, and refusing there would drop good data.
  Eigen::MatrixXi adjacent;
  int count() const { return int(names.size()); }
  bool compatible(int a, int b) const { return a < 0 || b < 0 || adjacent(a, b) != 0; }
};

// Segments of a MakeHuman-rigged template: the torso (with head, neck, clavicles and pelvis), and
// per side the upper arm, the forearm with the hand, the thigh, and the shin with the foot. A
// bone belongs to the segment of its nearest ancestor (itself included) among upperarm01,
// lowerarm01, upperleg01, lowerleg01 (.L/.R); a vertex to the segment carrying most of its
// skinning weight. The split puts every contact of FAUST's poses (hand on hip, crossed forearms,
// foot on the other knee, inner thighs) between non-adjacent segments, while the arm-torso and
// thigh-torso seams stay adjacent.
//   F the template's faces (adjacency). Throws InputError when the weights' size disagrees.
BodySegments body_segments(const Skeleton& skeleton, const SkinWeights& weights, const Eigen::MatrixX3i& F);

struct PointSegmentOptions {
  int neighbours = 16;                 // posed vertices considered per point
  double min_normal_cos = 0.0;         // a vertex whose normal is farther than 90° is not taken
  bool unsigned_normals = false;       // scans whose normals were estimated (no orientation)
};

// The segment of every scan point: that of the closest vertex of the posed template V (normals
// VN) whose normal agrees with the point's. Near a contact the scan points of the hand and of the
// hip it rests on are close to both, but their normals face opposite ways, as do the posed hand's
// and hip's: the normal test gives each its own limb. A point with no agreeing vertex among the
// neighbours (or no normals) takes the closest vertex's segment.
//   P, N #P by 3 (N may be empty); V, VN #V by 3; vertex_segment #V.
Eigen::VectorXi point_segments(const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& N, const Eigen::MatrixX3d& V,
                               const Eigen::MatrixX3d& VN, const Eigen::VectorXi& vertex_segment,
                               const PointSegmentOptions& options = {});

}  // namespace bodymodel
