#pragma once

/// Summary statistics of a set of errors, defined as numpy (and so evo) defines them.

#include <cstddef>
#include <span>

namespace dcl::eval {

/// The statistics evo reports for an error array: rmse, mean, median, std, min, max.
struct Statistics {
  double rmse = 0.0;      ///< sqrt(mean(e^2))
  double mean = 0.0;      ///< arithmetic mean
  double median = 0.0;    ///< middle value; mean of the two middle values for an even count
  double std = 0.0;       ///< population standard deviation (numpy's ddof = 0)
  double min = 0.0;       ///< smallest error
  double max = 0.0;       ///< largest error
  std::size_t count = 0;  ///< number of errors
};

/// The statistics of `errors`, as numpy computes them (np.sqrt(np.mean(e**2)), np.mean,
/// np.median, np.std, np.min, np.max). Throws core::Error for an empty set.
Statistics computeStatistics(std::span<const double> errors);

}  // namespace dcl::eval
