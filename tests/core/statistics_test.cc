#include <gtest/gtest.h>

#include <cmath>

#include "core/statistics.h"

namespace bodymodel {
namespace {

TEST(Statistics, PercentileInterpolatesLinearlyAsNumpy) {
  // numpy.percentile([1, 2, 3, 4], q): 50 → 2.5, 95 → 3.85, 0 → 1, 100 → 4.
  EXPECT_DOUBLE_EQ(percentile({4, 1, 3, 2}, 50), 2.5);
  EXPECT_DOUBLE_EQ(percentile({1, 2, 3, 4}, 95), 3.85);
  EXPECT_DOUBLE_EQ(percentile({1, 2, 3, 4}, 0), 1.0);
  EXPECT_DOUBLE_EQ(percentile({1, 2, 3, 4}, 100), 4.0);
  EXPECT_DOUBLE_EQ(percentile({1, 2, 3, 4, 10, 10, 10, 10}, 95), 10.0);
  EXPECT_DOUBLE_EQ(median({7}), 7.0);
  EXPECT_DOUBLE_EQ(median({3, 1, 2}), 2.0);
  EXPECT_DOUBLE_EQ(percentile_sorted({1, 2, 3, 4}, 25), 1.75);
}

TEST(Statistics, NoValuesHaveNoPercentile) {
  EXPECT_TRUE(std::isnan(percentile({}, 50)));
  EXPECT_TRUE(std::isnan(median({})));
}

}  // namespace
}  // namespace bodymodel
