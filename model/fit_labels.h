// The labels reported with a model fit (`bodymodel fit`, Model.fit in Python): each label of the
// fitted sub-model predicted by its regression from the coefficients, and measured on the input
// and on the fitted body where a mesh can tell (core/measure.h; measurements assume a closed
// mesh in a standing pose, so a mesh that cannot be measured just has no measured values).
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "core/measure.h"
#include "model/body_model.h"

namespace bodymodel {

struct FitLabel {
  std::string name, unit;
  std::optional<double> predicted;  // the regression's value (labels of the model only)
  std::optional<double> measured_input, measured_fitted;
};

// The sub-model's labels in its order, then the measurable body labels (height_cm, weight_kg,
// volume_l, chest_cm, waist_cm, hips_cm, neck_cm) the model has no label for, when measured.
// `coefficients` may be shorter than the sub-model's (the unfitted components count as 0); a
// non-finite prediction is reported as 0 (as the JSON output, which has no NaN).
std::vector<FitLabel> fit_labels(const BodyModel& model, const SubModel& sub, const Eigen::VectorXd& coefficients,
                                 const Eigen::MatrixX3d& input, const Eigen::MatrixX3d& fitted,
                                 const Eigen::MatrixX3i& F, Sex sex);

}  // namespace bodymodel
