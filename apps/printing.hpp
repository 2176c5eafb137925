#pragma once

// Small helpers the commands share for timing and printing what they did.

#include <chrono>
#include <cstddef>
#include <set>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/ids.hpp>

namespace dcl::apps {

/// s on the steady clock since `start`.
inline double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// A length of metrics.json (m) with three decimals, "-" when it is null.
inline std::string metresText(const nlohmann::ordered_json& value) {
  return value.is_null() ? "-" : fmt::format("{:.3f}", value.get<double>());
}

/// How many robots own poses of `graph`.
inline std::size_t robotCount(const backend::PoseGraph& graph) {
  std::set<core::RobotId> robots;
  for (const auto& [key, pose] : graph.nodes()) robots.insert(key.robot);
  return robots.size();
}

}  // namespace dcl::apps
