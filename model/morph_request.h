// The morph options a user's request implies, set one way for `bodymodel morph` and Python's
// Model.morph, so both return the same body for the same call.
#pragma once

#include <string>
#include <vector>

#include "model/morph.h"

namespace bodymodel {

// The sex the measurements use is `sex`, else the conditions' sex label; the change is the
// likely one (the model's conditional mean) from the model's mean body and the smallest (the
// paper's eq. 11) from a given body, unless `change` ("likely" or "smallest") names one.
MorphOptions morph_request_options(const std::vector<LabelCondition>& conditions, Sex sex, const std::string& change,
                                   bool from_mean, int iterations);

}  // namespace bodymodel
