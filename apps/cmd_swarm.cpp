// `dcl-slam swarm`: one `dcl-slam robot` process per robot of a dataset on
// this machine, over Cyclone DDS on the loopback interface, all on one swarm
// clock (a shared epoch shortly in the future, and the rate); then their
// outputs are read back and evaluated together, as `dcl-slam run` evaluates
// its robots: metrics.json and report.html. The robots share nothing but the
// network: each builds its own view of the dataset and talks to the others
// only through DDS, as robot computers would.
//
// With --ros2, each robot is a live robot (`robot --ros2`) fed by its own
// `play` process over ROS 2 topics, as a LiDAR driver feeds it on a robot:
// the players share the swarm clock, stamp the scans as the dataset does,
// and once they are done and --linger has passed, the robots are stopped
// with SIGINT, as an operator stops them, and write their outputs.
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <sys/prctl.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <dcl/core/error.hpp>
#include <dcl/core/progress.hpp>
#include <dcl/eval/run_report.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/file.hpp>
#include <dcl/robot/frames.hpp>

#include "commands.hpp"
#include "option_checks.hpp"
#include "output_folder.hpp"
#include "printing.hpp"
#include "process.hpp"
#include "robot_outputs.hpp"

namespace dcl::apps {
namespace {

using Json = nlohmann::ordered_json;
using SteadyClock = std::chrono::steady_clock;

/// How often the parent looks at its children (and a signal).
constexpr auto kPollPeriod = std::chrono::milliseconds(100);
/// s a robot gets to write its outputs after SIGTERM before it is killed.
constexpr double kStopGrace = 30.0;
/// s a live robot finishes its round with its peers after SIGINT at most
/// (robot --settle's default), before kStopGrace starts.
constexpr double kLiveSettle = 60.0;

struct SwarmOptions {
  std::string dataset;
  std::string out = "out/swarm";
  double rate = 1.0;
  double linger = 10.0;
  std::size_t max_frames = 0;
  std::vector<std::string> robots;  ///< names; empty: every robot of the dataset
  std::uint32_t domain = 0;
  std::string interface = "lo";
  /// s of wall time from now to the swarm's epoch: every robot process
  /// reads the dataset and builds its world before the clock starts.
  double start_delay = 3.0;
  bool json = false;
  bool force = false;            ///< replace --out even when it holds files of another program
  bool ros2 = false;             ///< live robots, each fed over ROS 2 by a player
  std::uint32_t ros_domain = 0;  ///< the ROS 2 topics' DDS domain, with --ros2
};

// ---- the plan -------------------------------------------------------------------------

void validate(const SwarmOptions& o) {
  if (!(o.rate > 0.0) || !std::isfinite(o.rate))
    throw core::Error("--rate must be a finite number > 0");
  if (o.rate > 1000.0)  // the robots' own bound (cmd_robot.cpp)
    throw core::Error(
        fmt::format("--rate {:g} is beyond 1000 swarm seconds per wall second", o.rate));
  if (!(o.linger >= 0.0) || !std::isfinite(o.linger))
    throw core::Error("--linger must be a finite number >= 0");
  if (!(o.start_delay >= 0.0) || !std::isfinite(o.start_delay))
    throw core::Error("--start-delay must be a finite number >= 0");
}

/// The dataset indices of the robots to start, in dataset order.
std::vector<std::size_t> selectRobots(const io::DatasetSpec& spec,
                                      const std::vector<std::string>& names) {
  std::vector<std::size_t> indices;
  if (names.empty()) {
    for (std::size_t r = 0; r < spec.robots.size(); ++r) indices.push_back(r);
  }
  for (const std::string& name : names) {
    const auto index = spec.robotIndex(name);
    if (!index) {
      std::string known;
      for (const io::RobotSpec& r : spec.robots) known += (known.empty() ? "" : ", ") + r.name;
      throw core::Error(fmt::format("--robots: dataset {} has no robot '{}' (robots: {})",
                                    spec.folder, name, known));
    }
    if (std::find(indices.begin(), indices.end(), *index) == indices.end())
      indices.push_back(*index);
  }
  std::sort(indices.begin(), indices.end());
  if (indices.size() > 255) throw core::Error("a swarm holds at most 255 robots");
  return indices;
}

/// s on the swarm clock at which the last robot stops, from the ground truth
/// (one scan per pose); none when a robot has no ground truth.
std::optional<double> expectedEnd(const io::DatasetSpec& spec,
                                  const std::vector<std::size_t>& robots, const SwarmOptions& o) {
  double end = 0.0;
  for (const std::size_t r : robots) {
    if (spec.robots[r].ground_truth.empty()) return std::nullopt;
    const core::Trajectory truth = io::readGroundTruth(spec, r);
    std::size_t frames = truth.size();
    if (o.max_frames > 0) frames = std::min(frames, o.max_frames);
    if (frames > 0) end = std::max(end, spec.robots[r].start_time + truth.stamp(frames - 1));
  }
  return end + o.linger;
}

/// A swarm name no other run on this network uses at the same time.
std::string uniqueSwarmName() {
  const auto ms = static_cast<long long>(unixNow() * 1000.0);
  return fmt::format("dcl-swarm-{}-{}", ::getpid(), ms);
}

// ---- the robot processes ------------------------------------------------------------

struct Child {
  std::string name;
  std::string log;  ///< its stdout and stderr
  pid_t pid = -1;
  std::optional<int> status;  ///< waitpid's, once it ended
  bool player = false;        ///< a `play` process feeding a live robot
  bool told_to_stop = false;  ///< a live robot sent SIGINT, its normal end
};

/// "exit code 3" or "signal 9".
std::string describeStatus(int status) {
  if (WIFEXITED(status)) return fmt::format("exit code {}", WEXITSTATUS(status));
  if (WIFSIGNALED(status))
    return fmt::format("signal {} ({})", WTERMSIG(status), ::strsignal(WTERMSIG(status)));
  return fmt::format("status {}", status);
}

bool succeeded(int status) {
  return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

/// A child's end is a success: exit code 0, or, for a live robot told to
/// stop, the exit code of its SIGINT.
bool succeeded(const Child& c) {
  return c.status && (succeeded(*c.status) || (c.told_to_stop && WIFEXITED(*c.status) &&
                                               WEXITSTATUS(*c.status) == 128 + SIGINT));
}

/// The last non-empty line of a file (a failed robot's reason), or "".
std::string lastLine(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::string last;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") != std::string::npos) last = line;
  }
  return last;
}

/// Starts `args` (args[0]: the executable) with stdout and stderr into
/// `log`. The child gets SIGTERM when this process dies, so no robot
/// outlives a killed swarm.
pid_t spawn(const std::vector<std::string>& args, const std::string& log) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0)
    throw core::Error(fmt::format("cannot start a robot process: {}", std::strerror(errno)));
  if (pid > 0) return pid;
  // The child: only async-signal-safe calls until exec.
  ::prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (::getppid() != parent) ::_exit(126);
  const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) ::_exit(125);
  ::dup2(fd, STDOUT_FILENO);
  ::dup2(fd, STDERR_FILENO);
  ::execv(argv[0], argv.data());
  static constexpr char kFailed[] = "dcl-slam swarm: cannot execute the robot process\n";
  [[maybe_unused]] const auto n = ::write(STDERR_FILENO, kFailed, sizeof(kFailed) - 1);
  ::_exit(127);
}

/// The options given to the whole program (--config, --log-level), which
/// every robot process must see too.
struct GlobalOptions {
  std::string config;     ///< absolute path, or empty
  std::string log_level;  ///< or empty
};

GlobalOptions globalOptions(CLI::App& app) {
  GlobalOptions g;
  if (CLI::Option* c = app.get_option_no_throw("--config"); c && c->count() > 0)
    g.config = std::filesystem::absolute(c->as<std::string>()).string();
  if (CLI::Option* l = app.get_option_no_throw("--log-level"); l && l->count() > 0)
    g.log_level = l->as<std::string>();
  return g;
}

/// `exe` and the options of the whole program every child must see too;
/// `reads_dataset`: --allow-outside-paths when this process was given it.
std::vector<std::string> programArgs(const std::string& exe, const GlobalOptions& g,
                                     bool reads_dataset) {
  std::vector<std::string> args{exe};
  if (!g.config.empty()) args.insert(args.end(), {"--config", g.config});
  if (!g.log_level.empty()) args.insert(args.end(), {"--log-level", g.log_level});
  if (reads_dataset && datasetReadOptions().allow_outside_paths)
    args.emplace_back("--allow-outside-paths");
  return args;
}

std::vector<std::string> robotArgs(const std::string& exe, const GlobalOptions& g,
                                   const SwarmOptions& o, const std::string& name,
                                   const std::string& swarm, double epoch) {
  std::vector<std::string> args = programArgs(exe, g, /*reads_dataset=*/true);
  args.insert(args.end(), {"robot",
                           "--dataset",
                           o.dataset,
                           "--robot",
                           name,
                           "--out",
                           o.out,
                           "--transport",
                           "dds",
                           "--rate",
                           fmt::format("{}", o.rate),
                           "--epoch",
                           fmt::format("{:.6f}", epoch),
                           "--linger",
                           fmt::format("{}", o.linger),
                           "--max-frames",
                           std::to_string(o.max_frames),
                           "--swarm",
                           swarm,
                           "--domain",
                           std::to_string(o.domain),
                           "--interface",
                           o.interface});
  return args;
}

/// A live robot's scans: one topic per robot, whatever ros.points says.
std::string pointsTopic(const std::string& robot) {
  return "/" + robot + "/points";
}

/// A live robot's IMU, when its dataset's robots carry one.
std::string imuTopic(const std::string& robot) {
  return "/" + robot + "/imu";
}

/// `exe ... robot --ros2`: a live robot reading its scans (and its IMU, `imu`) from its player.
std::vector<std::string> liveRobotArgs(const std::string& exe, const GlobalOptions& g,
                                       const SwarmOptions& o, const std::string& name,
                                       std::size_t id, const std::string& swarm, bool imu) {
  std::vector<std::string> args = programArgs(exe, g, /*reads_dataset=*/false);
  args.insert(args.end(), {"robot", "--ros2", "--robot", name, "--id", std::to_string(id),
                           "--points", pointsTopic(name), "--out", o.out, "--swarm", swarm,
                           "--domain", std::to_string(o.domain), "--ros-domain",
                           std::to_string(o.ros_domain), "--interface", o.interface});
  if (imu) args.insert(args.end(), {"--imu", imuTopic(name)});
  return args;
}

/// `exe ... play`: robot `name`'s scans (and IMU readings, `imu`) on the swarm
/// clock, with their dataset stamps.
std::vector<std::string> playerArgs(const std::string& exe, const GlobalOptions& g,
                                    const SwarmOptions& o, const std::string& name, double epoch,
                                    bool imu) {
  std::vector<std::string> args = programArgs(exe, g, /*reads_dataset=*/true);
  args.insert(args.end(),
              {"play", "--dataset", o.dataset, "--robot", name, "--points", pointsTopic(name),
               "--epoch", fmt::format("{:.6f}", epoch), "--rate", fmt::format("{}", o.rate),
               "--dataset-stamps", "--max-frames", std::to_string(o.max_frames), "--ros-domain",
               std::to_string(o.ros_domain), "--interface", o.interface});
  if (imu) args.insert(args.end(), {"--imu", imuTopic(name)});
  return args;
}

void signalAll(std::vector<Child>& children, int signal) {
  for (const Child& c : children) {
    if (!c.status) ::kill(c.pid, signal);
  }
}

/// Collects the children that ended; true when none is left.
bool reap(std::vector<Child>& children) {
  bool all = true;
  for (Child& c : children) {
    if (c.status) continue;
    int status = 0;
    const pid_t rc = ::waitpid(c.pid, &status, WNOHANG);
    if (rc == c.pid)
      c.status = status;
    else
      all = false;
  }
  return all;
}

/// Waits for every child; the first to fail (or a signal to this process)
/// stops the others with SIGTERM, and after kStopGrace with SIGKILL.
/// Live robots (children with players) get SIGINT once every player is
/// done and `linger` s of swarm time have passed. Returns the first failed
/// child, if one failed.
std::optional<std::size_t> waitAll(std::vector<Child>& children, std::optional<double> end,
                                   double epoch, double rate, double linger) {
  core::ProgressBar progress("swarm", end ? static_cast<std::size_t>(std::ceil(*end)) : 0,
                             "s swarm time");
  const bool live =
      std::any_of(children.begin(), children.end(), [](const Child& c) { return c.player; });
  std::optional<std::size_t> failed;
  std::optional<SteadyClock::time_point> stopping;
  std::optional<SteadyClock::time_point> played;  ///< when the last player ended
  while (!reap(children)) {
    // A live robot ending before it is told to is a failure, as is a player's error.
    if (!failed) {
      for (std::size_t i = 0; i < children.size(); ++i) {
        if (children[i].status && !succeeded(children[i])) {
          failed = i;
          break;
        }
      }
    }
    if (live && !played && std::all_of(children.begin(), children.end(), [](const Child& c) {
          return !c.player || c.status.has_value();
        })) {
      played = SteadyClock::now();
    }
    if (played && !failed && secondsSince(*played) >= linger / rate) {
      for (Child& c : children) {
        if (!c.player && !c.status && !c.told_to_stop) {
          ::kill(c.pid, SIGINT);
          c.told_to_stop = true;
        }
      }
    }
    if (!stopping && (failed || stopSignal() != 0)) {
      stopping = SteadyClock::now();
      signalAll(children, SIGTERM);
    }
    if (stopping && secondsSince(*stopping) > kStopGrace) signalAll(children, SIGKILL);
    if (played && secondsSince(*played) > linger / rate + kLiveSettle + kStopGrace)
      signalAll(children, SIGKILL);
    const auto running =
        std::count_if(children.begin(), children.end(), [](const Child& c) { return !c.status; });
    const double now = std::max(0.0, (unixNow() - epoch) * rate);
    progress.update(static_cast<std::size_t>(now),
                    fmt::format("{} of {} robots running", running, children.size()));
    std::this_thread::sleep_for(kPollPeriod);
  }
  progress.finish();
  if (!failed) {
    for (std::size_t i = 0; i < children.size() && !failed; ++i) {
      if (!succeeded(children[i])) failed = i;
    }
  }
  return failed;
}

// ---- the evaluation -----------------------------------------------------------------

struct SwarmRun {
  eval::RunSummary summary;
  std::vector<RobotReport> reports;  ///< in summary.robots' order
};

/// The inter-robot loops to draw: each is known to both robots of its pair,
/// so each is taken from the lower robot's list, when both robots ran.
std::vector<eval::RunLoop> loopsOf(const std::vector<RobotOutputs>& robots,
                                   const std::map<core::RobotId, std::size_t>& position_of) {
  std::vector<eval::RunLoop> loops;
  const auto position = [&](const core::PoseKey& key) -> std::optional<Eigen::Vector3d> {
    const auto it = position_of.find(key.robot);
    if (it == position_of.end()) return std::nullopt;
    const core::Trajectory& estimate = robots[it->second].estimate;
    if (key.keyframe.value() >= estimate.size()) return std::nullopt;
    return estimate.pose(key.keyframe.value()).translation();
  };
  for (const RobotOutputs& r : robots) {
    for (const RobotReport::Loop& loop : r.report.inter_loops) {
      if (std::min(loop.from.robot, loop.to.robot).value() != r.report.robot) continue;
      const auto a = position(loop.from);
      const auto b = position(loop.to);
      if (!a || !b) continue;
      loops.push_back(
          {position_of.at(loop.from.robot), position_of.at(loop.to.robot), *a, *b, loop.accepted});
    }
  }
  return loops;
}

std::size_t counter(const std::map<std::string, double>& counters, const char* name) {
  const auto it = counters.find(name);
  return it == counters.end() ? 0 : static_cast<std::size_t>(it->second);
}

eval::RobotRun robotRun(RobotOutputs& r, const io::DatasetSpec& spec) {
  eval::RobotRun run;
  run.name = r.report.name;
  run.estimate = std::move(r.estimate);
  run.odometry = std::move(r.odometry);
  // A robot whose frame is unknown (a round's initiator did not say) is in one of its own.
  run.frame = r.report.frame && *r.report.frame < spec.robots.size()
                  ? spec.robots[*r.report.frame].name
                  : "(unknown: " + r.report.name + ")";
  if (!spec.robots[r.report.robot].ground_truth.empty())
    run.ground_truth = io::readGroundTruth(spec, r.report.robot);
  run.frames = r.report.frames;
  run.keyframes = r.report.keyframes;
  run.intra_loops = counter(r.report.counters, "intra_loops");
  run.inter_loops_accepted = counter(r.report.counters, "inter_loops_accepted");
  run.inter_loops_rejected = counter(r.report.counters, "inter_loops_rejected");
  run.bytes_sent = r.report.bytes_sent;
  run.bytes_received = r.report.bytes_received;
  run.sent_over_time = r.report.sent_over_time;
  run.counters = r.report.counters;
  return run;
}

/// Every robot's estimates moved into the lowest frame the accepted loops
/// between frames join its own to (robot/frames.hpp); each robot's `frame`
/// then names that frame.
void joinFrames(std::vector<RobotOutputs>& robots) {
  std::vector<robot::RobotEstimates> estimates;
  std::vector<backend::Factor> loops;
  for (const RobotOutputs& r : robots) {
    const core::RobotId id(r.report.robot);
    robot::RobotEstimates e{id, std::nullopt, r.estimate.poses()};
    if (r.report.frame) e.frame = core::RobotId(*r.report.frame);
    estimates.push_back(std::move(e));
    for (const backend::Factor& f : r.graph.factors()) {  // each loop once: the lower robot's
      if (f.from.robot != f.to.robot && std::min(f.from.robot, f.to.robot) == id)
        loops.push_back(f);
    }
  }
  const std::vector<std::optional<robot::FramePlacement>> placed =
      robot::joinRobots(estimates, loops);
  for (std::size_t i = 0; i < robots.size(); ++i) {
    if (!placed[i]) continue;
    robots[i].estimate.transformWorld(placed[i]->T_root_frame);
    robots[i].report.frame = placed[i]->root.value();
  }
}

SwarmRun readSwarm(const io::DatasetSpec& spec, const std::vector<std::size_t>& robots,
                   const std::string& out) {
  std::vector<RobotOutputs> outputs;
  std::map<core::RobotId, std::size_t> position_of;
  for (const std::size_t r : robots) {
    outputs.push_back(readRobotOutputs(out + "/" + spec.robots[r].name));
    position_of[core::RobotId(static_cast<std::uint8_t>(r))] = outputs.size() - 1;
  }
  joinFrames(outputs);
  SwarmRun run;
  run.summary.dataset = spec.name.empty() ? spec.folder : spec.name;
  run.summary.loops = loopsOf(outputs, position_of);
  run.summary.meter_interval = outputs.front().report.meter_interval;
  for (RobotOutputs& r : outputs) {
    run.summary.duration = std::max(run.summary.duration, r.report.duration);
    run.reports.push_back(r.report);
    run.summary.robots.push_back(robotRun(r, spec));
  }
  return run;
}

Json metricsJson(const SwarmRun& run, const std::vector<eval::RobotMetrics>& metrics,
                 const SwarmOptions& o, const std::string& swarm, double wall_time) {
  Json robots = Json::array();
  for (std::size_t i = 0; i < run.summary.robots.size(); ++i) {
    const eval::RobotRun& r = run.summary.robots[i];
    const eval::RobotMetrics& m = metrics[i];
    const RobotReport& report = run.reports[i];
    Json robot = robotMetricsJson(r, m);
    robot["max_lag_s"] = report.max_lag;
    robot["wall_time_s"] = report.wall_time;
    robot["failed_writes"] = report.failed_writes;
    robot["counters"] = r.counters;
    robots.push_back(std::move(robot));
  }
  return {{"dataset", run.summary.dataset},
          {"duration_s", run.summary.duration},
          {"transport", "dds"},
          {"scans", o.ros2 ? "ros2" : "dataset"},
          {"swarm", swarm},
          {"rate", o.rate},
          {"wall_time_s", wall_time},
          {"robots", robots}};
}

void printTable(const Json& m, const std::string& out) {
  fmt::print("{:<6} {:>7} {:>9} {:>9} {:>9} {:>11} {:>9} {:>7} {:>7} {:>8}\n", "robot", "frames",
             "ATE (m)", "odometry", "joint", "loops", "kB sent", "kB/s tx", "kB/s rx", "max lag");
  for (const Json& r : m["robots"]) {
    const auto accepted = r["inter_loops_accepted"].get<std::size_t>();
    fmt::print("{:<6} {:>7} {:>9} {:>9} {:>9} {:>11} {:>9.1f} {:>7.2f} {:>7.2f} {:>7.2f}s\n",
               r["name"].get<std::string>(), r["frames"].get<std::size_t>(),
               metresText(r["ate_rmse"]), metresText(r["ate_rmse_odometry_only"]),
               metresText(r["ate_rmse_joint"]),
               fmt::format("{} + {}/{}", r["intra_loops"].get<std::size_t>(), accepted,
                           accepted + r["inter_loops_rejected"].get<std::size_t>()),
               static_cast<double>(r["bytes_sent"].get<std::size_t>()) / 1000.0,
               r["transmit_kBps"].get<double>(), r["receive_kBps"].get<double>(),
               r["max_lag_s"].get<double>());
  }
  printFrames(m);
  fmt::print(
      "ATE in m (keyframes, SE(3)-aligned per robot; joint: one alignment for all robots of a "
      "frame); "
      "loops: intra + inter kept/found; max lag: s of swarm time a scan was played late\n");
  fmt::print(
      "{:.1f} s of swarm time at rate {} in {:.1f} s; outputs in {} (metrics.json, "
      "report.html, one folder per robot with its robot.log)\n",
      m["duration_s"].get<double>(), m["rate"].get<double>(), m["wall_time_s"].get<double>(), out);
}

// ---- the command ----------------------------------------------------------------------

void runSwarmProcesses(const SwarmOptions& options, const GlobalOptions& g) {
  validate(options);
  OutputFolder out(options.out, options.force);
  out.requireOutside(options.dataset, "the dataset");
  SwarmOptions o = options;  // the robots write into the staging folder
  o.out = out.path();
  const io::DatasetSpec spec = io::readDataset(o.dataset, datasetReadOptions());
  const std::vector<std::size_t> robots = selectRobots(spec, o.robots);
  const std::optional<double> end = expectedEnd(spec, robots, o);
  const std::string exe = std::filesystem::read_symlink("/proc/self/exe").string();
  const std::string swarm = uniqueSwarmName();
  const StopSignals signals;
  const auto start = SteadyClock::now();
  const double epoch = unixNow() + o.start_delay;
  // The simulated robots' IMUs go over ROS 2 too (sensor_msgs/Imu, as a robot's driver sends it).
  const bool imu = spec.sim.has_value() && spec.sim->imu;

  std::vector<Child> children;
  for (const std::size_t r : robots) {
    const std::string& name = spec.robots[r].name;
    const std::string folder = o.out + "/" + name;
    std::filesystem::create_directories(folder);
    std::filesystem::remove(folder + "/robot.json");  // a stale one must not pass for this run's
    Child& c = children.emplace_back();
    c.name = name;
    c.log = folder + "/robot.log";
    c.pid = spawn(o.ros2 ? liveRobotArgs(exe, g, o, name, r, swarm, imu)
                         : robotArgs(exe, g, o, name, swarm, epoch),
                  c.log);
  }
  for (const std::size_t r : o.ros2 ? robots : std::vector<std::size_t>{}) {
    const std::string& name = spec.robots[r].name;
    Child& c = children.emplace_back();
    c.name = name;
    c.log = o.out + "/" + name + "/play.log";
    c.player = true;
    c.pid = spawn(playerArgs(exe, g, o, name, epoch, imu), c.log);
  }
  if (!o.json) {
    const std::string where = o.interface.empty() ? "the default interface" : o.interface;
    if (o.ros2)
      fmt::print(
          "swarm '{}': {} live robots over DDS on {}, each fed its scans over ROS 2 (domain {}) "
          "by a player, rate {}, logs in {}/NAME/robot.log and play.log\n",
          swarm, robots.size(), where, o.ros_domain, o.rate, out.out());
    else
      fmt::print(
          "swarm '{}': {} robot processes over DDS on {}, rate {}, logs in {}/NAME/robot.log\n",
          swarm, children.size(), where, o.rate, out.out());
  }
  std::fflush(stdout);

  const std::optional<std::size_t> failed = waitAll(children, end, epoch, o.rate, o.linger);
  // A failed robot's last log line, before its log moves with the folder.
  const std::string reason = failed ? lastLine(children[*failed].log) : std::string();
  if (stopSignal() != 0 || failed) out.commit();  // the logs, and what the robots wrote
  if (stopSignal() != 0) {
    std::fprintf(stderr,
                 "dcl-slam swarm: stopped by signal %d; the robots' outputs so far are in %s\n",
                 stopSignal(), out.out().c_str());
    throw CLI::RuntimeError(128 + stopSignal());
  }
  if (failed) {
    const Child& c = children[*failed];
    throw core::Error(fmt::format(
        "{}robot '{}' (pid {}) failed with {}{}; the others were stopped "
        "(its log: {})",
        c.player ? "the player of " : "", c.name, c.pid, describeStatus(*c.status),
        reason.empty() ? "" : ": " + reason,
        (std::filesystem::path(out.out()) / std::filesystem::path(c.log).lexically_relative(o.out))
            .string()));
  }

  const SwarmRun run = readSwarm(spec, robots, o.out);
  const std::vector<eval::RobotMetrics> metrics = eval::evaluateRun(run.summary);
  const Json m = metricsJson(run, metrics, o, swarm, secondsSince(start));
  io::writeFileAtomic(o.out + "/metrics.json",
                      [&](std::ostream& out) { out << m.dump(2) << "\n"; });
  io::writeFileAtomic(o.out + "/report.html",
                      [&](std::ostream& s) { s << eval::reportHtml(run.summary, metrics); });
  out.commit();
  if (o.json) return fmt::print("{}\n", m.dump(2));
  printTable(m, out.out());
}

}  // namespace

void addSwarmCommand(CLI::App& app, const AppConfig& config) {
  auto o = std::make_shared<SwarmOptions>();
  o->domain = config.dds.domain;
  o->ros_domain = config.ros.domain;
  CLI::App* cmd = app.add_subcommand(
      "swarm",
      "starts one `dcl-slam robot` process per robot of a dataset on this machine (Cyclone DDS "
      "on loopback, one swarm clock), waits for them and evaluates their outputs together: "
      "metrics.json and report.html as `run` writes them");
  cmd->add_option("--dataset", o->dataset, "dataset folder (dataset.yaml)")->required();
  cmd->add_option("--out", o->out, "output folder")->capture_default_str();
  cmd->add_option("--rate", o->rate, "swarm seconds per wall second (2: twice real time)")
      ->capture_default_str();
  cmd->add_option("--linger", o->linger,
                  "s of swarm time each robot keeps running after its last scan")
      ->capture_default_str();
  cmd->add_option("--max-frames", o->max_frames, "scans per robot at most (0: all)")
      ->check(kNonNegative)
      ->capture_default_str();
  cmd->add_option("--robots", o->robots, "the robots to start, e.g. a,c (default: all)")
      ->delimiter(',');
  cmd->add_option("--domain", o->domain, "DDS domain id (default: dds.domain)")
      ->capture_default_str();
  cmd->add_option("--interface", o->interface,
                  "network interface the robots talk on, with multicast discovery")
      ->capture_default_str();
  cmd->add_option("--start-delay", o->start_delay,
                  "s from now to the swarm clock's start: the robots load their data first")
      ->capture_default_str();
  cmd->add_flag("--json", o->json, "print metrics.json instead of the table");
  addForceFlag(*cmd, o->force);
  cmd->add_flag("--ros2", o->ros2,
                "live robots (robot --ros2), each fed its scans over ROS 2 by a player (play "
                "--dataset-stamps) on the swarm clock, and stopped with SIGINT --linger after the "
                "last scan");
  cmd->add_option("--ros-domain", o->ros_domain,
                  "with --ros2: DDS domain of the ROS 2 topics (default: ros.domain)")
      ->check(CLI::Range(0, 232))
      ->capture_default_str();
  cmd->callback([o, &app] { runSwarmProcesses(*o, globalOptions(app)); });
}

}  // namespace dcl::apps
