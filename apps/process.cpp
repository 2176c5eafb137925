#include "process.hpp"

#include <chrono>
#include <cmath>

#include <fmt/format.h>

#include <dcl/core/error.hpp>

namespace dcl::apps {
namespace {

volatile std::sig_atomic_t g_signal = 0;
volatile std::sig_atomic_t g_count = 0;

/// Keeps the first signal (the one that ended the run) and counts them all.
extern "C" void onStopSignal(int signal) {
  if (g_signal == 0) g_signal = signal;
  if (g_count < 1000) g_count = g_count + 1;
}

}  // namespace

StopSignals::StopSignals()
    : previous_int_(std::signal(SIGINT, onStopSignal)),
      previous_term_(std::signal(SIGTERM, onStopSignal)) {
  g_signal = 0;
  g_count = 0;
}

StopSignals::~StopSignals() {
  std::signal(SIGINT, previous_int_);
  std::signal(SIGTERM, previous_term_);
}

int stopSignal() {
  return static_cast<int>(g_signal);
}

int stopSignalCount() {
  return static_cast<int>(g_count);
}

double unixNow() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

void checkSwarmClock(double epoch, double rate) {
  constexpr double kMostRate = 1000.0;
  constexpr double kMostClockOffset = 86400.0;  // s, a day
  if (!(rate > 0.0) || !std::isfinite(rate))
    throw core::Error("--rate must be a finite number > 0");
  if (rate > kMostRate)
    throw core::Error(
        fmt::format("--rate {:g} is beyond {:g} swarm seconds per wall second", rate, kMostRate));
  if (!(epoch >= 0.0) || !std::isfinite(epoch))
    throw core::Error("--epoch must be a finite number of seconds since 1970 (0: now)");
  if (epoch > 0.0) {
    const double away = (unixNow() - epoch) * rate;
    if (std::abs(away) > kMostClockOffset)
      throw core::Error(fmt::format(
          "--epoch {:.0f} puts the swarm clock {:.0f} s {} its data's start (more than a day): "
          "give the Unix time at which the swarm starts, as `dcl-slam swarm` does, or 0 for now",
          epoch, std::abs(away), away > 0.0 ? "past" : "before"));
  }
}

}  // namespace dcl::apps
