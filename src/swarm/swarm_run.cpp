#include <algorithm>
#include <cmath>
#include <span>
#include <utility>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <dcl/core/error.hpp>
#include <dcl/robot/frames.hpp>
#include <dcl/swarm/swarm_run.hpp>

namespace dcl::swarm {
namespace {

/// A robot's radio endpoint behind a buffer: arrivals are fetched before a
/// step and handed out during it; sends are kept until after it and then go
/// to the radio in robot order, which keeps a parallel step deterministic.
class BufferedTransport final : public comm::Transport {
 public:
  explicit BufferedTransport(comm::Transport& radio) : radio_(&radio) {}

  [[nodiscard]] core::RobotId self() const override { return radio_->self(); }

  void send(std::optional<core::RobotId> to, comm::MessageKind kind,
            std::span<const std::uint8_t> bytes) override {
    outbox_.push_back({to, kind, {bytes.begin(), bytes.end()}});
  }

  std::vector<comm::Datagram> receive() override { return std::exchange(inbox_, {}); }

  void fetch() {
    for (comm::Datagram& d : radio_->receive()) inbox_.push_back(std::move(d));
  }

  void flush() {
    for (const Outgoing& m : outbox_) radio_->send(m.to, m.kind, m.bytes);
    outbox_.clear();
  }

 private:
  struct Outgoing {
    std::optional<core::RobotId> to;
    comm::MessageKind kind;
    std::vector<std::uint8_t> bytes;
  };
  comm::Transport* radio_;
  std::vector<comm::Datagram> inbox_;
  std::vector<Outgoing> outbox_;
};

void validate(const std::vector<SwarmMember>& members, const SwarmConfig& config) {
  if (members.empty()) throw core::Error("swarm: no robot to run");
  if (members.size() > 254) throw core::Error("swarm: more than 254 robots");
  if (!(config.step > 0.0) || !std::isfinite(config.step))
    throw core::Error("swarm config: step must be a finite number > 0");
  if (!(config.drain >= 0.0) || !std::isfinite(config.drain))
    throw core::Error("swarm config: drain must be finite and at least 0");
  if (!(config.settle >= 0.0) || !std::isfinite(config.settle))
    throw core::Error("swarm config: settle must be finite and at least 0");
  if (config.threads < 0) throw core::Error("swarm config: threads must be at least 0");
  validate(config.map);
  for (const SwarmMember& m : members) {
    if (!m.scans) throw core::Error("swarm: robot '" + m.name + "' has no scans");
  }
}

/// One robot during the run.
struct Member {
  SwarmMember spec;
  std::size_t frames = 0;  ///< to play
  std::size_t next = 0;    ///< the next scan
  std::unique_ptr<BufferedTransport> transport;
  std::unique_ptr<robot::RobotNode> node;
  KeyframeClouds map_clouds;
  std::size_t keyframes_seen = 0;  ///< keyframes whose clouds went to map_clouds

  [[nodiscard]] double swarmTime(std::size_t i) const {
    return spec.start_time + spec.scans->stamp(i);
  }

  [[nodiscard]] bool left(double time) const { return spec.leave_time && time >= *spec.leave_time; }

  /// Plays the scans due by `time`, keeps the clouds of new keyframes for the
  /// map, then handles what arrived; nothing once it has left.
  void step(double time) {
    if (left(time)) return;
    while (next < frames && swarmTime(next) <= time) {
      node->addScan(spec.scans->stamp(next), spec.scans->scan(next), spec.scans->up(next));
      ++next;
    }
    node->tick(time);
    keepClouds();
  }

  void keepClouds() {
    const std::vector<core::Keyframe>& keyframes = node->keyframes();
    for (; keyframes_seen < keyframes.size(); ++keyframes_seen)
      map_clouds.add(keyframes[keyframes_seen].cloud);
  }
};

/// Bytes `id` transmitted per kind and time bin: a broadcast is logged once
/// per link it went on, one entry after the other, and counted once.
std::map<comm::MessageKind, std::vector<std::size_t>> sentOverTime(const comm::SimRadio& radio,
                                                                   core::RobotId id,
                                                                   double interval) {
  std::map<comm::MessageKind, std::vector<std::size_t>> bins;
  const comm::TrafficEvent* previous = nullptr;
  for (const comm::TrafficEvent& e : radio.log()) {
    const bool same_broadcast = previous != nullptr && e.broadcast && previous->broadcast &&
                                previous->from == e.from && previous->sent == e.sent &&
                                previous->kind == e.kind && previous->bytes == e.bytes;
    previous = &e;
    if (e.from != id || e.fate == comm::Fate::unreachable || same_broadcast) continue;
    const auto bin = static_cast<std::size_t>(e.sent / interval);
    std::vector<std::size_t>& series = bins[e.kind];
    if (series.size() <= bin) series.resize(bin + 1, 0);
    series[bin] += e.bytes;
  }
  return bins;
}

/// Every robot's estimates moved into the lowest frame the accepted loops
/// between frames join its own to (robot/frames.hpp).
void joinFrames(std::vector<MemberResult>& robots) {
  std::vector<robot::RobotEstimates> estimates;
  std::vector<backend::Factor> loops;
  for (std::size_t r = 0; r < robots.size(); ++r) {
    const MemberResult& m = robots[r];
    const core::RobotId id(static_cast<std::uint8_t>(r));
    robot::RobotEstimates e{id, m.frame, {}};
    for (const core::Keyframe& k : m.keyframes) {
      const core::PoseKey key{id, k.id};
      e.keyframes.push_back(m.graph.hasNode(key) ? m.graph.estimate(key) : k.T_odom_keyframe);
    }
    estimates.push_back(std::move(e));
    for (const robot::InterLoop& loop : m.inter_loops) {  // each once: from the lower robot's list
      if (loop.accepted && std::min(loop.factor.from.robot, loop.factor.to.robot) == id)
        loops.push_back(loop.factor);
    }
  }
  const std::vector<std::optional<robot::FramePlacement>> placed =
      robot::joinRobots(estimates, loops);
  for (std::size_t r = 0; r < robots.size(); ++r) {
    if (!placed[r]) continue;
    MemberResult& m = robots[r];
    std::vector<std::pair<core::PoseKey, Eigen::Isometry3d>> moved;
    for (const auto& [key, T] : m.graph.nodes())
      moved.emplace_back(key, placed[r]->T_root_frame * T);
    for (const auto& [key, T] : moved) m.graph.setEstimate(key, T);
    m.frame = placed[r]->root;
  }
}

MemberResult resultOf(Member& m, const comm::SimRadio& radio, core::RobotId id, double interval) {
  MemberResult r;
  r.name = m.spec.name;
  r.map_clouds = std::move(m.map_clouds);
  r.frames = m.next;
  r.keyframes.reserve(m.node->keyframes().size());
  for (const core::Keyframe& k : m.node->keyframes()) {  // all but the cloud, never copied
    r.keyframes.push_back(
        {k.robot, k.id, k.stamp, k.T_odom_keyframe, k.T_previous_keyframe, k.covariance, {}});
  }
  r.graph = m.node->graph();
  r.frame = m.node->frame();
  r.inter_loops = m.node->interLoops();
  r.counters = m.node->counters();
  r.traffic = radio.traffic(id);
  r.sent_over_time = sentOverTime(radio, id, interval);
  return r;
}

void updateStatus(SwarmStatus& status, const std::vector<Member>& robots,
                  const comm::SimRadio& radio, double time) {
  status.time = time;
  for (std::size_t r = 0; r < robots.size(); ++r) {
    const Member& m = robots[r];
    RobotProgress& p = status.robots[r];
    p.frames = m.next;
    p.keyframes = m.node->keyframes().size();
    const auto& counters = m.node->counters();
    const auto loops = counters.find("inter_loops_accepted");
    p.inter_loops = loops == counters.end() ? 0 : static_cast<std::size_t>(loops->second);
    p.bytes_sent = radio.traffic(core::RobotId(static_cast<std::uint8_t>(r))).sent;
    p.left = m.left(time);
  }
}

}  // namespace

SwarmResult runSwarm(std::vector<SwarmMember> members, const SwarmConfig& config,
                     const SwarmProgress& progress) {
  validate(members, config);
  comm::SimRadio radio(config.radio);
  std::vector<Member> robots(members.size());
  double end = 0.0;
  for (std::size_t r = 0; r < members.size(); ++r) {
    Member& m = robots[r];
    m.spec = std::move(members[r]);
    m.frames = m.spec.scans->size();
    if (config.max_frames > 0) m.frames = std::min(m.frames, config.max_frames);
    if (m.frames > 0) end = std::max(end, m.swarmTime(m.frames - 1));
    const core::RobotId id(static_cast<std::uint8_t>(r));
    m.transport = std::make_unique<BufferedTransport>(radio.endpoint(id));
    m.node = std::make_unique<robot::RobotNode>(*m.transport, config.robot, /*incarnation=*/1,
                                                std::move(m.spec.front_end));
    m.map_clouds = KeyframeClouds(config.map.voxel);
  }
  end += config.drain;
  SwarmStatus status;
  status.end = end;
  for (const Member& m : robots) {
    status.robots.push_back({.name = m.spec.name, .total_frames = m.frames});
    status.nodes.push_back(m.node.get());
  }

  tbb::task_arena arena(config.threads > 0 ? config.threads : tbb::task_arena::automatic);
  const auto optimising = [&](double t) {
    return std::any_of(robots.begin(), robots.end(),
                       [&](const Member& m) { return !m.left(t) && !m.node->settled(); });
  };
  double time = 0.0;
  for (std::size_t k = 0; time <= end || (time <= end + config.settle && optimising(time));
       time = static_cast<double>(++k) * config.step) {
    for (std::size_t r = 0; r < robots.size(); ++r) {
      const core::Trajectory& truth = robots[r].spec.ground_truth;
      if (truth.empty()) continue;
      if (const auto T = truth.at(time - robots[r].spec.start_time))
        radio.setPosition(core::RobotId(static_cast<std::uint8_t>(r)), T->translation());
    }
    radio.advanceTo(time);
    for (Member& m : robots) m.transport->fetch();  // a robot that left hears nothing either
    arena.execute([&] {
      tbb::parallel_for(std::size_t{0}, robots.size(),
                        [&](std::size_t r) { robots[r].step(time); });
    });
    for (Member& m : robots) m.transport->flush();
    if (progress) {
      updateStatus(status, robots, radio, time);
      progress(status);
    }
  }

  // The run is over: a round still refining keeps the last step its group
  // kept (a robot that left stopped with what it held then).
  for (Member& m : robots)
    if (!m.left(time)) m.node->stop();

  SwarmResult result;
  result.duration = time;
  result.radio_events = radio.log().size();
  for (std::size_t r = 0; r < robots.size(); ++r) {
    result.robots.push_back(resultOf(robots[r], radio, core::RobotId(static_cast<std::uint8_t>(r)),
                                     config.radio.meter_interval));
    robots[r].node.reset();  // its keyframe clouds go before the next robot's results come
  }
  joinFrames(result.robots);
  return result;
}

}  // namespace dcl::swarm
