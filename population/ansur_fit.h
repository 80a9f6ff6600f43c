// Soldiers of ANSUR II as bodies: each row fitted (population/fit_proportions.h) to the columns
// it is given, and the accuracy of the bodies measured against the survey's own values — for the
// given columns (does the body measure what it was asked to?) and for the others (does it have the
// proportions of the real person?), beside the linear regression from the same given columns.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "population/ansur.h"
#include "population/fit_proportions.h"

namespace bodymodel {

struct AnsurFitOptions {
  std::vector<std::string> given;      // columns fitted (ANSUR names, e.g. stature, weightkg)
  std::vector<int> rows;               // rows of the table to fit (empty = all)
  // Rows the population prior and the regression baseline are learned from (empty = every row of
  // the prior table that is not fitted, so no person predicts itself).
  std::vector<int> prior_rows;
  int jobs = 0;                        // people fitted in parallel (0 = all cores)
  std::function<void(int done, int total)> progress;
};

struct AnsurFitRow {
  std::string id;
  int row = 0;
  ProportionFit fit;                   // fit.V is released unless AnsurFitRun keeps bodies
};

// Per measurement of the set that the table has.
struct AnsurMeasurementSummary {
  std::string name;
  bool given = false;
  double tolerance = 0;                // 5 mm lengths, 10 mm girths, 1 kg weight
  double within = 0;                   // fraction of people whose body is within `tolerance`
  double rmse_body = 0;                // body's value vs the survey's
  double rmse_regression = 0;          // not given: linear regression from the given columns
  double mean_error = 0;               // body − survey, mean (a bias)
};

struct AnsurFitRun {
  std::vector<AnsurFitRow> people;
  std::vector<AnsurMeasurementSummary> summary;
  double seconds = 0;
  int flipped_people = 0;              // people whose body has a flipped triangle
  int self_intersecting_people = 0;    // ... more intersecting triangle pairs than MakeHuman's own
                                       // body (ProportionFit::reference_self_intersections)
  int pushed_apart_people = 0;         // people whose crossing parts were pushed apart
  int template_self_intersections = 0;
};

// ANSUR II's measurements as core/ansur_measure.h takes them on a body of MakeHuman's topology
// (its skeleton regressed from the body vertices), as a MeasurementSet to fit bodies to.
MeasurementSet ansur_measurement_set(const MakeHuman& makehuman);

// The 18 columns of the accuracy bar (docs/population.md): stature, weightkg, chest, waist,
// buttock, thigh, calf, flexed-biceps, neck-base and shoulder circumference, biacromial and hip
// breadth, chest depth, acromial, crotch, iliocristale and mid-patella knee height, sleeve outseam.
const std::vector<std::string>& default_ansur_columns();

// The tolerance of an ANSUR column for the accuracy bar: girths ("circumference") 10 mm, weight
// 1 kg, every other length 5 mm.
double ansur_tolerance(const std::string& name);

// Fits `rows` of `table` (one sex) to `given`, learning the prior from `prior_table`'s rows of
// that sex (prior_rows or the rest). `keep_bodies` keeps each fit's vertices (for writing).
// InputError for a given column the set or the table lacks.
AnsurFitRun fit_ansur_rows(const ProportionFitter& fitter, const MeasurementSet& set, const AnsurTable& table,
                           const AnsurTable& prior_table, const AnsurFitOptions& options, bool keep_bodies);

}  // namespace bodymodel
