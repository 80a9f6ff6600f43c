// The registration of one scan as every front end runs it: `bodymodel register` (a scan
// database), `bodymodel register-mesh` (meshes of any topology) and Python's
// `bodymodel.register_scan` set RegistrationJobOptions from their flags, build the template once
// (registration_template) and call run_registration_job per scan. The post-steps (fold repair,
// the plausibility check) therefore cannot drift apart between them.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/makehuman.h"
#include "core/shape_space.h"
#include "core/progress.h"
#include "registration/fold_untangle.h"
#include "registration/landmarks.h"
#include "registration/register_scan.h"
#include "registration/scan.h"

namespace bodymodel {

// What to do with triangles folded after the non-rigid fit.
enum class FoldRepair {
  keep,   // leave them (diagnosis)
  local,  // repair_local_folds from the rest template's shape, then untangle_local_folds
  full,   // unfold_triangles against the posed template, then the local repair and untangling
};

// The user-facing settings, named as the verbs' flags.
struct RegistrationJobOptions {
  std::string schedule = "fast";  // non-rigid stiffness schedule: "paper" or "fast"
  int fast_steps = NonrigidOptions{}.fast_steps;
  double fast_k_end = NonrigidOptions{}.fast_k_end;
  double landmark_floor = NonrigidOptions{}.landmark_floor;
  double transform_length = NonrigidOptions{}.normalization_length;
  bool pose_only = false;    // stop after the pose fit (no post-steps either)
  bool proportions = true;   // segment proportions from the landmarks
  bool shape_fit = true;     // MakeHuman's macro sliders as the template's shape space
  bool proportions_with_shape = false;
  // "default" (default_pose_parameters), "segment", "bone" or "best" (segment and bone tried,
  // the closer kept).
  std::string pose_joints = "default";
  bool hand_stage = false;   // finger curls and thumbs after the body
  int pose_iterations = PoseFitOptions{}.max_icp_iterations;  // ICP iterations (0: landmarks only)
  FoldRepair folds = FoldRepair::local;
  // The start body's macro sliders (MakeHuman's default body when unset).
  std::optional<MacroSettings> start_shape;
  // A shape space learned from real bodies (`bodymodel shape-space`, core/shape_space.h): the
  // shape fit moves inside it, starting from its mean body (start_shape is then not used).
  std::shared_ptr<const ShapeSpace> learned_space;
  // Its prior weight (ShapeFitOptions::space_prior_weight): mm² of mean squared data residual a
  // coefficient of one standard deviation costs.
  double learned_space_prior = ShapeFitOptions{}.space_prior_weight;
  // Contacts: refuse non-rigid data pairs between body segments that do not touch on the
  // template (NonrigidOptions::contact_segments; off by default).
  bool contact_segments = NonrigidOptions{}.contact_segments;
  // Or the shape space of a model the project built (`--model`: its PCA shape space linearised
  // around the mean, model/model_shape_space.h): the shape fit moves its coefficients (sd units)
  // from its mean body. Not with learned_space.
  std::shared_ptr<const VertexShapeSpace> model_space;
  // As learned_space_prior. 10, not 1: better on every correspondence figure and in local folds
  // on 8 FAUST meshes (docs/real-registration.md#the-model-in-the-loop).
  double model_space_prior = 10.0;
};

// InputError naming the option when a value is out of range.
void validate(const RegistrationJobOptions& o);

// The template: MakeHuman's body of `o.start_shape`, with MakeHuman as its shape space unless
// o.shape_fit is off. Loads MakeHuman (throws as MakeHuman::load when its data is missing), so
// callers that register many scans build it once.
RegistrationTemplate registration_template(const RegistrationJobOptions& o);

// The registration options derived from `o` (validated), cheap to make.
struct RegistrationSetup {
  RegistrationOptions options;
  FoldRepair folds = FoldRepair::local;
  std::vector<std::string> pose_joint_names;  // by RegistrationSummary::pose_choice
};
RegistrationSetup registration_setup(const RegistrationJobOptions& o);

struct RegistrationJobResult {
  RegistrationResult registration;
  RegistrationSummary summary;
  int local_folds_repaired = 0;  // folds the local repair found (before it)
  // The untangling after it (registration/fold_untangle.h): the local folds left (locally_folded_
  // triangles against the fitted rest body; 0 unless its rounds ran out) and how far it moved
  // vertices. All zero when folds are kept.
  UntangleSummary untangle;
  std::string pose_joints;       // the parameterisation kept
};

// Registers `scan` (normals checked or estimated in place) with `landmarks`, then the post-steps
// of setup.folds and the plausibility check: a result that is not a body throws InputError
// "<what>: registration failed: …". A caller may change setup.options per scan (e.g. a start
// pose for diagnosis).
RegistrationJobResult run_registration_job(const RegistrationTemplate& tpl, const RegistrationSetup& setup,
                                           PointCloud& scan, const std::vector<Landmark>& landmarks,
                                           const std::string& what, const ProgressCallback& progress = {});

// The fitted shape as JSON text (for NAME.shape.json): the macro sliders, and with a learned
// space its coefficients under "shape_space_coefficients"; with a model's space (no sliders) only
// its coefficients, under "model_coefficients". Empty when there was no shape fit.
std::string registration_shape_json(const RegistrationResult& r);

// The registered vertices carried back to the template's rest pose: the inverse of the linear
// blend skinning that posed the template (r.rest_skeleton scaled by r.pose.scale about its root,
// r.pose.pose, `weights`), per vertex; where a vertex's blended map nearly degenerates (|det| <
// 0.05) its dominant bone's map is inverted instead. The result keeps the person's size (the
// pose fit's scale) and the non-rigid fit's detail: what a model of body shapes is built from.
Eigen::MatrixX3d unpose_registration(const RegistrationResult& r, const SkinWeights& weights);

}  // namespace bodymodel
