#pragma once

/// The text of a swarm run's progress display (core::ProgressBoard draws it):
/// a summary line, then one compact line per robot (scans played, keyframes,
/// inter-robot loops kept, bytes sent), so that a user sees a robot that
/// lags or finds no loop while the run goes on.

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include <dcl/swarm/swarm_run.hpp>

namespace dcl::swarm {

/// Robot lines a display shows at most: with more robots, the slowest
/// (least of their scans played) and one line for the rest, so that a
/// 27-robot run still fits a terminal.
inline constexpr std::size_t kProgressRobotLines = 8;

/// The lines for `status`: "label [bar] t done/end s, frames, eta" first, then
/// the robots, in member order; with more than `max_robot_lines` robots, the
/// `max_robot_lines - 1` slowest and a line summing up the others. The time
/// left comes from the simulated time done in `elapsed_s` seconds.
std::vector<std::string> progressLines(std::string_view label, const SwarmStatus& status,
                                       double elapsed_s,
                                       std::size_t max_robot_lines = kProgressRobotLines);

/// "950 B", "12.3 kB", "1.21 MB", "3.40 GB" (powers of 1000).
std::string formatBytes(std::size_t bytes);

}  // namespace dcl::swarm
