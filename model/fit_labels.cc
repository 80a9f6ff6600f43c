#include "model/fit_labels.h"

#include <cmath>

#include "core/error.h"
#include "model/morph.h"

namespace bodymodel {

std::vector<FitLabel> fit_labels(const BodyModel& model, const SubModel& sub, const Eigen::VectorXd& coefficients,
                                 const Eigen::MatrixX3d& input, const Eigen::MatrixX3d& fitted,
                                 const Eigen::MatrixX3i& F, Sex sex) {
  Eigen::VectorXd c = Eigen::VectorXd::Zero(sub.component_count());
  c.head(coefficients.size()) = coefficients;
  const Eigen::VectorXd predicted = sub.regression.predict(c);
  MeasureOptions mo;
  const std::string up = model.metadata.contains("source") ? model.metadata["source"].value("up_axis", "y") : "y";
  mo.up_axis = up == "x" ? 0 : up == "z" ? 2 : 1;
  auto measure = [&](const Eigen::MatrixX3d& V) -> std::optional<BodyMeasurements> {
    try {
      return measure_body(V, F, sex, mo);
    } catch (const InputError&) {
      return std::nullopt;  // not measurable (open, not standing): no measured values
    }
  };
  const auto m_in = measure(input), m_fit = measure(fitted);
  auto measured = [](const std::string& name, const std::optional<BodyMeasurements>& m) -> std::optional<double> {
    return m ? measured_label(name, *m) : std::nullopt;
  };
  std::vector<FitLabel> out;
  for (int i = 0; i < sub.regression.label_count(); ++i) {
    const LabelInfo& L = sub.regression.labels[i];
    out.push_back({L.name, L.unit, std::isfinite(predicted(i)) ? predicted(i) : 0.0, measured(L.name, m_in),
                   measured(L.name, m_fit)});
  }
  for (const std::string name : {"height_cm", "weight_kg", "volume_l", "chest_cm", "waist_cm", "hips_cm", "neck_cm"}) {
    bool have = false;
    for (const auto& l : out) have = have || l.name == name;
    if (have) continue;
    FitLabel l{name, name == "volume_l" ? "L" : name == "weight_kg" ? "kg" : "cm", std::nullopt,
               measured(name, m_in), measured(name, m_fit)};
    if (l.measured_input || l.measured_fitted) out.push_back(l);
  }
  return out;
}

}  // namespace bodymodel
