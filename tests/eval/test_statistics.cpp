#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/eval/statistics.hpp>

namespace dcl::eval {
namespace {

TEST(Statistics, EvenCountMatchesHandComputedNumpy) {
  const std::vector<double> e{4.0, 1.0, 3.0, 2.0};
  const Statistics s = computeStatistics(e);
  EXPECT_EQ(s.count, 4u);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);           // mean of the two middle values
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(1.25));  // population std: sum (e - 2.5)^2 / 4
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(7.5));  // (16 + 1 + 9 + 4) / 4
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 4.0);
}

TEST(Statistics, OddCountTakesTheMiddleValue) {
  const std::vector<double> e{0.3, 0.1, 0.2, 10.0, 0.0};
  const Statistics s = computeStatistics(e);
  EXPECT_DOUBLE_EQ(s.median, 0.2);
  EXPECT_DOUBLE_EQ(s.mean, 10.6 / 5.0);
  EXPECT_DOUBLE_EQ(s.min, 0.0);
  EXPECT_DOUBLE_EQ(s.max, 10.0);
}

TEST(Statistics, EvenCountWithDuplicatesAtTheMiddle) {
  const std::vector<double> e{5.0, 1.0, 5.0, 1.0, 3.0, 9.0};  // sorted 1 1 3 5 5 9
  EXPECT_DOUBLE_EQ(computeStatistics(e).median, 4.0);
}

TEST(Statistics, SingleValueHasZeroStd) {
  const std::vector<double> e{-2.0};
  const Statistics s = computeStatistics(e);
  EXPECT_DOUBLE_EQ(s.rmse, 2.0);
  EXPECT_DOUBLE_EQ(s.mean, -2.0);
  EXPECT_DOUBLE_EQ(s.std, 0.0);
  EXPECT_DOUBLE_EQ(s.median, -2.0);
}

TEST(Statistics, EmptySetIsAnError) {
  EXPECT_THROW(computeStatistics({}), core::Error);
}

}  // namespace
}  // namespace dcl::eval
