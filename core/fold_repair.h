// Fold repair: triangles of a mesh whose normal points against the same triangle of a fold-free
// reference mesh of the same topology ("flipped" triangles: eyelids of a decoded body, the
// fingers and toes of a registration) are re-solved from the reference's local shape.
//
// Method (Laplacian editing, Sorkine et al. 2004, "Laplacian surface editing", with the local
// similarity fit of its §3): the vertices of the flipped triangles, grown by `rings` vertex
// rings, form regions; each connected region is re-solved on its own so that its vertices'
// umbrella-Laplacian coordinates equal the REFERENCE's, rotated and scaled by the similarity
// transform that best maps the reference's region border onto the mesh's (a Procrustes fit), and
// glued to the unchanged vertices around it. Without that fit a body that is taller, wider or
// leaning against the reference gets the reference's unscaled, unrotated local shape pasted into
// it, which folds the region's border instead (a 10-subject model's body went from 54 to 126
// flipped triangles that way). A region's solution is kept only if it leaves fewer flipped
// triangles among the triangles it touches, so a repair never increases the count; a further
// pass grows the region of the folds that remain by one more ring.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <vector>

namespace bodymodel {

struct FoldRepairOptions {
  int rings = 2;    // vertex rings grown around the flipped triangles' vertices (first pass)
  int passes = 3;   // passes while flipped triangles remain; pass p grows rings + p rings
  // Rotate and scale the reference's Laplacian coordinates per region (Procrustes fit of the
  // region's border); false pastes them unchanged (the registration's former behaviour, right
  // only when the reference is already fitted to the mesh, e.g. the pose-fitted template).
  bool local_similarity = true;
  // Keep a region's solve only if it leaves fewer flipped triangles among those it touches
  // (false keeps every solve: the repair may then increase the count; for comparisons only).
  bool keep_only_improving = true;
  // Regions with more vertices than this are left alone (a broken decode is not a fold).
  int max_region_vertices = 4000;
  // > 0: a solve is also refused when an edge of the triangles it touches ends longer than this
  // times its length in V_ref and longer than it was (animation frames: the exploded-triangle
  // bound of 3x rest). 0 = no edge test.
  double max_edge_ratio = 0;
  // A region's solve is also refused when it moves any vertex farther than this (mesh units;
  // infinity = no limit): a solve that removes a fold by dragging a limb's surface away is worse
  // than the fold.
  double max_displacement = std::numeric_limits<double>::infinity();
  // After the passes: up to this many umbrella-smoothing steps on the folds that remain (each
  // vertex of a flipped triangle moved half-way to the mean of its neighbours, no vertex farther
  // than max_displacement in one step), kept while the count falls. For one-triangle-wide creases
  // (a heavy body's crotch, the sternum between strong pectorals) where the Laplacian solve from
  // the reference either leaves the crease or moves the surface tens of mm. 0 = none.
  int smoothing_steps = 0;
  // Vertices never re-solved (they glue a region like its border): a registration's landmark
  // vertices, placed on purpose where the reference's local shape would put them elsewhere.
  std::vector<int> pinned;
};

struct FoldRepairSummary {
  int flipped_before = 0;   // triangles flipped against the reference before the repair
  int flipped_after = 0;    // ... and after
  int regions_solved = 0;   // region solves tried over all passes
  int regions_kept = 0;     // ... and kept (fewer flipped triangles among those they touch)
  int vertices_moved = 0;   // distinct vertices changed by kept solves (and smoothing steps)
  int smoothing_steps = 0;  // smoothing steps kept (FoldRepairOptions::smoothing_steps)
  int passes = 0;           // passes run
};

// Flipped triangles: those whose normal in V has a negative dot product with its normal in
// V_ref (degenerate triangles of either mesh are not counted).
//   V #V by 3, V_ref #V by 3 (same units and orientation), F #F by 3.
int count_flipped_triangles(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref,
                            const Eigen::MatrixX3i& F);

// Repairs the flipped triangles of V against V_ref in place (see the file comment). V_ref must be
// in V's frame (e.g. the template rigidly fitted onto V); with local_similarity its size may
// differ. Throws InputError when V and V_ref differ in size or F indexes outside them.
//   V #V by 3 (modified in place), V_ref #V by 3, F #F by 3.
FoldRepairSummary repair_folds(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref,
                               const Eigen::MatrixX3i& F, const FoldRepairOptions& options = {});

// The same repair with "flipped" judged against given reference face normals instead of V_ref's:
// triangle f is flipped when its normal in V has a negative dot product with N_ref.row(f). For
// meshes without a fold-free reference of the same shape, e.g. a posed body (pose morph): N_ref
// = each triangle's rest normal turned by the rotation of the bone that mostly carries it (the
// flip test of animation frames), V_ref = the rest body, whose local shape the Procrustes fit of
// each region's border rotates and scales into place (local_similarity should be true).
//   V #V by 3 (modified in place), V_ref #V by 3, N_ref #F by 3 (any length), F #F by 3.
FoldRepairSummary repair_folds_against_normals(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref,
                                               const Eigen::MatrixX3d& N_ref, const Eigen::MatrixX3i& F,
                                               const FoldRepairOptions& options = {});
// The same with each vertex's reference Laplacian coordinate mapped by its own frame instead of
// the region's Procrustes fit: vertex_frames[i] (#V 3 by 3 maps, V_ref's frame → V's) e.g. the
// blended bone rotation of vertex i in an animation frame, so that a region spanning two bones
// (armpit, groin) gets each side's rest shape turned with its own bone.
//   V #V by 3 (modified in place), V_ref #V by 3, N_ref #F by 3, vertex_frames #V, F #F by 3.
FoldRepairSummary repair_folds_against_normals(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref,
                                               const Eigen::MatrixX3d& N_ref,
                                               const std::vector<Eigen::Matrix3d>& vertex_frames,
                                               const Eigen::MatrixX3i& F, const FoldRepairOptions& options = {});
// Triangles of V whose normal has a negative dot product with N_ref.row(f).
int count_flipped_triangles_against_normals(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& N_ref,
                                            const Eigen::MatrixX3i& F);

}  // namespace bodymodel
