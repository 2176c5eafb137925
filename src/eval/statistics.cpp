#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include <dcl/core/error.hpp>
#include <dcl/eval/statistics.hpp>

namespace dcl::eval {

namespace {

double meanOf(std::span<const double> values) {
  return std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(values.size());
}

double meanSquareOf(std::span<const double> values, double about) {
  double sum = 0.0;
  for (const double v : values) sum += (v - about) * (v - about);
  return sum / static_cast<double>(values.size());
}

// np.median: the middle of the sorted values, or the mean of the two middle ones.
double medianOf(std::span<const double> values) {
  std::vector<double> sorted(values.begin(), values.end());
  const std::size_t half = sorted.size() / 2;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(half),
                   sorted.end());
  const double upper = sorted[half];
  if (sorted.size() % 2 == 1) return upper;
  const double lower =
      *std::max_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(half));
  return 0.5 * (lower + upper);
}

}  // namespace

Statistics computeStatistics(std::span<const double> errors) {
  if (errors.empty()) throw core::Error("statistics: no errors to summarise (empty set)");
  Statistics s;
  s.count = errors.size();
  s.mean = meanOf(errors);
  s.rmse = std::sqrt(meanSquareOf(errors, 0.0));
  s.std = std::sqrt(meanSquareOf(errors, s.mean));
  s.median = medianOf(errors);
  const auto [lo, hi] = std::minmax_element(errors.begin(), errors.end());
  s.min = *lo;
  s.max = *hi;
  return s;
}

}  // namespace dcl::eval
