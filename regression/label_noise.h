// Simulated measurement noise on labels. The synthetic database's labels are exact measurements
// of noise-free meshes, while Hasler et al. 2009 (§2.1) label their subjects with instruments:
// a scale, an impedance-spectroscopy body-fat scale (body fat and muscle percentages) and tape /
// scan measurements. Over-fitting of the unfiltered eq. 10 (§4: "severely overtrained") shows only
// when labels carry such noise; this adds it, seeded, so the Table 1 comparison can be run in
// the paper's regime and repeated exactly.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace bodymodel {

// How much noise each label gets, parsed from text such as "0.2" (every label: 0.2 × its standard
// deviation over the rows) or "height_cm=1,weight_kg=0.5" (σ in the label's unit; unnamed labels
// get none). Mixed: "0.1,weight_kg=0.5" (the bare number applies to the labels not named).
struct LabelNoiseSpec {
  double relative = 0;                                      // × the label's standard deviation
  std::vector<std::pair<std::string, double>> absolute;     // label name → σ, label unit
  bool empty() const { return relative == 0 && absolute.empty(); }
};
// Throws InputError naming the bad entry (negative, not a number, unknown shape).
LabelNoiseSpec parse_label_noise(const std::string& text);

// σ per label (label units) for the labels `names` of Y (#rows by #labels, NaN = missing); the
// relative part uses the standard deviation of each column's finite values. Throws InputError
// when the spec names a label that is not in `names`.
Eigen::VectorXd label_noise_sigma(const LabelNoiseSpec& spec, const Eigen::MatrixXd& Y,
                                  const std::vector<std::string>& names);

// Y + Gaussian noise: sigma #labels (label units), groups #rows subject index (or empty = one
// subject per row). A subject's rows share one draw per label (the label is the subject's, e.g.
// all scans of one person in the full model). NaN stay NaN. Deterministic for a seed.
Eigen::MatrixXd add_label_noise(const Eigen::MatrixXd& Y, const Eigen::VectorXd& sigma,
                                const std::vector<int>& groups, unsigned seed);

}  // namespace bodymodel
