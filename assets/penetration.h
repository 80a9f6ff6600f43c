// Body-through-cloth penetration of a fitted (and posed) garment, and a fix that pushes the
// garment out along the body's normal.
//
// Definition (docs/assets.md): a garment vertex is penetrated when it lies INSIDE the visible
// body surface deeper than a threshold (2 mm): there the skin shows through the cloth. The
// signed distance of a garment vertex is its distance to the closest point of the body's
// visible faces (exact, AABB tree), negative when it lies behind the surface: the sign is that
// of (x − closest) · n, with n the body's area-weighted vertex normals interpolated at the closest
// point (an approximation of the angle-weighted pseudo-normal; it can mis-sign a point whose
// closest feature is a sharp concave crease, which the smooth hm08 skin does not have). Only
// vertices are tested: a body vertex poking through the middle of a large garment triangle
// between garment vertices that are all outside is not counted.
#pragma once

#include <Eigen/Core>

namespace bodymodel {

// Signed distance (mm, negative inside) of each row of `points` to the body surface (V, F):
// F the VISIBLE body faces (assets/fit.h visible_faces), V any rows F indexes (e.g. all 19158).
// normals_out (optional): the interpolated unit body normal at each closest point.
Eigen::VectorXd signed_distance_to_body(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& body_V,
                                        const Eigen::MatrixX3i& body_F,
                                        Eigen::MatrixX3d* normals_out = nullptr);

struct Penetration {
  int vertices = 0;        // garment vertices tested
  int penetrating = 0;     // of which inside the body deeper than the threshold
  double fraction = 0;     // penetrating / vertices
  double max_depth = 0;    // deepest, mm (0 when none is inside)
};

// Counts the garment vertices whose signed distance is below −depth_mm.
Penetration penetration_of(const Eigen::VectorXd& signed_distance, double depth_mm = 2.0);

struct PushOutOptions {
  double clearance = 1.0;  // mm: a pushed vertex ends this far outside the body
  int iterations = 4;      // push, spread, re-measure; stops early when nothing is inside
  int spread_rings = 2;    // each push is spread to this many rings of garment neighbours
                           // (keeping the larger displacement), so the cloth moves as a sheet
};

struct PushOutResult {
  Eigen::MatrixX3d V;      // the corrected garment vertices
  Penetration before, after;  // at the threshold passed to push_garment_out
  int moved = 0;           // garment vertices displaced
  double max_move = 0;     // mm
};

// Pushes the garment (G, its faces GF) out of the body (V, F as in signed_distance_to_body):
// every vertex closer than `clearance` outside (or inside) moves along the body normal to
// `clearance` outside, the displacement spread to its garment neighbours.
PushOutResult push_garment_out(const Eigen::MatrixX3d& G, const Eigen::MatrixX3i& GF,
                               const Eigen::MatrixX3d& body_V, const Eigen::MatrixX3i& body_F,
                               const PushOutOptions& options = {}, double depth_mm = 2.0);

}  // namespace bodymodel
