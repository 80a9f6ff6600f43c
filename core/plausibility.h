// Plausibility figures of a body mesh: surface roughness and self-intersections.
//
// ROUGHNESS (issue 23; docs/population.md §5): per vertex, the angle between its
// area-weighted normal and the mean of its one-ring neighbours' normals, in degrees. A smooth
// surface scores a few degrees (the angle grows with curvature × edge length); a crease, a fold
// or a crumpled patch scores tens. Reported as the 95th percentile and the maximum over a vertex
// region: for bodies the trunk and limbs (head, hands and feet excluded, where fingers, toes,
// ears and lips are legitimately sharp and would hold the top 5 % on any body), so that the
// figure answers "is the skin smooth" and not "does it have fingers".
//
// SELF-INTERSECTIONS: pairs of triangles that share no vertex and intersect (CGAL boxes, then
// exact-predicate triangle–triangle tests). Thighs pressed into each other, a crumpled groin or
// arms sunk into the torso show up here.
#pragma once

#include <cstddef>
#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "core/skeleton.h"

namespace bodymodel {

struct Roughness {
  double p95_deg = 0;  // 95th percentile over the region's vertices
  double max_deg = 0;  // maximum over the region
  int vertices = 0;    // vertices in the region
};

// Per-vertex roughness angles in degrees (#V; 0 for isolated vertices).
//   V #V by 3, F #F by 3 (closed or open; any unit).
Eigen::VectorXd vertex_roughness_deg(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F);

// p95 and max of vertex_roughness_deg over the vertices with region[v] != 0 (empty region = all).
Roughness roughness(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const std::vector<char>& region = {});
// The same with unique_edges(F) (core/geometry.h) given, for callers measuring many meshes of one
// topology (a crowd): sorting the edges was a tenth of the measurement's cost per body.
Roughness roughness(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const std::vector<char>& region,
                    const Eigen::MatrixX2i& edges);

// The trunk and limbs of a skinned body (#V entries, 1 = in the region): every vertex whose
// largest skinning weight belongs to a bone outside the head ("head" and its descendants: jaw,
// eyes, tongue, face), the hands ("wrist.L/R" and descendants) and the feet ("foot.L/R" and
// descendants) of MakeHuman's default skeleton. bone_names #B, parents #B (parents first),
// weights #V by #B.
std::vector<char> trunk_and_limbs_region(const std::vector<std::string>& bone_names, const std::vector<int>& parents,
                                         const SkinWeights& weights);

// Number of intersecting triangle pairs that share no vertex.   V #V by 3, F #F by 3.
// Broad phase a uniform grid; the same count as self_intersecting_triangle_pairs_box_d (CGAL's
// box_self_intersection_d broad phase, the reference), with the same exact narrow phase.
int self_intersecting_triangle_pairs(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F);
// The same pairs as a list (face indices, first < second, sorted).
std::vector<std::pair<int, int>> self_intersecting_triangle_pair_list(const Eigen::MatrixX3d& V,
                                                                      const Eigen::MatrixX3i& F);
// cutoff: CGAL's segment-tree cutoff (its own default is 10); the pairs found do not depend on it.
int self_intersecting_triangle_pairs_box_d(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                                           std::ptrdiff_t cutoff = 2000);

}  // namespace bodymodel
