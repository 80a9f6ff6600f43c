// A body's measurements named and scaled as a survey's own columns, so that a body measured by
// `bodymodel measure --standard` can be set beside the survey's rows (docs/population.md).
#pragma once

#include <string>
#include <vector>

#include "core/measure.h"

namespace bodymodel {

struct SurveyValue {
  std::string column;  // the survey's column name, e.g. BMXWAIST
  double value = 0;    // in the survey's unit
  std::string unit;
  std::string definition;  // what is measured on the mesh
};

// NHANES P_BMX: BMXHT, BMXWT, BMXWAIST (iliac crest), BMXHIP, BMXARMC, BMXARML, BMXLEG. The
// survey definitions need the hm08 template's topology: InputError naming `what` when the
// measurements were taken without them (BodyMeasurements::survey false).
std::vector<SurveyValue> nhanes_columns(const BodyMeasurements& m, const std::string& what);

}  // namespace bodymodel
