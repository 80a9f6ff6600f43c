// Correspondence error of registrations against ground-truth correspondences (FAUST's protocol,
// Bogo et al. 2014; docs/evaluation.md#correspondence-between-meshes-faust-protocol).
//
// A data set of real bodies registered with a common template of its own (FAUST, SCAPE: vertex
// i of every truth mesh is the same point of the body) is registered again with our template.
// For an ordered pair (A, B): each truth vertex i of A is located on the registration of A (its
// closest surface point, as a triangle and barycentric coordinates), that point is carried to
// the registration of B (same triangle, same barycentric coordinates), and its distance to
// B's truth vertex i is the error. A pair is *inter-subject* when A and B are different people,
// *intra-subject* when they are the same person in different poses.
//
// Core takes arrays: the truths and registrations are given as matrices in one frame and unit
// (mm); tools/verbs/eval_correspondence.cc reads the files.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/progress.h"

namespace bodymodel {

// A point on a triangle mesh: triangle `face` and barycentric coordinates (sum 1, each ≥ 0).
struct SurfaceLocation {
  int face = -1;
  Eigen::Vector3d bary = Eigen::Vector3d::Zero();
  double distance = 0;  // from the located point to the surface
};

// The closest point of the triangle surface (V, F) to each row of P (exact: an AABB tree over
// all triangles), as a triangle and barycentric coordinates.   #P locations
// Throws InputError for an empty mesh, bad indices or non-finite input.
std::vector<SurfaceLocation> locate_on_surface(const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& V,
                                               const Eigen::MatrixX3i& F);

// Like locate_on_surface, but a point whose closest triangle faces away from its normal (PN, #P
// by 3 unit normals; dot < 0) is located instead on the closest triangle facing its way among the
// triangles around its `neighbours` nearest vertices of V (kept as it was when there is none).
// Where two limbs touch, a point of one limb lies within millimetres of the other's surface, which
// faces the opposite way; the closest point alone can land on the wrong limb. Approximate: the
// search is limited to those triangles.
std::vector<SurfaceLocation> locate_on_surface_oriented(const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& PN,
                                                        const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                                                        int neighbours = 32);

// The points at `locations` on the mesh V (#V by 3, the faces F the locations were made on).
Eigen::MatrixX3d carry_locations(const std::vector<SurfaceLocation>& locations,
                                 const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F);

// One registered mesh of the data set.
struct CorrespondenceMesh {
  std::string id;            // e.g. tr_reg_013
  std::string subject;       // the person (pairs of one subject are intra-subject)
  Eigen::MatrixX3d truth;    // #T by 3 truth vertices (data set topology), mm
  Eigen::MatrixX3d registered;  // #R by 3 registration vertices (template topology), mm
  // Optional #T by 3 outward unit normals of the truth: with them the truth vertices are located
  // by locate_on_surface_oriented (CorrespondenceOptions::oriented_location).
  Eigen::MatrixX3d truth_normals;
};

enum class PairSelection { inter, intra, all };

struct ErrorStats {
  long long count = 0;  // errors pooled (vertices × pairs)
  int pairs = 0;
  double mean = 0, median = 0, p95 = 0, max = 0;  // mm
};

struct PairError {
  int a = -1, b = -1;  // indices into the meshes
  bool inter = false;
  ErrorStats stats;
};

struct CorrespondenceReport {
  std::vector<PairError> pairs;  // every evaluated ordered pair (a ≠ b)
  ErrorStats inter, intra;       // pooled over all vertices of all pairs of that kind
  // Per mesh: mean distance (mm) of its truth vertices to its registration's surface (how far
  // the location step had to reach).
  std::vector<double> location_distance_mean;
  // #truth vertices by #meshes: the mean error of truth vertex i over the evaluated pairs that
  // include mesh m (as A or as B), where a mesh's contacts show (0 for a mesh in no pair).
  Eigen::MatrixXd vertex_error_mean;
};

struct CorrespondenceOptions {
  PairSelection pairs = PairSelection::all;
  // Pooled median and p95 come from a histogram of this bin width (mm) up to `histogram_max`
  // (larger errors are counted in the last bin; the max is exact): the pooled errors of FAUST's
  // 4 830 ordered pairs are 33 million values. Per-pair statistics are exact.
  double histogram_bin = 0.01;
  double histogram_max = 5000;
  // Locate each truth vertex on a registration triangle facing its way (needs truth_normals),
  // not on the closest triangle whatever its side: a diagnosis of contacts, not FAUST's protocol.
  bool oriented_location = false;
};

// Evaluates every ordered pair (a, b), a ≠ b, selected by options.pairs. truth_F: the truth
// topology's faces (unused by the metric, checked only for indices); registered_F: the
// template's faces. Every mesh must have the same truth and registration vertex counts.
CorrespondenceReport evaluate_correspondence(const std::vector<CorrespondenceMesh>& meshes,
                                             const Eigen::MatrixX3i& registered_F,
                                             const CorrespondenceOptions& options = {},
                                             const ProgressCallback& progress = {});

// Mean, median, 95th percentile (linear interpolation, numpy's default) and max of e.
ErrorStats error_stats(const Eigen::VectorXd& e);

}  // namespace bodymodel
