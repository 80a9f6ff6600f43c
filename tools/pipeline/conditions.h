// `--where LABEL=VALUE` / `LABEL=LO..HI` conditions of the generating verbs (character, crowd).
#pragma once

#include <string>
#include <vector>

#include "core/measure.h"
#include "model/morph.h"
#include "model/semantic.h"

namespace bodymodel {

// Parses each condition against the shape model's labels (InputError listing the valid ones
// for an unknown label; "sex" accepts female/male).
std::vector<LabelCondition> parse_conditions(const SemanticRegression& reg, const std::vector<std::string>& where);
// The sex a condition list asks for (unknown when none).
Sex sex_of(const std::vector<LabelCondition>& conditions);

}  // namespace bodymodel
