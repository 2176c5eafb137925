#pragma once

/// The net motion of an iterative solver's last few steps. Near the optimum
/// of an ICP-like problem, correspondences flip between neighbouring target
/// points (or voxels, or planes), so Gauss-Newton often ends in a short limit
/// cycle of millimetre steps that undo each other rather than in a vanishing
/// step. A small net motion over a window of steps ends the iteration as well
/// as a small step does.

#include <array>
#include <cstddef>
#include <limits>

#include <dcl/core/se3.hpp>

namespace dcl::core {

/// The sum of the last `Size` steps; `Size` a power of two covers limit
/// cycles of every period that divides it.
template <std::size_t Size>
class StepWindow {
 public:
  /// Records `step`; the norm of the sum of the last Size steps (infinite
  /// until Size steps were seen).
  double add(const Vector6d& step) {
    sum_ += step - steps_[next_];
    steps_[next_] = step;
    next_ = (next_ + 1) % Size;
    ++count_;
    return count_ >= Size ? sum_.norm() : std::numeric_limits<double>::infinity();
  }

 private:
  std::array<Vector6d, Size> steps_ = zeros();
  Vector6d sum_ = Vector6d::Zero();
  std::size_t next_ = 0;
  std::size_t count_ = 0;

  static std::array<Vector6d, Size> zeros() {
    std::array<Vector6d, Size> a;
    a.fill(Vector6d::Zero());
    return a;
  }
};

}  // namespace dcl::core
