// Levels of detail of a dressed body (docs/assets.md#levels-of-detail): each part simplified by
// edge collapse (CGAL's Surface_mesh_simplification, Lindstrom–Turk cost and placement) to a
// share of a triangle budget, its skinning weights carried to the new vertices from the closest
// point of the part it came from, and optionally the body replaced by a MakeHuman proxy mesh
// (fitted by its binding, weights carried through it, the skin the outfit hides dropped).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "assets/dress.h"
#include "assets/fit.h"

namespace bodymodel {

struct SimplifiedMesh {
  Eigen::MatrixX3d V;
  Eigen::MatrixX3i F;
};

// About `target_triangles` triangles (edge collapse stops on an edge count, so the result may be
// a few triangles off; never more than the input). With max_error > 0 (mesh units) a collapse
// whose new vertex would lie farther than that from the input surface is refused (CGAL's
// Bounded_distance_placement), so the target may not be reached. Non-manifold input is split
// into manifold pieces first (vertices duplicated), degenerate and duplicate triangles dropped.
// InputError for an empty mesh or a target < 1.
SimplifiedMesh simplify_mesh(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, int target_triangles,
                             double max_error = 0);

// A part whose vertices are new (simplified, or a proxy): weights of each vertex from the closest
// point of `source` (its triangle's rows mixed by barycentric coordinates, skin_weights_at).
DressedPart simplified_part(const DressedPart& source, int target_triangles, double max_error = 0);

// The body replaced by a proxy (.proxy asset): fitted to `dressed.full_rest` by its binding,
// weights carried through it from dressed.full_weights, a proxy face dropped when all its
// vertices are hidden (a vertex is hidden when its binding's largest-weight body vertex is hidden
// by the outfit). The colour and roughness are the body part's (`body`).
DressedPart proxy_body_part(const Asset& proxy, const DressedSkinBody& dressed, const DressedPart& body);

// The closed surface of a proxy fitted to the dressed body, for measuring a level's garments
// against it (docs/assets.md#between-keys-and-levels): every proxy face, the weights carried
// through the binding, and the vertices hidden by the outfit as proxy_body_part decides them.
struct ProxySurface {
  Eigen::MatrixX3d V;
  Eigen::MatrixX3i F;
  SkinWeights weights;
  std::vector<char> hidden;
};
ProxySurface proxy_surface(const Asset& proxy, const DressedSkinBody& dressed);

struct LodSpec {
  int max_triangles = 2000;             // the whole level
  const Asset* proxy = nullptr;         // replaces the body; nullptr = the body simplified like the rest
  std::vector<std::string> drop_kinds;  // asset kinds left out (asset_kind: "eyelashes", …)
  double max_error_mm = 0;              // simplify_mesh's bound (0 = none)
};

// One level of detail of `parts` (dress_skin_body's, body first): the body (or the proxy, kept
// whole unless it takes more than half the budget), then every part not dropped, simplified to a
// share of the remaining triangles proportional to its area (at least 24; a part under its share
// is kept as it is), the shares shrunk until the level fits `max_triangles`. Garment flags are
// kept; penetration figures are not measured for the level.
std::vector<DressedPart> level_of_detail(const std::vector<DressedPart>& parts, const DressedSkinBody& dressed,
                                         const LodSpec& spec);

int triangle_count(const std::vector<DressedPart>& parts);

}  // namespace bodymodel
