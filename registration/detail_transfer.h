// Detail transfer (Hasler et al. 2009 §2, Fig. 4; docs/method.md §2.7): the registered template is
// smooth at the template's resolution; the scan's finer detail is kept as offsets along the
// normal of a once-subdivided mesh. The fitted mesh is subdivided once (mid-edge, 1 → 4
// triangles), each new edge-midpoint vertex is projected onto the scan along the base mesh's
// normal, and the signed normal offsets are stored per triangle (one per triangle edge). On
// recall any mesh of the same topology — the fitted mesh itself, or the same body morphed or
// reposed — is subdivided again and the offsets are added along *its* normals.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>

#include "core/mesh.h"

namespace bodymodel {

// Mid-edge subdivision of a triangle mesh with #V vertices and faces F (#F by 3): new vertex
// #V + e is the midpoint of edges.row(e); each triangle (a, b, c) with midpoints ab, bc, ca
// becomes (a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca) — rows 4f … 4f+3 of F.
struct MidEdgeSubdivision {
  Eigen::MatrixX2i edges;       // #E by 2 vertex pairs (sorted), one per unique edge
  Eigen::MatrixX3i face_edges;  // #F by 3: edge index of side k (corner k → corner k+1)
  Eigen::MatrixX3i F;           // #4F by 3 subdivided faces (same orientation)
};
MidEdgeSubdivision mid_edge_subdivision(const Eigen::MatrixX3i& F, int vertex_count);

// Unit normals at the edge midpoints: the normalised mean of the two end vertices'
// area-weighted normals (smooth, defined on any mesh of the topology).   #E by 3
Eigen::MatrixX3d edge_midpoint_normals(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                                       const MidEdgeSubdivision& sub);

struct DetailTransferOptions {
  // Offsets larger than this are not detail but a misfit (or the far side of a thin part):
  // the midpoint keeps offset 0.
  double max_offset = 15.0;  // mm
  // Scan points within this distance of the normal line through a midpoint give its offset:
  // the ten nearest the line, by a plane fitted to their signed distances along the normal
  // (their mean if fewer than five). ≤ 0: 3 × the scan's median point spacing.
  double line_radius = 0.0;  // mm
  // Scan points whose normal is more than this far from the midpoint normal are ignored (the
  // back of a thin part). Normals compared without sign when `unsigned_normals`.
  double max_normal_angle_deg = 60.0;
  bool unsigned_normals = false;
};

struct SurfaceDetail {
  // #F by 3 signed normal offset (mm) of the midpoint of side k (corner k → k+1) of triangle f;
  // a side shared by two triangles has the same value in both. 0 where none was found.
  Eigen::MatrixX3d offsets;
  int edges_found = 0;    // midpoints with an offset from the scan
  int edges_missing = 0;  // midpoints without scan points near their normal line (holes)
  double line_radius = 0; // mm, as used
};

// Captures the detail of `scan` (unit normals; the registration's scan) relative to the
// fitted mesh V (#V by 3, mm) with faces F. Throws InputError if V, F and scan disagree in
// size or are not finite.
SurfaceDetail capture_detail(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                             const PointCloud& scan, const DetailTransferOptions& options = {});

// Re-adds stored detail to a mesh of the same topology (V #V by 3, faces F as captured): the
// mid-edge subdivision with each midpoint moved along its normal by the mean of the offsets
// stored for its edge (scaled by `amount`; 0 gives the plain subdivision). Returns #V + #E
// vertices and 4·#F faces; the first #V vertices are V. InputError if the detail was captured
// on another topology.
Mesh apply_detail(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                  const SurfaceDetail& detail, double amount = 1.0);

// .detail.npz: "offsets" (#F by 3, mm), "faces" (#F by 3, the topology, to check on recall),
// "edges_found", "edges_missing", "line_radius". Written atomically.
void write_detail(const std::filesystem::path& path, const SurfaceDetail& detail,
                  const Eigen::MatrixX3i& F);
// Reads a .detail.npz; with a non-empty `F` checks that it was captured on these faces
// (InputError naming the file otherwise).
SurfaceDetail read_detail(const std::filesystem::path& path, const Eigen::MatrixX3i& F = {});

}  // namespace bodymodel
