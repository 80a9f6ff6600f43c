// A MakeHuman body from a person's measurements (the "virtual caliper" job, issue 23).
//
// Finds MakeHuman's macro sliders (gender, age, muscle, weight, height, proportions, cup,
// firmness, the three ethnic weights) AND its 20 measurement modifiers (targets/measure/:
// waist-circ, hips-circ, bust-circ, upperarm-circ, upperarm-length, upperleg-height, ...) whose
// body, MEASURED on the output mesh with core/measure.h's definitions, has the requested
// measurements.
//
// Method: bounded Levenberg–Marquardt on
//     Σ_k ((m_k(x) − t_k) / σ_k)²  +  Σ_j ((x_j − x0_j) / s_j)²,
// m_k = measure_body of the built body (survey definitions), t_k the targets, σ_k a small
// per-unit scale (the data term dominates wherever the targets are reachable), x0 the prior
// (gender 0 or 1 from the sex, the age slider from the age, the ethnic mix, everything else
// MakeHuman's default), s_j how freely each slider may move: the prior picks "the most ordinary
// body" among the many that measure the same (a person given by height and weight alone gets
// default proportions). The Jacobian is by forward differences of the measured values (the
// measures are convex-hull perimeters and an arg-max level, not differentiable in closed
// form), refreshed every few steps with Broyden updates between; each evaluation builds the body
// and measures it (milliseconds, measuring the larger part). The start is the best of a coarse (muscle, weight) grid.
//
// REACH. MakeHuman's sliders in [0, 1] and modifiers in [−1, 1] do not reach heavy people (a
// 160 cm woman at weight 1, muscle 0 measures BMI ≈ 33). The EXTENDED space lets a few sliders
// go beyond MakeHuman's range, where the targets are extrapolated linearly
// (MakeHuman::BuildOptions::allow_extrapolation): weight up to `weight_max`, muscle down to
// `muscle_min`, the modifiers to ±`modifier_limit`. docs/population.md reports the NHANES
// coverage in both spaces and the roughness of bodies at the extended bounds.
//
// A person outside the reach gets the closest body (least squares) and `reached = false` with a
// reason naming the measurements that miss and the sliders held at a bound — never a silent miss.
#pragma once

#include <Eigen/Core>
#include <array>
#include <functional>
#include <string>
#include <vector>

#include "core/makehuman.h"
#include "core/measure.h"
#include "core/plausibility.h"

namespace bodymodel {

// One requested measurement: a name of measurement_definitions() (core/measure.h) that the fit
// supports (fittable_measurements()) and its value in that unit.
struct MeasurementTarget {
  std::string name;
  double value = 0;
};

// Names fit_measurements accepts: height_cm, weight_kg, waist_iliac_cm, hips_cm,
// arm_circumference_cm, upper_arm_length_cm, upper_leg_length_cm, waist_cm, chest_cm, neck_cm.
const std::vector<std::string>& fittable_measurements();

// Throws InputError for an unknown name (listing the valid ones) or a name given twice.
void validate_measurement_names(const std::vector<std::string>& names);

// Throws InputError for an unknown name (listing the valid ones), a name given twice, a
// non-finite value, or a value outside the physically possible range of that measurement
// (height 50–250 cm, weight 20–350 kg, girths 15–250 cm, lengths 10–80 cm: "waist 20 cm").
void validate_measurement_targets(const std::vector<MeasurementTarget>& targets);

struct PersonSpec {
  Sex sex = Sex::female;
  double age_years = 40;
  std::vector<MeasurementTarget> targets;
  // Prior of the ethnic sliders (african, asian, caucasian; sum 1): MakeHuman's default 1/3 each.
  std::array<double, 3> ethnic_prior{1.0 / 3, 1.0 / 3, 1.0 / 3};
};

struct FitMeasurementsOptions {
  // Sliders beyond MakeHuman's range (header comment). false = MakeHuman's own space.
  bool extended_space = true;
  // Extended bounds, chosen where the extrapolated bodies stay smooth (docs/population.md): a
  // woman at weight 1.25, muscle 0 has trunk roughness p95 ≈ 10° against 8.4° at weight 1 and
  // 18° at 1.6, where folds cut across belly and back; a negative muscle creases every body.
  double weight_max = 1.25;      // extended upper bound of the weight slider (MakeHuman: 1)
  double muscle_min = 0.0;       // extended lower bound of the muscle slider (MakeHuman: 0)
  double modifier_limit = 1.5;   // extended bound of the measurement modifiers (MakeHuman: 1)
  // Beyond MakeHuman's range each slider pays an extra ((excess) / scale)² on top of its prior,
  // so the fit stays inside the range whenever the range reaches the person.
  double extension_scale_slider = 0.05, extension_scale_modifier = 0.1;
  // Ages 18–24: MakeHuman's age slider below 0.5 (25 y) blends towards its 10-year-old child
  // targets, which no adult has; adults younger than 25 get the 25-year-old shape (slider 0.5).
  bool adult_shape_below_25 = true;
  int max_iterations = 40;
  // The fit stops when an accepted step lowers the cost by less than `relative_tolerance` of it
  // and every target is within stop_cm / stop_kg (in the target's unit).
  double relative_tolerance = 1e-2;
  int polish_steps = 3;          // ... or after this many accepted steps with the targets met
  int refresh_every = 4;         // steps between forward-difference Jacobians (Broyden between)
  double stop_cm = 0.1, stop_kg = 0.2;
  // "Reached": every target within these (the bar: 0.5 cm height, 1 kg, 2 cm girths).
  double reach_height_cm = 0.5, reach_weight_kg = 1.0, reach_other_cm = 2.0;
  // Data-term scales σ_k per unit (smaller = stiffer), and prior scales s_j of the sliders.
  double sigma_cm = 0.1, sigma_kg = 0.15;
  double prior_gender = 0.02, prior_age = 0.05, prior_muscle = 0.5, prior_weight = 0.5,
         prior_height = 0.5, prior_proportions = 0.25, prior_breast = 0.25, prior_ethnic = 0.15,
         prior_modifier = 0.4;
  MeasureOptions measure;        // measurement options (band girths switched on when needed)
};

struct MeasurementResidual {
  std::string name;
  double target = 0, achieved = 0;
  double residual() const { return achieved - target; }
  bool within = false;  // |residual| within the reach tolerance
};

struct MeasurementFit {
  MacroSettings sliders;         // may lie outside [0, 1] in the extended space
  Eigen::VectorXd modifiers;     // one per MakeHuman::measure_modifier_names()
  Eigen::MatrixX3d V;            // the body (13 380 by 3, mm), MakeHuman's frame
  BodyMeasurements measured;     // measure_body of V (all definitions)
  std::vector<MeasurementResidual> residuals;  // one per target, in the targets' order
  bool reached = false;          // every target within its reach tolerance
  bool extrapolated = false;     // some slider or modifier outside MakeHuman's range
  Roughness roughness;           // core/plausibility.h, over MakeHuman's trunk and limbs
  int self_intersections = 0;    // intersecting triangle pairs of V
  std::string reason;            // when not reached: what misses, which sliders sit at a bound
  int iterations = 0, evaluations = 0;
  double seconds = 0;
  std::string sliders_text() const;  // "gender=0.000 age=0.692 ..., waist-circ=0.31, ..."
};

// Fits one person. Throws InputError for bad targets (validate_measurement_targets), an age
// below 1 or above 90 years, or a MakeHuman data folder without targets/measure.
MeasurementFit fit_measurements(const MakeHuman& makehuman, const PersonSpec& person,
                                const FitMeasurementsOptions& options = {});

// The MakeHuman age slider for an age in years (inverse of MacroSettings::age_years; ages
// 18–24 map to 0.5 when adult_shape_below_25).
double age_slider_for_years(double years, bool adult_shape_below_25);

}  // namespace bodymodel

namespace bodymodel {

// How plausible a body (hm08 topology, mm, standard pose) is against MakeHuman's own body with
// the nearest sliders: the MakeHuman body fitted (fit_measurements) to the body's measured
// height, weight, waist at the iliac crest and hip, and the roughness of both over MakeHuman's
// trunk and limbs (core/plausibility.h).
struct PlausibilityReport {
  BodyMeasurements measured;     // of the body
  Roughness roughness;           // of the body
  int self_intersections = 0;    // of the body
  Roughness reference;           // of the nearest MakeHuman body
  int reference_self_intersections = 0;
  bool reference_reached = false;  // the reference measures as the body (fit reached)
  double p95_ratio() const { return reference.p95_deg > 0 ? roughness.p95_deg / reference.p95_deg : 0; }
};
// V 13380 by 3 (mm), F the template's faces; `age_years` for the reference's age slider.
PlausibilityReport plausibility_against_makehuman(const MakeHuman& makehuman, const Eigen::MatrixX3d& V,
                                                  const Eigen::MatrixX3i& F, Sex sex, double age_years,
                                                  const FitMeasurementsOptions& options = {});

}  // namespace bodymodel
