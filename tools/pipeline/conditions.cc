#include "tools/pipeline/conditions.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>

#include "core/error.h"

namespace bodymodel {

namespace {

double number(const std::string& s, const std::string& what) {
  char* end = nullptr;
  double v = std::strtod(s.c_str(), &end);
  if (s.empty() || !end || *end != '\0' || !std::isfinite(v))
    throw InputError(fmt::format("{}: '{}' is not a number", what, s));
  return v;
}

}  // namespace

std::vector<LabelCondition> parse_conditions(const SemanticRegression& reg, const std::vector<std::string>& where) {
  std::vector<LabelCondition> out;
  for (const auto& s : where) {
    const auto eq = s.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == s.size())
      throw InputError(fmt::format("--where expects LABEL=VALUE or LABEL=LO..HI, got '{}'", s));
    const std::string label = s.substr(0, eq), text = s.substr(eq + 1);
    reg.index(label);  // InputError listing the valid labels
    const auto dots = text.find("..");
    if (dots != std::string::npos) {
      double lo = number(text.substr(0, dots), "--where " + label + " lower bound");
      double hi = number(text.substr(dots + 2), "--where " + label + " upper bound");
      if (!(lo < hi)) throw InputError(fmt::format("--where {}: empty range {}..{}", label, lo, hi));
      out.push_back(LabelCondition::range(label, lo, hi));
    } else if (label == "sex" && (text == "female" || text == "f")) {
      out.push_back(LabelCondition::exact(label, 0));
    } else if (label == "sex" && (text == "male" || text == "m")) {
      out.push_back(LabelCondition::exact(label, 1));
    } else {
      out.push_back(LabelCondition::exact(label, number(text, "--where " + label)));
    }
  }
  return out;
}

Sex sex_of(const std::vector<LabelCondition>& conditions) {
  for (auto& c : conditions)
    if (c.label == "sex") return c.lo < 0.5 ? Sex::female : Sex::male;
  return Sex::unknown;
}

}  // namespace bodymodel
