#pragma once

/// CLI11 checks for numeric options, for what CLI11's own let through:
/// CLI::NonNegativeNumber compares, so NaN passes it, and an unsigned option
/// takes "-1" as 2^64 - 1. A refused value fails the parse, naming the option.

#include <cmath>
#include <string>

#include <CLI/CLI.hpp>

namespace dcl::apps {

namespace detail {

/// Why `input` is not a finite number (>= 0 when `non_negative`), or "".
inline std::string numberProblem(const std::string& input, bool non_negative) {
  double value = 0.0;
  if (!CLI::detail::lexical_cast(input, value) || !std::isfinite(value)) {
    return "'" + input + "' is not a finite number";
  }
  if (non_negative && (value < 0.0 || input.starts_with('-'))) {
    return "'" + input + "' is negative (expected a number >= 0)";
  }
  return {};
}

}  // namespace detail

/// A finite number: NaN and infinities refused.
inline const CLI::Validator kFinite(
    [](std::string& input) { return detail::numberProblem(input, false); }, "FINITE");

/// A finite number >= 0 (a count, a tolerance, an index): negatives, NaN and
/// infinities refused.
inline const CLI::Validator kNonNegative(
    [](std::string& input) { return detail::numberProblem(input, true); }, "NUMBER >= 0");

}  // namespace dcl::apps
