// The subjects `bodymodel synth-db` draws when no population is given, shared by the tool, the
// regression study and the tests so all sample the same people.
#pragma once

#include <random>

#include "core/makehuman.h"

namespace bodymodel {

// A random adult of one sex: macro sliders uniform over their middle range (age about 23 to 70
// years, others within [0.15, 0.85]), ethnic weights from normalised Gamma(2) draws.
MacroSettings random_makehuman_subject(std::mt19937_64& rng, bool male);

}  // namespace bodymodel
