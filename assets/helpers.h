// The hm08 helper geometry (helper-tights, -skirt and -hair shells, eyes, eyelashes, teeth,
// tongue, joint cubes: vertices 13380..19157) for a body that has only the 13380 skin vertices,
// e.g. a registered scan or a character of the statistical model. Garments are bound to the
// helper shells, so an asset needs them.
//
// Two methods (figures: docs/assets.md):
//  - a regressor (preferred): each helper vertex is a fixed combination, weights summing to one,
//    of the skin vertices nearest to it, fitted by least squares over random MakeHuman bodies
//    (as MakeHuman::skeleton_from_body does for joints). Weights summing to one make it follow
//    any affine motion of its neighbourhood, so a posed skin carries its helpers along.
//  - a tie: each helper vertex tied to the skin triangle closest to it on one reference body
//    (barycentric point plus an offset in the triangle's frame). No training, but MakeHuman's
//    targets slide the helper shells along the skin, which a tie cannot follow.
#pragma once

#include <Eigen/Core>
#include <Eigen/Sparse>

namespace bodymodel {

class MakeHuman;

struct HelperRegressor {
  int body_vertex_count = 0;  // skin vertices (13380)
  int vertex_count = 0;       // all vertices (19158)
  Eigen::SparseMatrix<double, Eigen::RowMajor> R;  // #helpers by body_vertex_count, rows sum to 1
};

struct HelperRegressorOptions {
  int bodies = 60;        // random MakeHuman bodies (every macro slider uniform; ages 10 to 90 y)
  int neighbours = 128;   // skin vertices per helper, nearest on the default human
  double ridge = 1e-6;    // relative Tikhonov weight on the weights (stabilises flat neighbourhoods)
  unsigned seed = 1;
};

// Fits the regressor on `options.bodies` random bodies of `mh` (seconds of CPU: fit once, keep).
HelperRegressor fit_helper_regressor(const MakeHuman& mh, const HelperRegressorOptions& options = {});

// The body's skin rows followed by its helpers (#vertex_count by 3).
Eigen::MatrixX3d complete_with_helpers(const HelperRegressor& regressor, const Eigen::MatrixX3d& body);

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
