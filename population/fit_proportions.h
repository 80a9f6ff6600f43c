// A MakeHuman body from any subset of a survey's measurements (ANSUR II's columns), driving every
// body modifier: the macro sliders, the 20 measurement modifiers and the body-shape modifiers
// (core/makehuman.h shape_modifiers(); left and right limb modifiers move together, as the surveys
// measure one side).
//
// The measurements are whatever a MeasurementSet computes on the body (for ANSUR:
// core/ansur_measure.h), so the fit needs no derivatives of them: the Jacobian is by forward
// differences, cheap here because the body is linear in every modifier (a step adds one target's
// sparse offsets) and only the macro sliders rebuild it.
//
// Measurements that were not given are not left to MakeHuman's defaults: a MeasurementPrior (the
// mean and covariance of the survey's measurements for the person's sex, learned from the shared
// rows) completes them with their expected value given the ones that were (the Gaussian
// conditional — a linear regression on the given measurements), and the fit matches them as
// loosely as their conditional spread. docs/population.md states the figures this reaches.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "core/makehuman.h"
#include "core/measure.h"
#include "population/ansur.h"

namespace bodymodel {

// A named set of measurements of a 13 380-vertex body (mm): `measure` returns one value per name,
// in each measurement's survey unit (NaN where it cannot be taken). Must be thread-safe.
struct MeasurementSet {
  std::vector<std::string> names;
  std::function<Eigen::VectorXd(const Eigen::MatrixX3d& body_vertices)> measure;
  int index(const std::string& name) const;  // −1 when unknown
};

// The Gaussian of a population's measurements (one sex): mean and covariance of the named columns.
struct MeasurementPrior {
  std::vector<std::string> names;
  Eigen::VectorXd mean;
  Eigen::MatrixXd covariance;
  int rows = 0;  // people it was learned from
  // Expected value and standard deviation of every measurement given the named ones (the given
  // ones come back as they are, with standard deviation 0). Unknown names are InputError.
  void condition(const std::vector<std::string>& given_names, const Eigen::VectorXd& given_values,
                 Eigen::VectorXd& expected, Eigen::VectorXd& sd) const;
};

// Learns the prior from the rows of `table` of one sex (`male` 1 or 0), optionally only the rows
// listed in `rows` (e.g. a cross-validation fold). InputError when a column is missing or fewer
// rows than columns + 2 remain.
MeasurementPrior learn_measurement_prior(const AnsurTable& table, int male, const std::vector<std::string>& names,
                                         const std::vector<int>& rows = {});

struct ProportionTarget {
  std::string name;    // a MeasurementSet name
  double value = 0;    // in its unit
};

struct ProportionFitOptions {
  // Data-term scale of a given measurement, per unit (mm or kg): the given ones are matched to
  // well within the survey's own measurer error (ANSUR II's allowable error is 2–10 mm).
  double sigma_mm = 0.5, sigma_kg = 0.1;
  // Completed (not given) measurements are matched with their conditional standard deviation
  // times this.
  // Small, so the body carries the conditional expectation (the regression) wherever the
  // modifiers reach it; looser factors let MakeHuman's own proportions win (docs/population.md
  // compares them).
  double completion_sd_factor = 0.1;
  // Prior scales of the parameters (how far from MakeHuman's average each may move freely).
  double prior_slider = 0.5, prior_modifier = 0.6;
  double weight_max = 1.25;       // upper bound of the weight slider (fit_measurements.h: reach)
  double modifier_limit = 1.5;    // |modifier| bound (MakeHuman's own range is 1)
  int max_iterations = 30;
  int refresh_every = 5;          // LM steps between forward-difference Jacobians (Broyden between)
  double relative_tolerance = 1e-3;
  // Macro and modifier groups held at MakeHuman's average: hands, fingers and feet (no survey
  // measurement here sees them), the pregnant belly and the genital bulge.
  bool include_hands_and_feet = false;
  // The fold repair after the fit moves no vertex further than this (mm).
  double fold_repair_max_mm = 30;
  int fold_repair_passes = 6;
  // Umbrella-smoothing steps on the folds the passes leave (core/fold_repair.h smoothing_steps).
  int fold_smoothing_steps = 10;
  // Fits again with the modifiers' prior scales halved (quartered, ...) while the repaired body
  // still has a flipped triangle or more self-intersections than the template; the body with
  // the fewest is kept.
  int fold_retries = 3;
  // A body that still intersects itself more than MakeHuman's own has its trunk and limbs pushed
  // apart where they cross (core/intersection_repair.h; the hands, feet and head, where
  // MakeHuman's body has its own, are left alone), kept only if it has fewer intersections and no
  // more flipped triangles; then measured again. false: only the refits.
  bool intersection_repair = true;
};

struct ProportionFit {
  MacroSettings sliders;
  Eigen::VectorXd measure_modifiers;   // one per MakeHuman::measure_modifier_names()
  Eigen::VectorXd shape_modifiers;     // one per MakeHuman::shape_modifiers()
  Eigen::MatrixX3d V;                  // the body, 13 380 by 3, mm
  std::vector<std::string> names;      // the MeasurementSet's names
  Eigen::VectorXd target;              // per name: given value, completed value, or NaN
  Eigen::VectorXd target_sd;           // 0 for given, conditional sd for completed, NaN for neither
  std::vector<char> given;             // per name
  Eigen::VectorXd measured;            // per name, on V
  int iterations = 0, evaluations = 0;
  int retries = 0;                     // fits again with stiffer modifiers (fold_retries)
  // Faces whose normal turned against MakeHuman's body of the same macro sliders (the modifiers'
  // folds), before and after the fold repair.
  int flipped_before_repair = 0;
  int flipped_triangles = 0;
  int self_intersections = 0;          // intersecting triangle pairs (core/plausibility.h)
  int intersections_repaired = 0;      // pairs removed by the intersection repair (0: not run)
  // ... of MakeHuman's own body: the larger of the default body's and that of the same macro
  // sliders (computed only when self_intersections exceeds the default body's).
  int reference_self_intersections = 0;
  double seconds = 0;
};

// Fits bodies to measurements; build once, fit many people (fit() is const and thread-safe).
class ProportionFitter {
 public:
  ProportionFitter(const MakeHuman& makehuman, MeasurementSet set, const ProportionFitOptions& options = {});
  // `prior` (same sex as `sex`, or empty names = no completion). Throws InputError for an unknown
  // target name, a name given twice, a non-finite value, or an age outside 18–90.
  ProportionFit fit(Sex sex, double age_years, const std::vector<ProportionTarget>& targets,
                    const MeasurementPrior& prior) const;
  const std::vector<std::string>& parameter_names(Sex sex) const;
  // Intersecting triangle pairs of MakeHuman's default body (the template's own: fingers, toes).
  int template_self_intersections() const;

  struct Impl;

 private:
  std::shared_ptr<const Impl> impl_;
};

}  // namespace bodymodel
