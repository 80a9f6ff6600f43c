#include "model/morph_request.h"

#include "core/error.h"

namespace bodymodel {

MorphOptions morph_request_options(const std::vector<LabelCondition>& conditions, Sex sex, const std::string& change,
                                   bool from_mean, int iterations) {
  if (!change.empty() && change != "likely" && change != "smallest")
    throw InputError("change: expected 'likely' or 'smallest', got '" + change + "'");
  MorphOptions o;
  o.max_iterations = iterations;
  o.sex = sex;
  for (const auto& c : conditions)
    if (c.label == "sex" && o.sex == Sex::unknown && !c.keep) o.sex = c.lo < 0.5 ? Sex::female : Sex::male;
  o.prior_weighted = change.empty() ? from_mean : change == "likely";
  return o;
}

}  // namespace bodymodel
