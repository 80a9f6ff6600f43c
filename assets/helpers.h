// The hm08 helper geometry (helper-tights, -skirt and -hair shells, eyes, eyelashes, teeth,
// tongue, joint cubes: vertices 13380..19157) for a body that has only the 13380 skin vertices,
// e.g. a registered scan or a character of the statistical model. Garments are bound to the
// helper shells, so an asset needs them.
//
// Method: each helper vertex is tied to the skin triangle closest to it on a reference
// MakeHuman body: barycentric coordinates of the closest point plus the offset from that point
// in the triangle's own frame (edge, normal, their cross product). On another body the offset
// is re-expressed in that triangle's frame there, so it turns and stretches with the skin. It is
// an approximation: MakeHuman's targets move helpers and skin separately (figures:
// docs/assets.md).
#pragma once

#include <Eigen/Core>

namespace bodymodel {

struct HelperBinding {
  int body_vertex_count = 0;   // skin vertices (13380)
  int vertex_count = 0;        // all vertices (19158)
  Eigen::MatrixX3i triangle;   // #helpers by 3 skin vertex indices
  Eigen::MatrixX3d bary;       // #helpers by 3
  Eigen::MatrixX3d local;      // #helpers by 3 offset in the (edge, normal × edge, normal) frame
};

// Ties the helpers of `reference` (all vertices, rows body_vertex_count.. are helpers) to the
// skin triangles `body_F` (indices below body_vertex_count). InputError for bad sizes.
HelperBinding bind_helpers(const Eigen::MatrixX3d& reference, const Eigen::MatrixX3i& body_F,
                           int body_vertex_count = 13380);

// The body's skin rows followed by its helpers: #vertex_count by 3.
Eigen::MatrixX3d complete_with_helpers(const HelperBinding& binding, const Eigen::MatrixX3d& body);

}  // namespace bodymodel
