// The whole registration of one scan (Hasler et al. 2009 §2): scan checks, skeleton-based pose
// estimation (§2.2), then non-rigid registration (§2.3) started from the posed template.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/io/pose_csv.h"
#include "core/makehuman.h"
#include "core/mesh.h"
#include "core/progress.h"
#include "core/shape_space.h"
#include "core/skeleton.h"
#include "registration/landmarks.h"
#include "registration/nonrigid.h"
#include "registration/pose_fit.h"
#include "registration/proportions.h"
#include "registration/scan.h"
#include "registration/shape_fit.h"

namespace bodymodel {

// The template: rest mesh (mm), skeleton and LBS weights (e.g. the MakeHuman default body).
struct RegistrationTemplate {
  Mesh mesh;
  Skeleton skeleton;
  SkinWeights weights;
  // Optional shape space: the template is shape_space->body(shape_start) (mesh, skeleton and
  // weights above must be that body). With it, register_scan fits the macro sliders in the
  // pose stage (RegistrationOptions::fit_shape); without it, the global scale and the
  // landmark proportions stand in.
  std::optional<MakeHuman> shape_space;
  MacroSettings shape_start;
  // Optional space learned from real bodies (core/shape_space.h), inside shape_space's
  // parameters: with it the shape fit moves its coefficients (start: learned_start, empty = the
  // people's mean body, which the template then is) instead of the macro sliders.
  std::shared_ptr<const ShapeSpace> learned_space;
  Eigen::VectorXd learned_start;
  // Or a linear space of vertex positions (e.g. a built model's shape space, core/shape_space.h):
  // the shape fit moves its coefficients (from learned_start, empty = its mean body, which the
  // template then is). Not with learned_space.
  std::shared_ptr<const VertexShapeSpace> vertex_space = nullptr;  // (initialised: braced lists may omit it)
};

struct RegistrationOptions {
  ScanCheckOptions scan;
  PoseFitOptions pose;
  // Further pose fits tried after `pose` (e.g. another parameterisation); the fit with the
  // smallest two-sided distance to the scan (PoseFitSummary::two_sided_mm) is kept.
  std::vector<PoseFitOptions> pose_alternatives;
  NonrigidOptions nonrigid;
  // Stretch the template's segments to the landmarks' proportions before the pose fit
  // (registration/proportions.h); needs ≥ 3 landmarks.
  bool fit_proportions = true;
  ProportionOptions proportions;
  // With a shape space in the template: alternate pose fit and shape fit (registration/
  // shape_fit.h) up to shape_rounds times, until no slider moves more than shape_convergence,
  // then start the non-rigid fit from the shaped, posed template. The proportions are then not
  // applied (the sliders carry them) unless proportions_with_shape.
  bool fit_shape = true;
  ShapeFitOptions shape;
  int shape_rounds = 3;
  double shape_convergence = 0.01;
  double learned_space_convergence = 0.05;  // the same for a learned space's coefficients (sd)
  bool proportions_with_shape = false;
  // When the alternation stops unconverged (the last shape fit moved a slider), one more pose
  // fit on the last shape, so the pose and the shape handed to the non-rigid fit belong together
  // (without it the pose was fitted on the shape before). Better on every registration figure
  // for one more pose fit per scan (measured in docs/registration.md#history).
  bool final_pose_fit = true;
  // After the first shape fit, the pose fits keep the shape fit's global scale (the height
  // slider carries the size) instead of fitting their own.
  bool shape_fixes_scale = true;
  // The non-rigid fit's cotangent weights from the shaped body (else the template's).
  bool nonrigid_on_shaped_rest = true;
  bool skip_nonrigid = false;  // stop after the pose fit
  // After the non-rigid fit, triangles folded against the pose-fitted template are re-solved
  // from its local shape (repair_flipped_triangles, this many vertex rings around them).
  // ≤ 0 rings: off.
  int repair_flipped_rings = 2;
  // Repair passes while folds remain, pass p growing the region by p more rings. 6 (rings up to
  // 7): a large face fold (15-scan database, s001_p3) needs the 5th pass; with 3 it was left
  // whole (docs/benchmarks.md#figures-behind-code-comments).
  int repair_flipped_passes = 6;
  // Evaluation only (diagnosis of the non-rigid stage on synthetic data; never for real scans):
  // skip the pose fit and start the non-rigid fit from
  //  - start_vertices (#V by 3, template topology, mm) if non-empty, e.g. the true mesh, so the
  //    result's error is the non-rigid stage's own drift; else
  //  - start_pose: the (proportioned) template posed with this record (e.g. the truth's pose).
  Eigen::MatrixX3d start_vertices;
  std::optional<PoseRecord> start_pose;
};

struct RegistrationSummary {
  ScanCheckReport scan;
  PoseFitSummary pose;
  int pose_choice = 0;  // 0: `pose`, k ≥ 1: pose_alternatives[k − 1]
  NonrigidSummary nonrigid;
  double seconds = 0.0;
  int folded_triangles = 0;  // flipped against the pose-fitted template before the repair
  int shape_rounds = 0;      // pose ↔ shape alternations done (0: no shape fit)
  ShapeFitSummary shape;     // the last shape fit
  double shape_seconds = 0.0;  // all shape fits
};

struct RegistrationResult {
  Eigen::MatrixX3d V;     // #V by 3 registered template vertices (template topology, mm)
  PoseFitResult pose;     // scale, joint rotations and the posed template
  Proportions proportions;  // segment ratios applied to the template (empty if none)
  std::optional<MacroSettings> shape;  // fitted sliders (with a shape fit)
  Eigen::VectorXd shape_coefficients;  // with a learned or vertex space: its fitted coefficients (sd)
  Mesh rest;                // the rest template the pose was fitted on (shaped/proportioned, mm)
  Skeleton rest_skeleton;   // its skeleton (unscaled, rest pose): with pose, what posed the template
};

// Registers `scan` (modified: normals checked/estimated) with `landmarks` (template vertex →
// scan position). `what` names the scan in error messages.
RegistrationResult register_scan(const RegistrationTemplate& tpl, PointCloud& scan,
                                 const std::vector<Landmark>& landmarks,
                                 const RegistrationOptions& options, const std::string& what,
                                 RegistrationSummary* summary = nullptr,
                                 const ProgressCallback& progress = {});

}  // namespace bodymodel
