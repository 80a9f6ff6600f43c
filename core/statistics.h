// Order statistics every stage reports the same way (docs/evaluation.md).
#pragma once

#include <vector>

namespace bodymodel {

// The p-th percentile (p in [0, 100]) with linear interpolation between closest ranks, numpy's
// default; NaN for no values.
double percentile(std::vector<double> values, double p);

// As percentile, on values already sorted ascending (no copy).
double percentile_sorted(const std::vector<double>& sorted, double p);

// percentile(values, 50).
double median(std::vector<double> values);

}  // namespace bodymodel
