// Self-intersection repair: where two parts of one closed surface pass through each other (a
// heavy body's inner thighs at the crotch, a breast's underside into the chest wall), the
// vertices of each crossing triangle that lie behind the other triangle's plane (inside the other
// part) are pushed out along the other triangle's normal, half the depth each side plus a margin,
// and the push fades over a few vertex rings so the surface moves as a whole, not as spikes.
// Repeated while crossings remain: the triangles pushed out expose the next ones. The parts then
// touch along a flattened contact, as soft tissue does, instead of passing through each other.
// A simple projection scheme (no collision solver, no volume preservation): for shallow
// interpenetrations of a few millimetres, not for a limb inside another.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace bodymodel {

struct IntersectionRepairOptions {
  int iterations = 40;           // push rounds at most
  double margin = 0.2;           // gap left between the parts (mesh units, mm for bodies)
  int falloff_rings = 3;         // rings over which a push halves per ring
  // Stop (and undo the round) when a vertex would end farther than this from where it started.
  double max_displacement = 15.0;
};

struct IntersectionRepairSummary {
  int pairs_before = 0;          // intersecting pairs among the repaired faces, before and after
  int pairs_after = 0;
  int rounds = 0;                // push rounds kept
  int vertices_moved = 0;
  double max_displacement = 0;   // largest vertex move (mesh units)
};

// Repairs V in place. `faces`: #F flags, only pairs of two flagged faces are repaired (empty =
// every face); pairs elsewhere (a body's toes and fingers) are left as they are.
//   V #V by 3, F #F by 3 (consistently oriented, outward normals).
IntersectionRepairSummary repair_self_intersections(Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                                                    const std::vector<char>& faces = {},
                                                    const IntersectionRepairOptions& options = {});

}  // namespace bodymodel
