// A body's measurements named and scaled as a survey's own columns, so that a body measured by
// `bodymodel measure --standard` can be set beside the survey's rows (docs/population.md).
#pragma once

#include <string>
#include <vector>

#include "core/ansur_measure.h"
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

// ANSUR II: AnsurMeasurer::names() (stature, weightkg, chestcircumference, ...), in mm, weightkg in
// kg (the survey's CSV stores tenths of a kg). InputError naming `what` when V does not have the
// template's 13 380 vertices.
std::vector<SurveyValue> ansur2_columns(const AnsurMeasurer& measurer, const Eigen::MatrixX3d& V,
                                        const Skeleton& skeleton, const std::string& what);

}  // namespace bodymodel
