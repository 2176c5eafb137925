// The simulated radio, one core: a swarm driving KITTI 00's real roads for
// one simulated minute at 10 Hz (heartbeats, descriptor broadcasts, unicast
// candidates of random size, a bandwidth cap, latency and losses). The radio
// must cost far less than the robots it connects: a minute of an 8-robot
// swarm should take a few milliseconds.
#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include <dcl/comm/sim_radio.hpp>
#include <dcl/core/trajectory.hpp>
#include <dcl/io/pose_file.hpp>

namespace {

using dcl::comm::MessageKind;
using dcl::core::RobotId;

const dcl::core::Trajectory& kitti00() {
  static const dcl::core::Trajectory route =
      dcl::io::readKittiPoses(std::string(DCL_DATA_DIR) + "/trajectories/evo/KITTI_00_gt.txt");
  return route;
}

/// Robot r starts at frame 500 r; even robots drive forward, odd ones back,
/// so pairs meet and part along the way.
Eigen::Vector3d position(int robot, int step) {
  const int frame = 500 * robot + (robot % 2 == 0 ? step : -step) + 600;
  return kitti00().pose(static_cast<std::size_t>(frame)).translation();
}

/// One simulated minute; returns the log's length (transmissions per link).
std::size_t swarmMinute(int robots) {
  dcl::comm::SimRadioConfig config;
  config.bandwidth = 250'000.0;  // ~2 Mbit/s per link
  config.latency = 0.01;
  config.drop_rate = 0.05;
  dcl::comm::SimRadio radio(config);
  std::mt19937_64 script(3);
  const std::vector<std::uint8_t> heartbeat(40, 1);
  const std::vector<std::uint8_t> descriptor(1500, 2);
  std::vector<std::uint8_t> candidate(20'000, 3);
  for (int k = 0; k < 600; ++k) {
    for (int r = 0; r < robots; ++r)
      radio.setPosition(RobotId(static_cast<std::uint8_t>(r)), position(r, k));
    radio.advanceTo(0.1 * k);
    for (int r = 0; r < robots; ++r) {
      dcl::comm::Transport& endpoint = radio.endpoint(RobotId(static_cast<std::uint8_t>(r)));
      benchmark::DoNotOptimize(endpoint.receive());
      if (k % 10 == r % 10) endpoint.send(std::nullopt, MessageKind::heartbeat, heartbeat);
      if (k % 10 == (r + 5) % 10) endpoint.send(std::nullopt, MessageKind::descriptor, descriptor);
      if (script() % 20 != 0) continue;
      const auto to = static_cast<std::uint8_t>(script() % static_cast<std::uint64_t>(robots));
      const std::size_t n = 2'000 + script() % 18'000;
      endpoint.send(RobotId(to), MessageKind::loop_candidate, {candidate.data(), n});
    }
  }
  radio.advanceTo(120.0);
  return radio.log().size();
}

void BM_SimRadioSwarmMinute(benchmark::State& state) {
  const int robots = static_cast<int>(state.range(0));
  kitti00();
  std::size_t events = 0;
  for (auto _ : state) events = swarmMinute(robots);
  state.counters["log_entries"] = static_cast<double>(events);
  state.counters["entries_per_s"] =
      benchmark::Counter(static_cast<double>(events) * static_cast<double>(state.iterations()),
                         benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SimRadioSwarmMinute)->Arg(2)->Arg(8)->Unit(benchmark::kMillisecond);

}  // namespace
