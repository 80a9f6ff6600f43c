// Registering the template to a *mesh* of any topology (a captured or reconstructed body, e.g.
// the Vlasic et al. 2008 "jumping" sequence in animations/vlasic-jumping): the mesh becomes a
// dense oriented point cloud (the registration's scan), landmarks are given once as vertex
// indices of the mesh (so one file serves every frame of a sequence that keeps its topology),
// and the result is compared with the mesh by a two-sided surface distance and fold counts.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "registration/landmarks.h"

namespace bodymodel {

struct MeshScanOptions {
  // Surface samples drawn uniformly by area (on top of the mesh's own vertices). The inverse
  // correspondence search (Hasler et al. 2009 §2.3) projects a template vertex onto a plane only
  // when ≥ 4 scan points chose it, so the scan must be several times denser than the template
  // (13 380 vertices): 60 000 samples give ≈ 4.5 points per template vertex.
  int samples = 60000;
  unsigned seed = 1;
};

// A dense point cloud of `mesh` (unit: the mesh's) with oriented face normals: the mesh's
// vertices (area-weighted vertex normals) followed by `options.samples` area-uniform samples
// (normal of the sampled face). A closed mesh with negative signed volume (inward-facing
// triangles) has its normals flipped so they point outwards. Throws InputError naming `what` for
// an empty mesh, bad indices or non-finite coordinates.
PointCloud mesh_to_scan(const Mesh& mesh, const MeshScanOptions& options = {},
                        const std::string& what = "scan mesh");

// Reads a landmark file for a scan *mesh*: JSON {name: vertex} with `vertex` a 0-based vertex
// index of the scan mesh (placed once, e.g. on the first frame of a sequence, and reused for
// every frame of the same topology) or {name: [x, y, z]} (a position in the mesh's unit), both
// forms may be mixed. Each name is matched to the template vertex of the same name in `table`.
//   scan_V  #S by 3 vertices of the scan mesh (the landmark targets are taken from it)
// Throws InputError naming the file for malformed JSON, unknown names (listing the known ones),
// an index out of 0..#S-1 or a non-finite position.
std::vector<Landmark> read_mesh_landmarks(const std::filesystem::path& path,
                                          const LandmarkTable& table,
                                          const Eigen::MatrixX3d& scan_V);

// How closely a registered template follows a scan mesh.
struct MeshScanDistance {
  double registered_to_scan_mean = 0;  // mean distance, area-uniform samples of the registered
                                       // surface → scan surface (unit of the inputs)
  double scan_to_registered_mean = 0;  // the other way
  double two_sided_mean = 0;           // the average of the two means
  double registered_to_scan_p95 = 0;
  double scan_to_registered_p95 = 0;
  double registered_to_scan_max = 0;
  double scan_to_registered_max = 0;
  // Triangles of the registered mesh whose normal opposes the normal of the same triangle in
  // `reference_V` (the pose-fitted template: a fold made by the non-rigid fit). -1 if no
  // reference was given.
  int folded_triangles = -1;
  // Triangles whose normal opposes the normal of the closest scan triangle (centroid within
  // `near_distance` of the scan; inside a fist the template's fingers touch each other, so
  // farther triangles are not compared).
  int flipped_against_scan = 0;
};

// reg_V #V by 3 on faces reg_F; scan: the scan mesh in the same unit; reference_V (optional,
// #V by 3, same faces): the mesh the fold count compares with. `samples` points per surface.
MeshScanDistance mesh_scan_distance(const Eigen::MatrixX3d& reg_V, const Eigen::MatrixX3i& reg_F,
                                    const Mesh& scan, const Eigen::MatrixX3d* reference_V = nullptr,
                                    int samples = 30000, double near_distance = 10.0);

// Triangles whose normal in V opposes (dot < 0) their normal in reference_V (same faces F).
int folded_triangles(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& reference_V,
                     const Eigen::MatrixX3i& F);

struct UnfoldOptions {
  int max_rounds = 30;  // repair passes; pass p grows the region by p more rings
  int rings = 1;        // rings around the folded triangles in the first pass
};

// Removes folds left by a non-rigid fit where the template is finer than the scan (eyelids,
// armpits) with the fold repair of core/fold_repair.h: a region around the folded triangles is
// re-solved so that its umbrella-Laplacian coordinates are reference_V's, rotated and scaled
// to the region's border (the rest of the mesh fixed), and a solve is kept only where it leaves
// fewer folds; the region grows each pass until no fold is left. V #V by 3 (modified),
// reference_V #V by 3 (e.g. the pose-fitted template), F #F by 3. Returns the folds left (0
// unless max_rounds ran out).
int unfold_triangles(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& reference_V,
                     const Eigen::MatrixX3i& F, const UnfoldOptions& options = {});

}  // namespace bodymodel
