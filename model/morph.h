// Morphing a body by its labels (Hasler et al. 2009 §4, §5.1, §5.2; docs/method.md §4.3, §4.5):
// "make this person 10 cm taller but keep the weight", "200 different women of 65 kg".
//
// A label change is requested in the shape model's coefficient space: the minimum-norm change
// z meeting all label changes at once (eq. 11, semantic.h constrained_change), applied to the
// body's own encoding as x' = x + basis·z (optionally masked per triangle, §5.1), decoded.
//
// MEASUREMENT-CORRECTED ITERATIONS. The regression (eq. 10) is linear and only approximately
// what `bodymodel measure` reports on the decoded mesh (weight is a volume, height an extent:
// neither is linear in the encoding). So for labels that can be measured on a mesh (height,
// weight, girths, body fat) the solver works like a secant/Newton iteration on the MEASURED
// value: morph, decode, measure the output, add the remaining error (target − measured) to the
// requested change, re-solve eq. 11, repeat until every label is within tolerance. Labels
// that cannot be measured (age, muscle, sex, sliders) use the model's own prediction, which is
// met exactly in the first step.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/fold_repair.h"
#include "core/measure.h"
#include "encoding/relative_rotation_decoder.h"
#include "model/body_model.h"

namespace bodymodel {

// The measured value of a label on a mesh (height_cm, weight_kg, waist_cm, hips_cm, chest_cm,
// neck_cm, volume_l, body_fat_pct, and on template bodies the survey measurements
// waist_iliac_cm, arm_circumference_cm, upper_arm_length_cm, upper_leg_length_cm; core/measure.h),
// or nullopt for labels a mesh cannot tell.
std::optional<double> measured_label(const std::string& name, const BodyMeasurements& m);
bool is_measurable_label(const std::string& name);

// One condition on a label: exact (lo == hi), a range [lo, hi], or "keep" (the body's current
// value, resolved by the solver).
struct LabelCondition {
  std::string label;
  double lo = 0, hi = 0;
  bool keep = false;
  static LabelCondition exact(std::string l, double v) { return {std::move(l), v, v, false}; }
  static LabelCondition range(std::string l, double a, double b) { return {std::move(l), a, b, false}; }
  static LabelCondition keep_current(std::string l) { return {std::move(l), 0, 0, true}; }
};

struct MorphOptions {
  int max_iterations = 8;          // measurement-corrected iterations (see header comment)
  double tolerance_cm = 0.25;      // for labels in cm (height, girths)
  double tolerance_kg = 0.25;      // for weight
  double tolerance_other = 0.01;   // other labels, in units of the label's standard deviation
  // Range conditions aim this fraction of the range inside each bound (so that a body that
  // measures slightly differently still lands inside).
  double range_margin = 0.1;
  // Where a range condition aims when the start value is outside the range's inner part:
  // < 0 = the nearest inner point; in [0, 1] = that fraction across the inner part.
  double range_aim = -1;
  Eigen::VectorXd triangle_mask;   // #F in [0, 1] (§5.1, Fig. 6); empty = the whole body
  Sex sex = Sex::unknown;          // for the body-fat measurement
  ConstrainedChangeOptions change; // eq. 11 solver
  // The most likely change instead of the smallest: eq. 11 in the metric of the PCA eigenvalues
  // (ConstrainedChangeOptions::metric), i.e. the model's conditional mean of the body given the
  // label changes. From the mean body this makes "the typical person" with those labels (the
  // smallest change would leave every direction the labels do not force at the mean, however
  // strongly the data ties it to them); for an existing body the paper's smallest change keeps
  // more of the person.
  bool prior_weighted = false;
  // Correct with the measured response instead of a unit slope: the Jacobian J of the measured
  // labels with respect to the requested (eq. 11) change, by finite differences at the model's
  // mean body (1 + #measured-labels decodes, once per morpher and label set, cached), and each
  // iteration requests J⁻¹·(target − measured). The regression's slope is not the measured one
  // (weight is a volume, height an extent): with a unit slope a 65 kg request typically falls
  // short and needs a third decode (docs/results.md#generated-crowds). Worth it when many bodies share the
  // label set (generation), not for one morph.
  bool calibrated_response = false;
  // With calibrated_response: the shape coefficients of the body where the response is
  // calibrated (empty = the model's mean body, 0). There the labels are measured on the decoded
  // anchor and the response is fitted as a QUADRATIC function of the requested change (central
  // steps of 1.5 label standard deviations and, for up to 4 measured labels, their pairs, plus a
  // linear term per other label but sex (age): 1 + 2k + k(k−1)/2 + #other decodes, cached), not
  // the slope at the mean. The first request inverts
  // that model, later ones use its Jacobian at the current request. A start exactly at the
  // anchor (a population crowd at --spread 0: every body of a sex starts at its subjects'
  // mean) takes the anchor's measured values as its start; another start the regression's
  // prediction corrected by its error measured at the anchor (an approximation: the correction
  // is exact at the anchor only). On population bodies the regression is off in height at
  // the anchor, weight responds non-linearly far from the mean and also changes with age; this
  // model cut the decodes per body to about one (measured in docs/population.md#figures).
  Eigen::VectorXd response_anchor;
};

struct LabelOutcome {
  std::string label;
  double target = 0;     // the goal (a range's aim point for ranges)
  double lo = 0, hi = 0; // the accepted interval
  double start = 0;      // value before morphing
  double achieved = 0;   // value after morphing (measured when measurable)
  bool measured = false;
  bool satisfied = false;
};

struct MorphSummary {
  int iterations = 0;
  bool converged = false;
  std::vector<LabelOutcome> labels;
  double change_norm = 0;  // ‖z‖, coefficient units
  double seconds = 0;
  int decodes = 0;         // decoder calls (the cost of a morph)
  std::string report() const;  // one line per label
};

// Shape-space morphing, generation and decoding with one reusable decoder. Thread-safe: the
// const methods may run concurrently on one morpher (the decoder is, see
// encoding/relative_rotation_decoder.h), with results bit-identical to sequential calls.
class ShapeMorpher {
 public:
  explicit ShapeMorpher(std::shared_ptr<const BodyModel> model, DecoderOptions options = {});

  const BodyModel& model() const { return *model_; }
  RelativeRotationDecoder& decoder() { return decoder_; }

  // Decodes encoding values x (relative to the model's mean), aligned to the template.
  Eigen::MatrixX3d decode(const Eigen::VectorXd& x) const;
  // The shape model's pca.reconstruct(c) = mean + basis·c. When every basis value is a float32
  // (a model read from a file stores its bases so, model/model_file.h) the product reads a
  // float32 copy of the basis, made on first use: half the memory traffic of the double basis
  // (the product is memory-bound), the same values, summed in double in another order (results
  // within rounding of pca.reconstruct). Otherwise pca.reconstruct itself. Thread-safe.
  Eigen::VectorXd reconstruct(const Eigen::VectorXd& c) const;
  // measure_body (core/measure.h) of V.
  BodyMeasurements measure(const Eigen::MatrixX3d& V, Sex sex) const;

  // Morphs the body V (#V by 3, mm; the model's topology) to meet `conditions`. The result is
  // rigidly placed onto V (best fit, then its lowest point put at V's lowest point). Throws
  // InputError for unknown labels (listing the valid ones) or a conflicting label given twice.
  Eigen::MatrixX3d morph(const Eigen::MatrixX3d& V, const std::vector<LabelCondition>& conditions,
                         const MorphOptions& options = {}, MorphSummary* summary = nullptr) const;

  // The same starting from encoding values x0 (no placement: template-aligned output).
  // `c0_known`: the shape coefficients of x0 when the caller has them (x0 = pca.reconstruct(c0)),
  // which saves projecting x0 (a pass over the whole D by K basis). With c0_known, x0 may be
  // empty: then it is reconstructed only if needed (a mask, a kept label, no iterations), and each
  // candidate is mean + basis·(c0 + z) (one pass over the basis instead of two).
  // Computes and caches what morph_encoding with these conditions and options calibrates
  // (MorphOptions::calibrated_response) now, its decodes in parallel. Optional.
  void prepare(const std::vector<LabelCondition>& conditions, const MorphOptions& options) const;

  Eigen::MatrixX3d morph_encoding(const Eigen::VectorXd& x0, const std::vector<LabelCondition>& conditions,
                                  const MorphOptions& options, MorphSummary* summary,
                                  Eigen::VectorXd* x_out = nullptr,
                                  const Eigen::VectorXd* c0_known = nullptr) const;

 private:
  // The measured response (see MorphOptions::calibrated_response) for the conditions' labels,
  // cached by label set, sex and anchor (thread-safe; a deterministic function of the model, the
  // label set and the anchor). Its calibration decodes run in parallel.
  struct Response;
  std::shared_ptr<const Response> measured_response(const std::vector<LabelCondition>& conditions,
                                                    const MorphOptions& o) const;

  std::shared_ptr<const BodyModel> model_;
  RelativeRotationDecoder decoder_;
  struct ResponseCache;
  std::shared_ptr<ResponseCache> response_cache_;
  struct FloatBasis;
  std::shared_ptr<FloatBasis> float_basis_;
};

// The fold repair bodies get after decoding (generation and morphing): 8 passes, regions up to
// 2 + 7 rings, because the under-bust triangles of a full-breasted body need the wider regions.
FoldRepairOptions body_fold_repair_options();

// Random bodies from the shape-only model (§5.2).
struct GenerateOptions {
  // Coefficients ~ N(0, eigenvalues) scaled by this (1 = the data's spread). When a sex
  // condition is given, coefficients are drawn from that sex's subjects instead: their mean
  // plus a random Gaussian combination of their deviations (the within-sex distribution).
  double spread = 1.0;
  int max_attempts = 4;   // fresh samples when the conditions cannot be met
  // GeneratedBody::measured with the girths (measure_body, convex-hull sections: a large share
  // of a body's time); false = height, volume and weight only (the rest NaN).
  bool measure_girths = true;
  // Fold repair after decoding (repair_body_folds): a decoded body can fold a few tiny
  // triangles (toes, eyelids: docs/results.md#generated-crowds); they are
  // re-solved from the template's local shape, and the labels are measured AFTER the repair.
  bool repair_folds = true;
  // 8 passes (regions up to 2 + 7 rings): the under-bust triangles of a full-breasted body
  // (30-160 mm², turned 90-120° against the template's) need the wider regions; 3 passes left
  // some bodies folded (docs/benchmarks.md#figures-behind-code-comments; the re-solve moves vertices and the
  // weight, which the measurement after the repair sees).
  FoldRepairOptions fold_repair = body_fold_repair_options();
  // Morph settings; generation accepts 1 kg / 1 cm around exact targets (every decode costs,
  // and a crowd "of 65 kg" is checked at ± 2 kg), morphing keeps the tighter 0.25.
  MorphOptions morph = [] {
    MorphOptions m;
    m.tolerance_kg = 1.0;
    m.tolerance_cm = 1.0;
    m.calibrated_response = true;
    return m;
  }();
};

struct GeneratedBody {
  Eigen::MatrixX3d V;              // #V by 3, mm, template-aligned
  Eigen::VectorXd encoding;        // D values relative to the model's mean
  BodyMeasurements measured;
  MorphSummary summary;
  int attempts = 0;
  bool satisfied = false;
  FoldRepairSummary folds;         // the fold repair (GenerateOptions::repair_folds)
};

// Calibrates what generate_body with these conditions and options will need (the measured
// response at the conditions' sex's anchor, see MorphOptions::calibrated_response) with every
// core, so that concurrent generate_body calls do not wait for one thread to do it. Optional:
// the results are the same without it.
void prepare_generation(const ShapeMorpher& morpher, const std::vector<LabelCondition>& conditions,
                        const GenerateOptions& options);

// Throws InputError naming the option when `options` cannot generate bodies (a spread that is
// negative or not finite). generate_body, prepare_generation and the crowd call it.
void check_generate_options(const GenerateOptions& options);

// One body; `seed` makes it reproducible. Conditions may use "sex" with 0 = female, 1 = male.
GeneratedBody generate_body(const ShapeMorpher& morpher, const std::vector<LabelCondition>& conditions,
                            uint64_t seed, const GenerateOptions& options = {});

// morpher.measure(V, sex) of a body morphed for `conditions`. A body that cannot be measured
// (targets each within its label's range but contradictory together turn the body inside out)
// is an InputError naming those targets.
BodyMeasurements measure_morphed(const ShapeMorpher& morpher, const Eigen::MatrixX3d& V, Sex sex,
                                 const std::vector<LabelCondition>& conditions);

// The cheap part of core/measure.h's measure_body, with its definitions: height = extent
// along +y (cm), volume (L), weight = volume × density (kg); girths and body fat NaN.
//   V #V by 3 (mm), F #F by 3.
BodyMeasurements measure_height_and_weight(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F);

// Plausibility of a decoded body: triangles whose normal points against the template's
// (after a rigid fit of V onto the template), and the relative encoding residual
// ‖encode(V) − x‖ / ‖x − x̄‖ (how far the decoder had to deviate from the requested encoding).
int flipped_triangle_count(const BodyModel& model, const Eigen::MatrixX3d& V);

// Repairs the triangles flipped_triangle_count counts, in place (core/fold_repair.h against the
// template rigidly fitted onto V, with the reference's local shape rotated and scaled to V's):
// afterwards flipped_triangle_count(model, V) == summary.flipped_after <= flipped_before.
//   V #V by 3 (mm, modified in place).
FoldRepairSummary repair_body_folds(const BodyModel& model, Eigen::MatrixX3d& V,
                                    const FoldRepairOptions& options = {});

// A morph as a user asks for it (`bodymodel morph`, Python's Model.morph): from the body V (#V by
// 3, mm) or, when V is null, from the model's mean body (template-aligned), then the fold repair
// generation applies, so both front ends return the same body.
struct MorphedBody {
  Eigen::MatrixX3d V;
  MorphSummary summary;
  FoldRepairSummary folds;
};
MorphedBody morph_body(const ShapeMorpher& morpher, const Eigen::MatrixX3d* V,
                       const std::vector<LabelCondition>& conditions, const MorphOptions& options,
                       const FoldRepairOptions& repair = body_fold_repair_options());

// "height_cm = 250 (reached 212.3), …": the labels a morph did not meet.
std::string unmet_labels(const MorphSummary& summary);

// Root-mean-square vertex distance between two bodies after a rigid fit of b onto a (mm).
double rms_vertex_distance(const Eigen::MatrixX3d& a, const Eigen::MatrixX3d& b);

}  // namespace bodymodel
