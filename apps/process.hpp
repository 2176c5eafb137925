#pragma once

// What the commands that run as long-lived processes share (`robot`, `swarm`,
// `ping`): stopping cleanly on SIGINT/SIGTERM, and the wall clock that
// processes of one swarm agree on.

#include <csignal>

namespace dcl::apps {

/// While one lives, SIGINT and SIGTERM do not kill the process: the first
/// one received is kept (stopSignal()) so the command can stop, write what it
/// has and exit; the previous handlers come back after.
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  using Handler = void (*)(int);
  Handler previous_int_;
  Handler previous_term_;
};

/// The first SIGINT or SIGTERM received while a StopSignals lives; 0: none.
int stopSignal();

/// How many SIGINTs and SIGTERMs arrived while a StopSignals lives (a second
/// one: stop at once, without finishing what the first let finish).
int stopSignalCount();

/// s since the Unix epoch, from the system clock (shared by processes on one host).
double unixNow();

/// Checks a swarm clock's --epoch (Unix time of swarm time 0; 0: now) and
/// --rate (swarm seconds per wall second, at most 1000): a clock more than a
/// day from its data's start would play a day of scans at once, or wait a
/// day for the first, both a mistyped epoch or rate. Throws core::Error
/// naming the option.
void checkSwarmClock(double epoch, double rate);

}  // namespace dcl::apps
