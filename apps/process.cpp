#include "process.hpp"

#include <chrono>

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

}  // namespace dcl::apps
