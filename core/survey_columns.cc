#include "core/survey_columns.h"

#include "core/error.h"

namespace bodymodel {

std::vector<SurveyValue> nhanes_columns(const BodyMeasurements& m, const std::string& what) {
  if (!m.survey)
    throw InputError(what + ": the NHANES measurements need a body with the hm08 template's topology (" +
                     std::to_string(kSurveyTemplateVertexCount) +
                     " vertices: a MakeHuman body, a registration or a model's output)");
  return {
      {"BMXHT", m.height_cm, "cm", "standing height: extent along +y"},
      {"BMXWT", m.weight_kg, "kg", "weight: enclosed volume x density"},
      {"BMXWAIST", m.waist_iliac_cm, "cm", "waist girth at the right iliac crest"},
      {"BMXHIP", m.hips_cm, "cm", "hip girth at the maximum posterior extension of the buttocks"},
      {"BMXARMC", m.arm_circumference_cm, "cm", "right upper-arm girth, mid acromion-olecranon"},
      {"BMXARML", m.upper_arm_length_cm, "cm", "acromion to olecranon, straight (standing A-pose)"},
      {"BMXLEG", m.upper_leg_length_cm, "cm", "inguinal crease to patella, straight (standing A-pose)"},
  };
}

std::vector<SurveyValue> ansur2_columns(const AnsurMeasurer& measurer, const Eigen::MatrixX3d& V,
                                        const Skeleton& skeleton, const std::string& what) {
  if (V.rows() != kSurveyTemplateVertexCount)
    throw InputError(what + ": the ANSUR II measurements need a body with the hm08 template's topology (" +
                     std::to_string(kSurveyTemplateVertexCount) + " vertices, got " + std::to_string(V.rows()) +
                     "): a MakeHuman body, a registration or a model's output");
  Eigen::VectorXd values;
  try {
    values = measurer.measure(V, skeleton);
  } catch (const InputError& e) {
    throw InputError(what + ": " + e.what());
  }
  std::vector<SurveyValue> out;
  for (size_t k = 0; k < AnsurMeasurer::names().size(); ++k)
    out.push_back({AnsurMeasurer::names()[k], values(static_cast<Eigen::Index>(k)), AnsurMeasurer::units()[k],
                   AnsurMeasurer::definitions()[k]});
  return out;
}

}  // namespace bodymodel
