// Helpers shared by the model verbs (build, morph, generate, pose, edit).
#pragma once

#include <fmt/format.h>

#include <cmath>
#include <string>
#include <utility>

#include "core/error.h"
#include "model/body_model.h"
#include "model/model_file.h"
#include "tools/console.h"

namespace bodymodel::model_cli {

// "name=value" → (name, value); InputError naming the option otherwise.
inline std::pair<std::string, std::string> split_assignment(const std::string& s, const std::string& option) {
  auto eq = s.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == s.size())
    throw InputError(fmt::format("{} expects LABEL=VALUE, got '{}'", option, s));
  return {s.substr(0, eq), s.substr(eq + 1)};
}

inline double parse_number(const std::string& s, const std::string& what) {
  char* end = nullptr;
  double v = std::strtod(s.c_str(), &end);
  if (s.empty() || !end || *end != '\0' || !std::isfinite(v))
    throw InputError(fmt::format("{}: '{}' is not a number", what, s));
  return v;
}

// Value of a label given on the command line ("sex" also accepts female/male).
inline double parse_label_value(const std::string& label, const std::string& s) {
  if (label == "sex") {
    if (s == "female" || s == "f") return 0;
    if (s == "male" || s == "m") return 1;
  }
  return parse_number(s, "value of '" + label + "'");
}

// Warns (and clamps when asked) when `value` is far outside the training data of `info`.
inline double check_label_range(const LabelInfo& info, double value, bool clamp) {
  const double range = info.max - info.min;
  const double lo = info.min - 0.25 * range, hi = info.max + 0.25 * range;
  if (value >= lo && value <= hi) return value;
  if (clamp) {
    double c = std::clamp(value, info.min, info.max);
    cli::warn(fmt::format("{} = {} is far outside the data ({:.4g} .. {:.4g} {}); clamped to {:.4g}",
                          info.name, value, info.min, info.max, info.unit, c));
    return c;
  }
  cli::warn(fmt::format("{} = {} is far outside the data ({:.4g} .. {:.4g} {}): the result is an "
                        "extrapolation (use --clamp to stay inside the data)",
                        info.name, value, info.min, info.max, info.unit));
  return value;
}

inline BodyModel load_model_for_cli(const std::string& path) {
  cli::info("loading model " + path);
  return load_model(path);
}

}  // namespace bodymodel::model_cli
