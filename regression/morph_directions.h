// Morph directions (Hasler et al. 2009 §5.1, Table 2): the gradient of a label regressor at each
// subject, and how far those directions spread — the angle between each subject's direction and
// the mean direction. Small angles mean a single linear direction morphs every subject well.
#pragma once

#include <Eigen/Core>

#include "regression/regressor.h"

namespace bodymodel {

struct MorphDirectionSpread {
  double mean_deg = 0, std_deg = 0, max_deg = 0;  // over subjects, degrees
  int subjects = 0;         // directions used
  int zero_gradients = 0;   // subjects where the gradient vanished (no direction; skipped)
  Eigen::VectorXd angles_deg;    // #subjects used: the angle of each direction to the mean
  Eigen::VectorXd mean_direction;  // #features, unit length: mean of the normalised gradients
};

// Gradients of a fitted regressor at the rows of X (#subjects by #features) → #subjects by
// #features (label unit per feature unit).
Eigen::MatrixXd morph_directions(const Regressor& fitted, const Eigen::MatrixXd& X);

// Angles between the rows of G (#subjects by #features, one direction per subject) and their mean
// direction (mean of the normalised rows). Standard deviation is the population one (÷ n).
// Throws InputError when every row is zero.
MorphDirectionSpread morph_direction_spread(const Eigen::MatrixXd& G);

}  // namespace bodymodel
