#include "live_view.hpp"

#include <Eigen/Geometry>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

namespace dcl::apps {
namespace {

using Json = nlohmann::json;

constexpr auto kPeriod = std::chrono::milliseconds(250);

// The JSON Schemas of what the channels carry (Foxglove draws
// foxglove.PosesInFrame by its name; the schema describes the fields).
constexpr const char* kPosesSchema = R"({"type":"object","properties":{
"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},
"frame_id":{"type":"string"},
"poses":{"type":"array","items":{"type":"object","properties":{
"position":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},
"orientation":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}}}}}})";
constexpr const char* kCountersSchema = R"({"type":"object","properties":{
"time":{"type":"number"},"frames":{"type":"integer"},"keyframes":{"type":"integer"},
"inter_loops":{"type":"integer"},"bytes_sent":{"type":"integer"}}})";

Json stampOf(double seconds) {
  const auto ns = static_cast<std::int64_t>(std::max(0.0, seconds) * 1e9);
  return {{"sec", ns / 1000000000}, {"nsec", ns % 1000000000}};
}

}  // namespace

std::vector<viz::Channel> LiveView::channels(const std::vector<std::string>& robots) {
  std::vector<viz::Channel> out;
  for (const std::string& r : robots)
    out.push_back({"/" + r + "/path", "foxglove.PosesInFrame", kPosesSchema});
  for (const std::string& r : robots)
    out.push_back({"/" + r + "/counters", "dcl_slam.Counters", kCountersSchema});
  return out;
}

LiveView::LiveView(std::uint16_t port, const std::vector<std::string>& robots, double wait)
    : robots_(robots.size()), server_("dcl-slam", port, channels(robots)) {
  // On stderr: stdout keeps what --json promises.
  fmt::print(stderr,
             "live view: ws://127.0.0.1:{} (Foxglove or Lichtblick: open a connection, Foxglove "
             "WebSocket)\n",
             server_.port());
  std::fflush(stderr);
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait);
  while (server_.clients() == 0 && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
}

void LiveView::update(const swarm::SwarmStatus& status, bool now) {
  const auto wall = std::chrono::steady_clock::now();
  if (!now && wall - last_ < kPeriod) return;
  last_ = wall;
  const auto stamp_ns = static_cast<std::uint64_t>(std::max(0.0, status.time) * 1e9);
  for (std::size_t r = 0; r < robots_ && r < status.nodes.size(); ++r) {
    const robot::RobotNode& node = *status.nodes[r];
    Json poses = Json::array();
    for (const core::Keyframe& k : node.keyframes()) {
      const Eigen::Isometry3d T = node.estimate(k.id);
      const Eigen::Quaterniond q(T.linear());
      poses.push_back(
          {{"position",
            {{"x", T.translation().x()}, {"y", T.translation().y()}, {"z", T.translation().z()}}},
           {"orientation", {{"x", q.x()}, {"y", q.y()}, {"z", q.z()}, {"w", q.w()}}}});
    }
    server_.publish(
        r, stamp_ns,
        Json{{"timestamp", stampOf(status.time)}, {"frame_id", "map"}, {"poses", poses}}.dump());
    const swarm::RobotProgress& p = status.robots[r];
    server_.publish(robots_ + r, stamp_ns,
                    Json{{"time", status.time},
                         {"frames", p.frames},
                         {"keyframes", p.keyframes},
                         {"inter_loops", p.inter_loops},
                         {"bytes_sent", p.bytes_sent}}
                        .dump());
  }
}

}  // namespace dcl::apps
