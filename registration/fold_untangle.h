// The last step of the fold repair of a registration: an untangling solve that removes the local
// folds (registration/metrics.h locally_folded_triangles) the Laplacian repair of
// registration/local_fold_repair.h leaves. That repair re-solves a region from the rest
// template's local shape and keeps a solve only if it lowers the region's count; at a crease the
// non-rigid fit has crumpled (armpit, elbow, crotch, a finger's base, an eyelid) its solves do not
// lower it and it stops with the folds in place. Here each remaining fold's region (its vertices
// grown by rings) is moved as little as it can be while every triangle touching it faces with its
// neighbourhood: a penalty on each triangle whose normal falls below a margin along its ring
// normal (the same direction the fold test compares with), against an anchor on each vertex's
// motion along its normal (off the scan) and, weaker, across it (along the scan). The region
// grows by one ring each round until no fold is left. Triangles the rest template itself has
// facing clearly against their ring (its ear rims, eyelid edges) are not counted by the fold
// test and are not constrained here either: the registration keeps the template's own sharp
// features. A solve that would move a vertex farther than a bound is refused.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace bodymodel {

struct UntangleOptions {
  int rings = 2;         // the fold test's neighbourhood (as locally_folded_triangles)
  // Triangles the rest template has facing against their ring by more than this cosine are its
  // own sharp features (ear rims), left as they are; the fold test does not count them.
  double rest_fold_cos = 0.25;
  int region_rings = 1;  // first round: the folded triangles' vertices grown by this many rings
  int rounds = 12;       // rounds of fold test and solve; round r grows the region by r more rings
  int solves = 3;        // solves per round, the ring normals recomputed between them
  // A triangle must face along its ring normal by at least this fraction of its area (its rest
  // area scaled by the body's area ratio): well-shaped, not just barely unfolded. One that faces
  // along its ring by less at rest (an eyelid's edge) keeps its rest cosine, at least 0.05.
  double margin = 0.2;
  double normal_weight = 1.0;    // anchor on motion along the vertex normal (per mm²)
  double tangent_weight = 0.3;   // anchor on any motion (per mm²): a slide along the surface is cheaper
  double orientation_weight = 100.0;  // penalty on a triangle below the margin
  int max_region_vertices = 3000;     // larger regions are left alone (not a fold)
  // A round's solve that moves any vertex farther than this from where it started (mesh units,
  // mm) is refused: a fold is not worth dragging the surface off the scan (as the local repair).
  double max_displacement = 30.0;
};

struct UntangleSummary {
  int folded_before = 0;         // local folds before
  int folded_after = 0;          // ... and after (0 unless the rounds ran out)
  int rounds = 0;                // rounds run
  int vertices_moved = 0;        // vertices moved by kept solves
  double max_displacement = 0;   // the farthest a vertex moved (mesh units, mm)
  double mean_displacement = 0;  // mean over the moved vertices
};

// Untangles the local folds of V in place. V #V by 3 (a registration), rest_V #V by 3 (the
// template at rest, its shaped body if the shape was fitted: the fold test's exemptions), F #F
// by 3. A round's solve is kept only if it leaves fewer folds than before it and moves no vertex
// farther than options.max_displacement from V as given. Throws InputError
// when V and rest_V differ in size or F indexes outside them.
UntangleSummary untangle_local_folds(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& rest_V,
                                     const Eigen::MatrixX3i& F, const UntangleOptions& options = {});
// The same against several rest shapes of the template (e.g. the fitted body and the start
// body): a triangle is left facing against its ring only where every one of them has it so, as
// a triangle a shaped body folds and another does not is a fold of that blend, not a feature.
// The summary's fold counts are against rests[0]. Throws InputError when `rests` is empty.
UntangleSummary untangle_local_folds(Eigen::MatrixX3d& V, const std::vector<Eigen::MatrixX3d>& rests,
                                     const Eigen::MatrixX3i& F, const UntangleOptions& options = {});

}  // namespace bodymodel
