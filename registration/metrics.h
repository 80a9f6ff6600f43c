// Registration metrics (docs/evaluation.md#registration-against-ground-truth): correspondence,
// surface-fit, hole and joint errors against ground truth.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/skeleton.h"

namespace bodymodel {

// Distance from each point of P (#P by 3) to the triangle surface (V, F): exact point–triangle
// distances over the triangles around the `candidates` nearest vertices (exact for meshes whose
// triangles are small against the distances measured; an upper bound otherwise).   #P
Eigen::VectorXd point_to_mesh_distance(const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& V,
                                       const Eigen::MatrixX3i& F, int candidates = 16);

// Distance from a point to a triangle (a, b, c).
double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                               const Eigen::Vector3d& b, const Eigen::Vector3d& c);

struct RegistrationErrors {
  double correspondence_mean = 0;   // mean ‖reg_i − truth_i‖ (mm)
  double correspondence_max = 0;
  double surface_mean = 0;          // mean distance reg vertex → truth surface (mm)
  double surface_max = 0;
  int hole_vertices = 0;            // template vertices whose true position is > 5 mm from scan
  double hole_mean = 0;             // surface distance over those (mm)
  double hole_max = 0;
  int flipped_triangles = 0;        // triangles whose normal opposes the truth's (dot < 0)
  // Of those, triangles the scanner did not see: all three vertices are hole vertices (their
  // true position > hole_distance from every scan point). The scan says nothing about them.
  int flipped_unseen = 0;
  std::vector<char> hole_vertex;    // #V: 1 where the true position is a hole vertex
  std::vector<char> flipped;        // #F: 1 where the triangle is flipped against the truth
  Eigen::VectorXd vertex_errors;    // #V correspondence errors (mm)
  Eigen::VectorXd surface_errors;   // #V distances registered vertex → truth surface (mm)
};

// reg, truth: #V by 3 on the same topology F; scan_points: the scan (for the hole mask).
RegistrationErrors registration_errors(const Eigen::MatrixX3d& reg, const Eigen::MatrixX3d& truth,
                                       const Eigen::MatrixX3i& F,
                                       const Eigen::MatrixX3d& scan_points,
                                       double hole_distance = 5.0);

// The area-weighted normal (unnormalised: the sum of twice-area face normals) of the triangles
// within `rings` vertex rings of each triangle, itself included.   #F by 3
Eigen::MatrixX3d ring_normals(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, int rings = 2);

// Triangles folded against their own neighbourhood: f is folded in V when its normal has a
// negative dot product with the area-weighted normal of the triangles within `rings` vertex
// rings of it (its 2-ring by default), and is not so in V_rest (sharp features of the rest mesh,
// e.g. eyelids and ear rims, are not folds). Needs no ground truth: a self-check of a registered
// mesh, and on the synthetic truth it finds where linear blend skinning has collapsed a crease
// (armpit, groin, a finger's inner joint), which a fold-free registration cannot reproduce.
//   V #V by 3, V_rest #V by 3 (same topology F #F by 3); returns #F flags (1 = folded).
std::vector<char> locally_folded_triangles(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_rest,
                                           const Eigen::MatrixX3i& F, int rings = 2);

// Major joints compared by the pose evaluation (MakeHuman default skeleton names): for each
// body segment its most distal bone, whose world orientation is the segment's orientation
// whichever way a pose splits a rotation between the segment's bones (MakeHuman has two bones
// per limb segment and five in the spine).
const std::vector<std::string>& major_joints();

}  // namespace bodymodel
