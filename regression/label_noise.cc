#include "regression/label_noise.h"

#include <cmath>
#include <map>
#include <random>
#include <sstream>

#include "core/error.h"

namespace bodymodel {

namespace {

double parse_sigma(const std::string& text, const std::string& entry) {
  size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || !std::isfinite(v) || v < 0)
    throw InputError("--label-noise: '" + entry + "' is not a non-negative number (expected e.g. "
                     "'0.2' or 'height_cm=1,weight_kg=0.5')");
  return v;
}

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t") - a + 1);
}

}  // namespace

LabelNoiseSpec parse_label_noise(const std::string& text) {
  LabelNoiseSpec spec;
  std::stringstream ss(text);
  std::string item;
  bool have_relative = false;
  while (std::getline(ss, item, ',')) {
    item = trim(item);
    if (item.empty()) continue;
    const auto eq = item.find('=');
    if (eq == std::string::npos) {
      if (have_relative) throw InputError("--label-noise: two bare numbers in '" + text + "'");
      spec.relative = parse_sigma(item, item);
      have_relative = true;
    } else {
      const std::string name = trim(item.substr(0, eq));
      if (name.empty()) throw InputError("--label-noise: '" + item + "' has no label name before '='");
      spec.absolute.emplace_back(name, parse_sigma(trim(item.substr(eq + 1)), item));
    }
  }
  return spec;
}

Eigen::VectorXd label_noise_sigma(const LabelNoiseSpec& spec, const Eigen::MatrixXd& Y,
                                  const std::vector<std::string>& names) {
  if (static_cast<Eigen::Index>(names.size()) != Y.cols())
    throw InputError("label noise: " + std::to_string(names.size()) + " names for " +
                     std::to_string(Y.cols()) + " label columns");
  Eigen::VectorXd sigma = Eigen::VectorXd::Zero(Y.cols());
  for (Eigen::Index l = 0; l < Y.cols(); ++l) {
    double sum = 0, sum2 = 0;
    int n = 0;
    for (Eigen::Index i = 0; i < Y.rows(); ++i)
      if (std::isfinite(Y(i, l))) sum += Y(i, l), sum2 += Y(i, l) * Y(i, l), ++n;
    if (n > 1) {
      const double mean = sum / n;
      sigma(l) = spec.relative * std::sqrt(std::max(0.0, (sum2 - n * mean * mean) / (n - 1)));
    }
  }
  for (const auto& [name, s] : spec.absolute) {
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end()) {
      std::string known;
      for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
      throw InputError("--label-noise: '" + name + "' is not one of the evaluated labels (" + known + ")");
    }
    sigma(it - names.begin()) = s;
  }
  return sigma;
}

Eigen::MatrixXd add_label_noise(const Eigen::MatrixXd& Y, const Eigen::VectorXd& sigma,
                                const std::vector<int>& groups, unsigned seed) {
  if (sigma.size() != Y.cols())
    throw InputError("label noise: " + std::to_string(sigma.size()) + " σ for " + std::to_string(Y.cols()) +
                     " label columns");
  if (!groups.empty() && static_cast<Eigen::Index>(groups.size()) != Y.rows())
    throw InputError("label noise: " + std::to_string(groups.size()) + " subject indices for " +
                     std::to_string(Y.rows()) + " rows");
  // One draw per (subject, label), in the order subjects first appear, so the noise of a subject
  // does not depend on how many rows it has.
  std::map<int, int> subject_index;
  std::vector<int> subject_of(Y.rows());
  for (Eigen::Index i = 0; i < Y.rows(); ++i) {
    const int g = groups.empty() ? static_cast<int>(i) : groups[i];
    subject_of[i] = subject_index.emplace(g, static_cast<int>(subject_index.size())).first->second;
  }
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0, 1);
  Eigen::MatrixXd draws(subject_index.size(), Y.cols());
  for (Eigen::Index s = 0; s < draws.rows(); ++s)
    for (Eigen::Index l = 0; l < draws.cols(); ++l) draws(s, l) = normal(rng);
  Eigen::MatrixXd out = Y;
  for (Eigen::Index i = 0; i < Y.rows(); ++i)
    for (Eigen::Index l = 0; l < Y.cols(); ++l)
      if (std::isfinite(Y(i, l))) out(i, l) += sigma(l) * draws(subject_of[i], l);
  return out;
}

}  // namespace bodymodel
