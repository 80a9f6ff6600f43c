// Non-rigid registration of a template mesh to a scan (Hasler et al. 2009 §2.3, after Amberg
// et al. 2007): one 3×4 affine transform T_i per template vertex, stacked into X (4n × 3),
// minimising
//   E(X) = α·Ed + β·Es + γ·El
//   Ed = Σ_i ‖p̃_i − T_i p_i‖²                (targets by the paper's *inverse* search)
//   Es = Σ_edges w_ij ‖(T_i − T_j) G‖²_F      (cotangent weights of the original template)
//   El = Σ_landmarks ‖l̃ − T_i p_i‖²
// Each iteration is one sparse linear least-squares solve; the sparsity pattern never changes,
// so the solver analyses it once (per template) and only refactorises numerically.
#pragma once

#include <Eigen/Core>
#include <Eigen/Sparse>
#include <memory>
#include <vector>

#include "core/mesh.h"
#include "core/point_index.h"
#include "core/progress.h"
#include "registration/landmarks.h"
#include "registration/segments.h"

namespace bodymodel {

enum class NonrigidSchedule {
  paper,  // §2.3: t = 0..tmax-1, β = k0·e^{λt}, λ = ln(k∞/k0)/tmax, correspondences every step
  fast,   // the same β range walked in `fast_steps` geometric steps (default)
};

// Which form of the smoothness term.
enum class Smoothness {
  // Σ_edges w_ij ‖T_i − T_j‖²_F (docs/method.md §2.5; first differences with cotangent weights).
  edge_differences,
  // Σ_i ‖Σ_j w_ij (T_i − T_j)‖²_F (the paper's eq. 4 read literally: second-order differences,
  // a squared Laplacian; insensitive to the sign of w_ij; denser system).
  laplacian_squared,
};

struct NonrigidOptions {
  NonrigidSchedule schedule = NonrigidSchedule::fast;
  Smoothness smoothness = Smoothness::edge_differences;
  // §2.3 eq. 6–7: β = k0·e^{λt}, k0 = 3000, k∞ = 0.01, tmax = 1500; α = 1; γ = 2β.
  double k0 = 3000.0;
  double k_inf = 0.01;
  int t_max = 1500;
  double alpha = 1.0;
  double landmark_factor = 2.0;        // γ = landmark_factor·β
  // γ never below this (0: the paper's γ = 2β to the end). As β falls the landmarks weigh as
  // little as a couple of data points, and where the template's face differs from the scan's the
  // point-to-plane data term lets the nose slide along the surface.
  double landmark_floor = 0.0;
  // Fast schedule: geometric β from k0 to fast_k_end in fast_steps solves (correspondences
  // recomputed before every solve). The benchmark compares it with `paper`.
  int fast_steps = 40;
  double fast_k_end = 1.0;
  // §2.3 correspondence rejection: normals more than 30° apart or points more than 50 mm apart.
  double max_distance = 50.0;          // mm
  double max_normal_angle_deg = 30.0;
  int min_plane_points = 4;            // |P_i| ≥ 4 → project onto the least-squares plane
  // The closest-point fallback is also rejected when the scan point lies more than this far
  // sideways (perpendicular to the vertex normal) from the vertex: in a hole of the scan the
  // closest point is on the hole's rim, and pulling towards it would crumple the mesh there
  // (the paper does not need border labelling; without this test its fallback re-introduces
  // the rim pull within 50 mm of a hole). ≤ 0: twice the scan's median point spacing.
  double max_tangential_offset = 0.0;  // mm
  // The inverse search likewise ignores a scan point lying farther sideways from its closest
  // vertex than this many mean edge lengths of the template: across a hole the closest vertex
  // of a scan point on the far rim is a hole vertex, and such pairs pull the hole's vertices
  // into spikes. 0: off (the paper's plain inverse search; 1.5 changed nothing measurable on
  // scan s001_p3: docs/benchmarks.md#figures-behind-code-comments).
  double inverse_tangential_factor = 0.0;
  double inverse_max_tangential_offset = 0.0;  // mm; resolved from the factor when ≤ 0
  // Compare normals without sign (for scans whose normals were estimated and are unoriented).
  bool unsigned_normals = false;
  // Transforms act on (p − c)/s with c the centroid of the initial vertices and s this length
  // (mm), so the linear and translation parts of T are in the same unit and Es is balanced
  // (Amberg's G = diag(1,1,1,γ) with γ = 1 in these coordinates).
  double normalization_length = 1000.0;
  // Cotangent weights can be negative (obtuse angles). Negative or tiny weights are clamped to
  // min_weight_fraction × mean positive weight so Es stays positive semi-definite and every
  // edge keeps some stiffness (documented deviation: the paper does not say).
  double min_weight_fraction = 0.05;
  // Reuse of the numeric factorisation (speed; not in the paper): a step first solves its system
  // by conjugate gradients preconditioned with the last factorisation, warm-started from the
  // previous transforms, and refactorises only when that does not reach a relative residual of
  // reuse_tolerance within reuse_max_iterations. Consecutive steps differ by one β factor and
  // a few changed correspondences, so most steps need a few triangular solves instead of a
  // factorisation. reuse_max_iterations ≤ 0: factorise every step.
  int reuse_max_iterations = 12;
  double reuse_tolerance = 1e-7;
  // Contacts: with body segments given (NonrigidRegistration::set_segments), every scan point
  // takes the segment of the initial (posed) template's surface it lies on
  // (registration/segments.h), and data pairs between a scan point and a vertex of segments that
  // do not touch on the template are refused both ways, so a hand resting on a hip is not pulled
  // onto the hip. Off (default): every pair is kept, as in the paper; on FAUST's contact poses
  // the refusal changed nothing measurable (docs/real-registration.md#contacts).
  bool contact_segments = false;
};

struct NonrigidSummary {
  int iterations = 0;
  double seconds = 0.0;
  double data_rms = 0.0;         // RMS of ‖p̃_i − T_i p_i‖ over matched vertices, final step (mm)
  double landmark_rms = 0.0;     // RMS landmark distance, final step (mm)
  int matched_vertices = 0;      // vertices with a data target in the final step
  int plane_matches = 0;         // of which by plane projection
  double final_beta = 0.0;
  double correspondence_seconds = 0.0;  // time in the inverse search (all steps)
  double solve_seconds = 0.0;           // time in factorisation + solve (all steps)
  int factorizations = 0;               // numeric factorisations (≤ iterations)
  int reuse_iterations = 0;             // preconditioned CG iterations, all steps
  int contact_refused = 0;              // scan points refused across segments, final step
};

// Median distance from a scan point to its nearest neighbour (from up to 2000 samples).
double median_point_spacing(const PointIndex& scan_index);

// The β value of every iteration of a schedule.
std::vector<double> nonrigid_schedule(const NonrigidOptions& options);

// Result of the inverse correspondence search.
struct InverseCorrespondences {
  Eigen::MatrixX3d target;   // #V by 3 target positions p̃_i (valid where kind != 0)
  Eigen::VectorXi kind;      // #V: 0 = no data term, 1 = plane projection, 2 = closest scan point
  int plane_count = 0;
  int closest_count = 0;
  int refused = 0;           // scan points whose closest vertex was on a non-adjacent segment
};

// Segment labels for the search (contacts): pairs of incompatible segments are refused.
struct SegmentLabels {
  const BodySegments* segments = nullptr;
  Eigen::VectorXi point_segment;  // #scan points (-1: unknown, compatible with every segment)
};

// The paper's inverse search (§2.3): every scan point → closest vertex of V (rejecting pairs
// farther than max_distance or with normals more than max_normal_angle_deg apart); a vertex
// with ≥ min_plane_points matched points is projected onto their least-squares plane;
// otherwise the closest scan point is used if it passes the same tests; otherwise none.
//   V, VN  #V by 3 current vertices and unit vertex normals; scan with unit normals;
//   scan_index  k-d tree over scan.P. max_tangential_offset and inverse_max_tangential_offset must
//   be resolved (> 0) or they are not applied. With `labels`, a scan point whose closest vertex is
//   on a segment incompatible with its own is not matched, and a vertex's closest-point fallback
//   takes the closest of its 8 nearest scan points on a compatible segment.
InverseCorrespondences inverse_correspondences(const Eigen::MatrixX3d& V,
                                               const Eigen::MatrixX3d& VN,
                                               const PointCloud& scan,
                                               const PointIndex& scan_index,
                                               const NonrigidOptions& options,
                                               const SegmentLabels* labels = nullptr);

// Repairs folds of a registered mesh: triangles of V whose normal points away from the same
// triangle of V_ref (the pose-fitted template, which has the right orientation everywhere),
// grown by `rings` vertex rings, are re-solved so that their vertices' umbrella-Laplacian
// coordinates equal V_ref's (the region takes the reference's local shape, glued to the
// unchanged vertices around it). Repeats up to `passes` times while flipped triangles remain.
// Returns the number of triangles flipped against V_ref before the repair. `pinned` vertices
// (the landmarks' vertices) keep their place: the fit put them where the reference's shape
// would not, and re-solving them slid the nose tip 10 mm off its landmark on FAUST.
//   V #V by 3 (modified in place), V_ref #V by 3, F #F by 3.
int repair_flipped_triangles(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref,
                             const Eigen::MatrixX3i& F, int rings = 2, int passes = 3,
                             const std::vector<int>& pinned = {});

// Solver object: built once per template (cotangent weights of the *original* template,
// symbolic factorisation), then fit() to any number of scans. Not thread-safe: use one object
// per thread.
class NonrigidRegistration {
 public:
  // template_rest: the original template (for the weights and the topology).
  NonrigidRegistration(const Mesh& template_rest, const NonrigidOptions& options = {});
  ~NonrigidRegistration();
  NonrigidRegistration(NonrigidRegistration&&) noexcept;

  // Deforms V_init (#V by 3, e.g. the pose-fitted template, scan unit) onto `scan` (unit
  // normals required; see prepare_scan). Returns the registered vertices (#V by 3).
  // Throws NumericalError if a factorisation fails.
  Eigen::MatrixX3d fit(const Eigen::MatrixX3d& V_init, const PointCloud& scan,
                       const std::vector<Landmark>& landmarks, NonrigidSummary* summary = nullptr,
                       const ProgressCallback& progress = {});

  const NonrigidOptions& options() const;
  // Body segments of the template (contacts, NonrigidOptions::contact_segments); without them
  // no pair is refused.
  void set_segments(BodySegments segments);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bodymodel
