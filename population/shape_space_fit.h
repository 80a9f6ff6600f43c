// A shape space (core/shape_space.h) learned from real people: soldiers of ANSUR II fitted as
// bodies to their measurements (population/ansur_fit.h, every MakeHuman body modifier), then a
// PCA of the fitted parameters. It is the shape prior `register --shape-space` fits inside.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/shape_space.h"
#include "population/ansur.h"
#include "population/fit_proportions.h"

namespace bodymodel {

// The parameter vector of a fitted body in shape_space_parameter_names(makehuman)'s order.
Eigen::VectorXd shape_space_row(const MakeHuman& makehuman, const ProportionFit& fit);

struct ShapeSpaceFitOptions {
  int per_table = 150;                 // soldiers drawn at random from each table (0 = all)
  int components = 20;
  uint64_t seed = 1;
  int jobs = 0;                        // people fitted in parallel (0 = all cores)
  std::function<void(int done, int total)> progress;
};

struct ShapeSpaceFitRun {
  ShapeSpace space;
  int flipped_people = 0;              // fitted bodies that kept a flipped triangle (still used)
  double seconds = 0;
};

// Fits options.per_table soldiers of every table to ANSUR's default columns (the prior and
// completion learned from that table's other rows) and learns the space from all of them; the
// space's source names the tables' files. InputError for an empty table list or a table that
// lacks a default column.
ShapeSpaceFitRun ansur_shape_space(const MakeHuman& makehuman, const std::vector<AnsurTable>& tables,
                                   const ShapeSpaceFitOptions& options = {});

}  // namespace bodymodel
