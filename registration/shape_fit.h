// Body shape fit in MakeHuman's macro-slider space, inside the pose stage of registration.
//
// The template is a MakeHuman body; a subject's shape differs from it in girths, limb lengths
// and proportions, and a template of the wrong shape leaves a tangential offset the non-rigid
// fit's normal-only data term cannot remove (Hasler et al. 2009 §2.2 only fits a global scale).
// Here the continuous macro sliders (gender, age, muscle, weight, height, proportions, cup; the
// ethnic mix optionally) are fitted to the scan with the pose held: the template is rebuilt for
// the sliders (core/makehuman.h), its skeleton follows the shape, and it is posed with the same
// joint rotations (the posed root head stays where it was), then compared with the scan by
// ICP-style closest-point pairs both ways (point-to-plane plus some point-to-point, Huber
// weights, the paper's rejection of normals > 30° and far pairs) and the landmarks. The sliders
// (clamped to [0, 1]), a global translation and optionally the global scale are solved by
// Levenberg–Marquardt with a finite-difference Jacobian (one body build per slider and
// iteration, a few ms each) and a weak prior towards the start sliders. This is the same kind of
// shape prior as fitting SMPL's β: on bodies outside MakeHuman's space the non-rigid fit does
// the rest.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/makehuman.h"
#include "core/mesh.h"
#include "core/shape_space.h"
#include "core/skeleton.h"
#include "registration/landmarks.h"

namespace bodymodel {

struct ShapeFitOptions {
  // Fitted sliders (names as macro_slider). Firmness moves few vertices; the ethnic mix is
  // nearly redundant with the others on a body's outline (add "african", "asian" to fit it).
  std::vector<std::string> sliders = {"gender", "age",         "muscle", "weight",
                                      "height", "proportions", "cup"};
  // Prior towards the start sliders: cost prior_weight·Σ(s − s₀)² in mm² of the MEAN squared
  // data residual (a slider 0.5 away costs 0.25·prior_weight mm²). Weak: the data decide.
  double prior_weight = 1.0;
  bool fit_translation = true;
  // Fit the global scale too, with a prior towards 1 (scale_prior·(scale − 1)², same units as
  // prior_weight): the height slider should carry the size, the scale only what is outside
  // MakeHuman's range. false: the scale stays as given.
  bool fit_scale = true;
  double scale_prior = 1e4;
  int icp_iterations = 6;        // closest-point pair updates
  int solver_iterations = 3;     // Levenberg–Marquardt steps per pair update
  double fd_step = 0.01;         // finite-difference step of the sliders (and the scale)
  int sample_vertices = 2500;    // template vertices used as pair samples (evenly strided)
  int scan_samples = 3000;       // scan points paired with their closest posed template vertex
  // Rejection (§2.2): the distance threshold halves from initial_max_distance down to
  // max_distance over the ICP iterations; normals more than max_normal_angle_deg apart.
  double initial_max_distance = 50.0;  // mm
  double max_distance = 20.0;          // mm
  double max_normal_angle_deg = 30.0;
  bool unsigned_normals = false;       // scans with estimated (unoriented) normals
  double point_to_point_weight = 0.3;  // as PoseFitOptions
  double robust_scale = 10.0;          // Huber scale, mm
  // Weight of the landmark term (mean squared landmark distance) relative to the mean data term.
  double landmark_weight = 1.0;
  // Template vertices mostly bound to the bones below these (hands: fingers poorly posed) are
  // not used as samples.
  std::vector<std::string> excluded_below = {"wrist.L", "wrist.R"};
  double convergence = 0.002;  // stop when no slider moves more than this in an ICP iteration
  // A shape space learned from real bodies (core/shape_space.h; not owned). With it the fit
  // moves the space's coefficients (in the people's standard deviations, and its sex slider g
  // when it has one) instead of `sliders`, with the Gaussian prior space_prior_weight·‖c‖² (same
  // units as prior_weight; none on g): the people's variances decide how far each direction
  // moves for a given gain in the data term.
  const ShapeSpace* space = nullptr;
  double space_prior_weight = 1.0;
  // The sex slider's prior: 2·min(g, 1 − g) squared times this (a body halfway between the sexes
  // costs the weight; the people are one or the other).
  double space_sex_prior_weight = 10.0;
  double space_fd_step = 0.05;       // sd
  double space_limit = 3.0;          // |c| bound, sd
  double space_convergence = 0.01;   // sd
  // Or a linear space of vertex positions (core/shape_space.h; not owned), e.g. a model's shape
  // space linearised around its mean: the same fit, prior and bounds as for `space` (its
  // coefficients in sd, no sex slider); its bodies' skeletons are placed from their vertices.
  const VertexShapeSpace* vertex_space = nullptr;
};

struct ShapeFitSummary {
  int icp_iterations = 0;
  int solver_steps = 0;        // accepted Levenberg–Marquardt steps
  int builds = 0;              // MakeHuman bodies built
  double rms_before = 0.0;     // RMS point-to-plane distance of the accepted pairs, first/last (mm)
  double rms_after = 0.0;
  double landmark_rms = 0.0;   // mm, last iteration
  double seconds = 0.0;
};

struct ShapeFitResult {
  MacroSettings settings;      // fitted sliders (with a space: the macros of its body)
  Eigen::VectorXd coefficients;  // with a space: its coefficients (sd units); else empty
  MakeHuman::Body body;        // the body for them (rest mesh, skeleton, weights; mm)
  double scale = 1.0;          // global scale about the root head (pose_template)
  Pose pose;                   // the given rotations; root translation adjusted
  Eigen::MatrixX3d V;          // #V by 3 posed template (13380 by 3, mm)
};

// Fits the sliders of `mh` to `scan` (unit normals) with the joint rotations of `pose` held.
// `start`: the starting sliders (also the prior's centre); `scale`, `pose`: the pose fit's
// result for the template body(start) (root translation included). Landmarks: template vertex
// → scan position (may be empty).
ShapeFitResult fit_shape(const MakeHuman& mh, const MacroSettings& start, double scale,
                         const Pose& pose, const PointCloud& scan,
                         const std::vector<Landmark>& landmarks,
                         const ShapeFitOptions& options = {}, ShapeFitSummary* summary = nullptr);
// The same in the learned space options.space or the vertex space options.vertex_space (exactly
// one): `start` are its coefficients (dimension() / components() values; empty = its mean body,
// g = 0.5), also where the fit starts; the prior's centre is the people's mean. With a vertex
// space the result's `settings` are MakeHuman's defaults (its bodies have no sliders).
ShapeFitResult fit_shape_in_space(const MakeHuman& mh, const Eigen::VectorXd& start, double scale,
                                  const Pose& pose, const PointCloud& scan,
                                  const std::vector<Landmark>& landmarks,
                                  const ShapeFitOptions& options, ShapeFitSummary* summary = nullptr);

}  // namespace bodymodel
