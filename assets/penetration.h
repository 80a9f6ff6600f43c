// Body-through-cloth penetration of a fitted (and posed) garment, and a fix that pushes the
// garment out along the body's normal.
//
// Definition (docs/assets.md): a garment vertex is penetrated when it lies INSIDE the body deeper
// than a threshold (2 mm) and the closest skin is visible (not hidden by an asset's
// delete_verts): there the skin shows through the cloth. The signed distance is to the WHOLE
// closed body surface (hidden faces included, so inside and outside stay well defined under a
// garment that hides most of the skin): the distance to the closest point (exact, AABB tree),
// negative when (x − closest) · n < 0, with n the body's area-weighted vertex normals
// interpolated at the closest point (an approximation of the angle-weighted pseudo-normal; it
// can mis-sign a point whose closest feature is a sharp concave crease, which the smooth hm08
// skin does not have). Only vertices are tested: a body vertex poking through the middle of a
// large garment triangle whose corners are all outside is not counted (push_garment_out's
// PushOutOptions::faces clears those too).
#pragma once

#include <Eigen/Core>
#include <vector>

namespace bodymodel {

// Each point's signed distance to the body, the body normal there and whether that skin shows.
struct BodyDistance {
  Eigen::VectorXd signed_distance;  // mm, negative inside
  Eigen::MatrixX3d normal;          // unit body normal at the closest point
  std::vector<char> visible;        // 1 when the closest face has no hidden vertex
};

// Of each row of `points` to the closed body surface (V, F): F all body faces
// (MakeHuman::body_faces), V any rows F indexes (e.g. all 19158); `hidden` one flag per row of V
// (assets/fit.h hidden_body_vertices), or empty when nothing is hidden.
// A point whose closest body skin is hidden but which lies inside VISIBLE skin (where the body
// passes through itself: an arm sunk into the torso, a hand into a thigh; the garment between
// them is then inside the arm, and the arm shows through it) takes its distance, normal and
// visibility from the visible skin instead: when its closest visible point is within 40 mm, on
// the inner side of the normal there, and its generalised winding number over the visible faces
// is at least 0.5 (inside, allowing for the openings the hidden skin leaves). The headless pixel
// check (tests/tools/outfit_pixels_test.cc) found these: the closest-point test alone misses them.
BodyDistance body_distance(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& body_V,
                           const Eigen::MatrixX3i& body_F, const std::vector<char>& hidden = {});

// body_distance's second pass (exposed for its tests): the points flagged not visible in `out`
// re-measured against the visible skin as described above. vn: the body's vertex normals.
void inside_visible_skin(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& body_V, const Eigen::MatrixX3i& body_F,
                         const std::vector<char>& hidden, const Eigen::MatrixX3d& vn, BodyDistance& out);

struct Penetration {
  int vertices = 0;        // garment vertices tested
  int penetrating = 0;     // of which inside the body deeper than the threshold
  double fraction = 0;     // penetrating / vertices
  double max_depth = 0;    // deepest, mm (0 when none is inside)
};

// Counts the garment vertices inside deeper than depth_mm where the skin is visible.
Penetration penetration_of(const BodyDistance& d, double depth_mm = 2.0);

struct PushOutOptions {
  double clearance = 1.0;  // mm: a pushed vertex ends this far outside the body
  int iterations = 4;      // push, spread, re-measure; stops early when nothing is inside
  int spread_rings = 2;    // each push is spread to this many rings of garment neighbours
                           // (keeping the larger displacement), so the cloth moves as a sheet
  // Also push the triangles' interiors out: each face near the body is sampled at its centroid and
  // edge midpoints, and a sample more than `face_depth` inside visible skin moves the corners it
  // lies between along their own body normals until it reaches the clearance (not spread). On a
  // coarse garment the skin pokes through between corners that are all outside
  // (docs/assets.md#penetration); the depth leaves alone the shallow sag of a tight garment's
  // triangles over a convex limb.
  bool faces = true;
  double face_depth = 1.0;  // mm
};

struct PushOutResult {
  Eigen::MatrixX3d V;      // the corrected garment vertices
  Penetration before, after;  // at the threshold passed to push_garment_out
  int moved = 0;           // garment vertices displaced
  double max_move = 0;     // mm
};

// Pushes the garment (G, its faces GF) out of the body (V, F, hidden as in body_distance): every
// vertex (and, with options.faces, every triangle's interior sample) over visible skin that is
// inside or closer than `clearance` moves along the body normal to `clearance` outside, the
// displacement spread to its garment neighbours. Vertices over hidden skin stay: no skin can show
// there. `before` and `after` count vertices only (the measure's definition).
PushOutResult push_garment_out(const Eigen::MatrixX3d& G, const Eigen::MatrixX3i& GF,
                               const Eigen::MatrixX3d& body_V, const Eigen::MatrixX3i& body_F,
                               const std::vector<char>& hidden, const PushOutOptions& options = {},
                               double depth_mm = 2.0);

}  // namespace bodymodel
