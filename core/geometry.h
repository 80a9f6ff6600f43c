// Geometry operators on plain arrays (libigl conventions: V #V by 3, F #F by 3).
#pragma once

#include <Eigen/Core>
#include <Eigen/Sparse>
#include <vector>

namespace bodymodel {

using SparseMatrixd = Eigen::SparseMatrix<double>;

// Triangle areas.                                   returns #F
Eigen::VectorXd face_areas(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F);

// Unit triangle normals (zero for degenerate triangles).   returns #F by 3
Eigen::MatrixX3d face_normals(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F);

// Area-weighted unit vertex normals.                returns #V by 3
Eigen::MatrixX3d vertex_normals(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F);

// Cotangent Laplacian L (#V by #V): L_ij = (cot α_ij + cot β_ij) / 2 for an edge ij,
// L_ii = -Σ_j L_ij. Symmetric, rows sum to zero, negative semi-definite (libigl's sign).
// With the mass matrix M, M⁻¹ L V ≈ -2 H n (H mean curvature, n outward unit normal).
SparseMatrixd cotangent_laplacian(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F);

// Lumped (barycentric) mass matrix: diagonal, a third of the adjacent triangles' areas.
SparseMatrixd mass_matrix_barycentric(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F);

// Per-triangle gradient operator G (3·#F by #V), rows ordered [all x; all y; all z]:
// (G f) gives the gradient of the piecewise-linear function f on each triangle.
SparseMatrixd gradient_operator(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F);

// Undirected edges, each once with E(e,0) < E(e,1).       returns #E by 2
Eigen::MatrixX2i unique_edges(const Eigen::MatrixX3i& F);

// Triangle-triangle adjacency across edges: TT(f, k) is the triangle sharing edge k of f
// (edge k runs from F(f,k) to F(f,(k+1)%3)), or -1 on a boundary.   returns #F by 3
// Throws InputError if an edge is shared by more than two triangles (non-manifold).
Eigen::MatrixX3i triangle_adjacency(const Eigen::MatrixX3i& F);

// Topology checks. Throws InputError describing the first problem found (face index out
// of range, repeated vertex in a face, non-manifold edge). `what` names the mesh in messages.
void check_triangle_mesh(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                         const std::string& what = "mesh");

// Axis-aligned bounding box diagonal length.
double bounding_box_diagonal(const Eigen::MatrixX3d& V);

// Signed volume enclosed by a closed, outward-oriented triangle surface (divergence theorem).
double signed_volume(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F);

// Points sampled uniformly by area on the surface, with their triangle and barycentrics.
struct SurfaceSamples {
  Eigen::MatrixX3d P;        // #S by 3 positions
  Eigen::VectorXi face;      // #S triangle index
  Eigen::MatrixX3d bary;     // #S by 3 barycentric coordinates
};
SurfaceSamples sample_surface(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, int count,
                              unsigned seed);

// Best rigid motion (rotation R, translation t) minimising Σ w_i ‖R a_i + t − b_i‖² (Kabsch).
// A, B #N by 3; w #N (empty = uniform). Returns the aligned copy of A when `aligned` is set.
struct RigidMotion {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
};
RigidMotion fit_rigid_motion(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B,
                             const Eigen::VectorXd& w = Eigen::VectorXd());
Eigen::MatrixX3d apply(const RigidMotion& m, const Eigen::MatrixX3d& A);

}  // namespace bodymodel
