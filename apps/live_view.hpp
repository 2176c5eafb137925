#pragma once

// `--viz PORT` of `run` and `demo`: the swarm as it runs, served to
// Foxglove (or Lichtblick) over the Foxglove WebSocket protocol. Per robot
// its path (foxglove.PosesInFrame, keyframes at their current estimates in
// the robot's frame), its newest keyframe's scan there (foxglove.PointCloud),
// its accepted inter-robot loops (foxglove.SceneUpdate, lines), its
// counters, a few times a wall second, and its whole map (foxglove.PointCloud,
// every keyframe's cloud where the robot now thinks it was, thinned to one
// point per 0.4 m voxel) every 3 wall seconds.

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <dcl/swarm/swarm_run.hpp>
#include <dcl/viz/foxglove.hpp>

namespace dcl::apps {

class LiveView {
 public:
  /// Serves on `port` of 127.0.0.1 the channels of `robots` (their names);
  /// waits up to `wait` s for a first client. Throws core::Error when the
  /// port cannot be had.
  LiveView(std::uint16_t port, const std::vector<std::string>& robots, double wait);

  /// Whether update() would publish now (kPeriod of wall time since the last):
  /// callers that must build a status first ask before.
  [[nodiscard]] bool due() const;

  /// Publishes where the run stands, at most every kPeriod of wall time
  /// unless `now` (the run's end).
  void update(const swarm::SwarmStatus& status, bool now = false);

  [[nodiscard]] std::uint16_t port() const { return server_.port(); }

  /// The channels of robots named `robots`: per robot its path, scan, loops,
  /// counters and map (channel(r, 0..4)).
  static std::vector<viz::Channel> channels(const std::vector<std::string>& robots);
  static std::size_t channel(std::size_t robot, std::size_t kind);

 private:
  std::size_t robots_;
  viz::Server server_;
  std::chrono::steady_clock::time_point last_{};
  std::chrono::steady_clock::time_point last_loops_{};
  std::chrono::steady_clock::time_point last_map_{};
  std::vector<std::size_t> scans_published_;  ///< per robot, keyframes when its scan went out
};

}  // namespace dcl::apps
