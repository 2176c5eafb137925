#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <dcl/core/colour.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/eval/ate.hpp>
#include <dcl/eval/run_report.hpp>
#include <dcl/io/image.hpp>
#include <dcl/io/pose_file.hpp>

#include "test_support.hpp"

namespace dcl::eval {
namespace {

namespace fs = std::filesystem;

constexpr std::size_t kRobots = 3;
constexpr std::size_t kKeyframeEvery = 5;  // KITTI runs at 10 Hz: a keyframe every 0.5 s

// KITTI's camera frame (x right, y down, z forward) as a z-up frame (x forward, y left), the
// frame of a LiDAR robot: the report's top view (x-y) then sees the streets from above.
Eigen::Isometry3d zUpFromCamera() {
  Eigen::Matrix3d R;
  R << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  return core::makePose(Eigen::Vector3d::Zero(), R);
}

// KITTI 00 ground truth with its real stamps, read by dcl::io, in a z-up frame.
const core::Trajectory& kitti00() {
  static const core::Trajectory gt = [] {
    core::Trajectory t = io::readKittiPoses(test::evoData("KITTI_00_gt.txt"),
                                            test::evoData("KITTI_00_gt_times.txt"));
    t.transformWorld(zUpFromCamera());
    t.transformBody(zUpFromCamera().inverse());
    return t;
  }();
  return gt;
}

core::Trajectory slice(const core::Trajectory& t, std::size_t begin, std::size_t end,
                       std::size_t every) {
  core::Trajectory out;
  for (std::size_t i = begin; i < end; i += every) out.push_back(t.stamp(i), t.pose(i));
  return out;
}

// `keyframes` re-integrated from their relative motions with a yaw error per step and a scale
// error on every translation: how odometry drifts, deterministically.
core::Trajectory drifted(const core::Trajectory& keyframes, double yaw_per_step,
                         double scale_error) {
  const Eigen::Isometry3d yaw =
      core::makePose(Eigen::Vector3d::Zero(), core::expSO3(Eigen::Vector3d(0, 0, yaw_per_step)));
  core::Trajectory out;
  Eigen::Isometry3d T = keyframes.pose(0);
  out.push_back(keyframes.stamp(0), T);
  for (std::size_t i = 1; i < keyframes.size(); ++i) {
    Eigen::Isometry3d step = keyframes.pose(i - 1).inverse() * keyframes.pose(i);
    step.translation() *= 1.0 + scale_error;
    T = T * yaw * step;
    out.push_back(keyframes.stamp(i), T);
  }
  return out;
}

// The common frame of the swarm: the anchor's odometry frame, a rigid motion away from the
// ground truth's world.
Eigen::Isometry3d commonFromWorld() {
  return core::makePose(Eigen::Vector3d(-40.0, 12.0, 1.5),
                        core::expSO3(Eigen::Vector3d(0, 0, 0.7)));
}

// Inter-robot loops where two robots' keyframes are within 4 m of each other (KITTI 00 comes
// back to its streets), drawn at the full system's positions; every third one is rejected.
std::vector<RunLoop> revisits(const RunSummary& run,
                              const std::vector<core::Trajectory>& keyframes) {
  std::vector<RunLoop> loops;
  for (std::size_t a = 0; a < kRobots; ++a) {
    for (std::size_t b = a + 1; b < kRobots; ++b) {
      for (std::size_t i = 0; i < keyframes[a].size(); i += 4) {
        for (std::size_t j = 0; j < keyframes[b].size(); ++j) {
          const Eigen::Vector3d d =
              keyframes[a].pose(i).translation() - keyframes[b].pose(j).translation();
          if (d.norm() > 4.0) continue;
          loops.push_back({a, b, run.robots[a].estimate.pose(i).translation(),
                           run.robots[b].estimate.pose(j).translation(), loops.size() % 3 != 2});
          break;
        }
      }
    }
  }
  return loops;
}

// Bytes a robot sends per second: descriptors with each keyframe, a loop measurement now and
// then, optimisation rounds in bursts.
std::map<std::string, std::vector<std::size_t>> traffic(std::size_t robot, std::size_t seconds) {
  std::map<std::string, std::vector<std::size_t>> sent;
  for (std::size_t s = 0; s < seconds; ++s) {
    sent["descriptor"].push_back(2 * (1100 + 37 * ((s + robot) % 11)));
    sent["loop_measurement"].push_back((s + 3 * robot) % 17 == 0 ? 420 : 0);
    sent["dgs"].push_back((s / 20 + robot) % 3 == 0 ? 900 + 13 * (s % 7) : 0);
  }
  return sent;
}

// KITTI 00 split into three robots as the paper splits its sequences; odometry with a slow yaw
// and scale drift, the full system with one twentieth of it, in the common frame.
struct Swarm {
  RunSummary run;
  std::vector<core::Trajectory> keyframes;  // ground truth at the keyframes
};

Swarm kittiSwarm() {
  const core::Trajectory& gt = kitti00();
  Swarm swarm;
  swarm.run.dataset = "kitti00-3";
  swarm.run.duration = gt.stamps().back() - gt.stamps().front();
  const auto seconds = static_cast<std::size_t>(std::ceil(swarm.run.duration));
  for (std::size_t r = 0; r < kRobots; ++r) {
    const std::size_t begin = r * gt.size() / kRobots, end = (r + 1) * gt.size() / kRobots;
    swarm.keyframes.push_back(slice(gt, begin, end, kKeyframeEvery));
    RobotRun robot;
    robot.name = "robot_" + std::to_string(r);
    robot.ground_truth = slice(gt, begin, end, 1);
    robot.estimate = drifted(swarm.keyframes[r], 5e-5, 0.001);
    robot.estimate.transformWorld(commonFromWorld());
    robot.odometry = drifted(swarm.keyframes[r], 1e-3, 0.02);
    robot.odometry.transformWorld(swarm.keyframes[r].pose(0).inverse());
    robot.frames = end - begin;
    robot.keyframes = swarm.keyframes[r].size();
    robot.sent_over_time = traffic(r, seconds);
    for (const auto& [kind, bins] : robot.sent_over_time)
      for (const std::size_t b : bins) robot.bytes_sent += b;
    robot.bytes_received = 2 * robot.bytes_sent - 1000 * r;
    robot.counters = {{"descriptors_sent", static_cast<double>(robot.keyframes)},
                      {"candidates", 40.0 + static_cast<double>(r)},
                      {"verified", 12.0},
                      {"dgs_iterations_mean", 7.25}};
    swarm.run.robots.push_back(std::move(robot));
  }
  swarm.run.loops = revisits(swarm.run, swarm.keyframes);
  for (const RunLoop& loop : swarm.run.loops) {
    for (const std::size_t r : {loop.robot_a, loop.robot_b}) {
      ++(loop.accepted ? swarm.run.robots[r].inter_loops_accepted
                       : swarm.run.robots[r].inter_loops_rejected);
    }
  }
  return swarm;
}

const Swarm& swarm() {
  static const Swarm s = kittiSwarm();
  return s;
}

// All robots' trajectories one after the other (their stamps follow each other).
core::Trajectory concatenated(const std::vector<const core::Trajectory*>& parts) {
  core::Trajectory out;
  for (const core::Trajectory* t : parts)
    for (std::size_t i = 0; i < t->size(); ++i) out.push_back(t->stamp(i), t->pose(i));
  return out;
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(RunReport, CollaborationBeatsOdometryOnKitti00) {
  const RunSummary& run = swarm().run;
  const std::vector<RobotMetrics> metrics = evaluateRun(run);
  ASSERT_EQ(metrics.size(), kRobots);
  for (std::size_t r = 0; r < kRobots; ++r) {
    const RobotMetrics& m = metrics[r];
    ASSERT_TRUE(m.ate_rmse && m.ate_rmse_odometry_only && m.are_rmse_deg &&
                m.are_rmse_deg_odometry_only && m.ate_rmse_joint);
    const AteResult full = computeAte(run.robots[r].estimate, run.robots[r].ground_truth);
    const AteResult odometry = computeAte(run.robots[r].odometry, run.robots[r].ground_truth);
    EXPECT_EQ(full.pairs, swarm().keyframes[r].size());
    EXPECT_NEAR(*m.ate_rmse, full.translation_m.rmse, 1e-12);
    EXPECT_NEAR(*m.are_rmse_deg, full.rotation_deg.rmse, 1e-12);
    EXPECT_NEAR(*m.ate_rmse_odometry_only, odometry.translation_m.rmse, 1e-12);
    EXPECT_NEAR(*m.are_rmse_deg_odometry_only, odometry.rotation_deg.rmse, 1e-12);
    EXPECT_GT(*m.ate_rmse_odometry_only, 1.0) << "the drift should show";
    EXPECT_LT(*m.ate_rmse, 0.3 * *m.ate_rmse_odometry_only) << run.robots[r].name;
    EXPECT_LT(*m.are_rmse_deg, *m.are_rmse_deg_odometry_only) << run.robots[r].name;
  }
}

TEST(RunReport, JointAlignmentIsFittedOnAllRobotsTogether) {
  const RunSummary& run = swarm().run;
  const std::vector<RobotMetrics> metrics = evaluateRun(run);
  const AteResult pooled = computeAte(
      concatenated({&run.robots[0].estimate, &run.robots[1].estimate, &run.robots[2].estimate}),
      concatenated(
          {&run.robots[0].ground_truth, &run.robots[1].ground_truth, &run.robots[2].ground_truth}));
  for (std::size_t r = 0; r < kRobots; ++r) {
    const Association pairs = associate(run.robots[r].estimate, run.robots[r].ground_truth);
    const double expected = computeAte(pairs, pooled.S_gt_est, Alignment::se3).translation_m.rmse;
    ASSERT_TRUE(metrics[r].ate_rmse_joint);
    EXPECT_NEAR(*metrics[r].ate_rmse_joint, expected, 1e-9 * expected);
    // One alignment for three robots fits each of them worse than its own.
    EXPECT_GE(*metrics[r].ate_rmse_joint, *metrics[r].ate_rmse - 1e-9);
  }
}

TEST(RunReport, RigidlyMovedGroundTruthHasNoError) {
  RunSummary run = swarm().run;
  for (std::size_t r = 0; r < kRobots; ++r) {
    run.robots[r].estimate = swarm().keyframes[r];
    run.robots[r].estimate.transformWorld(commonFromWorld());
  }
  for (const RobotMetrics& m : evaluateRun(run)) {
    EXPECT_NEAR(*m.ate_rmse, 0.0, 1e-6);
    EXPECT_NEAR(*m.ate_rmse_joint, 0.0, 1e-6);
    EXPECT_NEAR(*m.are_rmse_deg, 0.0, 1e-4);
  }
}

TEST(RunReport, RigidMotionOfOneRobotChangesOnlyTheJointAte) {
  const std::vector<RobotMetrics> before = evaluateRun(swarm().run);
  RunSummary run = swarm().run;
  // Robot 1 never met the others: its estimate stays in a frame of its own.
  run.robots[1].estimate.transformWorld(
      core::makePose(Eigen::Vector3d(25.0, -10.0, 0.0), core::expSO3(Eigen::Vector3d(0, 0, 0.3))));
  const std::vector<RobotMetrics> after = evaluateRun(run);
  for (std::size_t r = 0; r < kRobots; ++r) {
    EXPECT_NEAR(*after[r].ate_rmse, *before[r].ate_rmse, 1e-6);
    EXPECT_NEAR(*after[r].are_rmse_deg, *before[r].are_rmse_deg, 1e-6);
    EXPECT_DOUBLE_EQ(*after[r].ate_rmse_odometry_only, *before[r].ate_rmse_odometry_only);
  }
  EXPECT_GT(*after[1].ate_rmse_joint, *before[1].ate_rmse_joint + 5.0);
}

TEST(RunReport, RobotsOfAnotherFrameAreAlignedApart) {
  // The same moved robot, named as in a frame of its own: the joint alignment
  // of the other two no longer sees it, and its own joint ATE is its own.
  RunSummary run = swarm().run;
  run.robots[1].estimate.transformWorld(
      core::makePose(Eigen::Vector3d(25.0, -10.0, 0.0), core::expSO3(Eigen::Vector3d(0, 0, 0.3))));
  for (std::size_t r = 0; r < kRobots; ++r) run.robots[r].frame.assign(1, r == 1 ? 'b' : 'a');
  const std::vector<RobotMetrics> metrics = evaluateRun(run);
  EXPECT_NEAR(*metrics[1].ate_rmse_joint, *metrics[1].ate_rmse, 1e-9);
  const AteResult pooled =
      computeAte(concatenated({&run.robots[0].estimate, &run.robots[2].estimate}),
                 concatenated({&run.robots[0].ground_truth, &run.robots[2].ground_truth}));
  for (const std::size_t r : {std::size_t{0}, std::size_t{2}}) {
    const Association pairs = associate(run.robots[r].estimate, run.robots[r].ground_truth);
    const double expected = computeAte(pairs, pooled.S_gt_est, Alignment::se3).translation_m.rmse;
    EXPECT_NEAR(*metrics[r].ate_rmse_joint, expected, 1e-9 * expected);
  }
}

TEST(RunReport, TrafficInKiloBytesPerSecond) {
  RunSummary run = swarm().run;
  for (const RobotMetrics& m : evaluateRun(run)) {
    EXPECT_GT(m.transmit_kBps, 0.0);
    EXPECT_GT(m.receive_kBps, m.transmit_kBps);
  }
  run.robots[0].bytes_sent = 1'234'567;
  run.robots[0].bytes_received = 89'000;
  run.duration = 470.5;
  const RobotMetrics m = evaluateRun(run)[0];
  EXPECT_DOUBLE_EQ(m.transmit_kBps, 1234.567 / 470.5);
  EXPECT_DOUBLE_EQ(m.receive_kBps, 89.0 / 470.5);
  run.duration = 0.0;
  EXPECT_EQ(evaluateRun(run)[0].transmit_kBps, 0.0);
  EXPECT_EQ(evaluateRun(run)[0].receive_kBps, 0.0);
  run.duration = -1.0;
  EXPECT_THROW(evaluateRun(run), core::Error);
}

TEST(RunReport, NoAteWithoutGroundTruth) {
  RunSummary run = swarm().run;
  run.robots[2].ground_truth = {};
  const std::vector<RobotMetrics> metrics = evaluateRun(run);
  const RobotMetrics& m = metrics[2];
  EXPECT_FALSE(m.ate_rmse || m.ate_rmse_odometry_only || m.ate_rmse_joint || m.are_rmse_deg ||
               m.are_rmse_deg_odometry_only);
  EXPECT_GT(m.transmit_kBps, 0.0);
  // The others keep their own ATE; the joint alignment is fitted on them alone.
  const std::vector<RobotMetrics> all = evaluateRun(swarm().run);
  const AteResult pooled =
      computeAte(concatenated({&run.robots[0].estimate, &run.robots[1].estimate}),
                 concatenated({&run.robots[0].ground_truth, &run.robots[1].ground_truth}));
  for (std::size_t r = 0; r < 2; ++r) {
    EXPECT_DOUBLE_EQ(*metrics[r].ate_rmse, *all[r].ate_rmse);
    const Association pairs = associate(run.robots[r].estimate, run.robots[r].ground_truth);
    EXPECT_NEAR(*metrics[r].ate_rmse_joint,
                computeAte(pairs, pooled.S_gt_est, Alignment::se3).translation_m.rmse, 1e-9);
  }
}

TEST(RunReport, StampsThatNeverMatchAreAnErrorNamingTheRobot) {
  RunSummary run = swarm().run;
  run.robots[1].name = "scout";
  std::vector<double> late = run.robots[1].ground_truth.stamps();
  for (double& t : late) t += 1000.0;
  run.robots[1].ground_truth = core::Trajectory(late, run.robots[1].ground_truth.poses());
  try {
    evaluateRun(run);
    FAIL() << "expected core::Error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("'scout'"), std::string::npos) << e.what();
  }
}

// The swarm with names that HTML must not take as markup.
RunSummary hostileNames() {
  RunSummary run = swarm().run;
  run.dataset = "kitti<00> & \"friends\"";
  run.robots[0].name = "<script>alert(\"x\")</script>";
  run.robots[1].name = "R&D 'b'";
  run.robots[2].sent_over_time["<kind>"] = {10, 20, 30};
  run.robots[2].counters["a<b"] = 1.0;
  return run;
}

// The run with a map: around each keyframe of each robot, a ring of points 6 m
// out, as walls around a street would be, in the robot's colour.
RunSummary withMap(RunSummary run) {
  for (std::size_t r = 0; r < run.robots.size(); ++r) {
    for (const Eigen::Isometry3d& T : run.robots[r].estimate.poses()) {
      for (int k = 0; k < 24; ++k) {
        const double angle = k * 2.0 * M_PI / 24.0;
        const Eigen::Vector3d p =
            T.translation() + 6.0 * Eigen::Vector3d(std::cos(angle), std::sin(angle), 0.0);
        run.map_points.push_back(p.cast<float>());
        run.map_robots.push_back(static_cast<std::uint8_t>(r));
      }
    }
  }
  return run;
}

TEST(RunReport, HtmlEscapesEveryNameAndHasOneSvgPerPlot) {
  const RunSummary run = hostileNames();
  const std::string html = reportHtml(run, evaluateRun(run));
  EXPECT_EQ(html.rfind("<!DOCTYPE html>\n<html lang=\"en\">", 0), 0u);
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("<kind>"), std::string::npos);
  EXPECT_EQ(html.find("<00>"), std::string::npos);
  EXPECT_NE(html.find("&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;"), std::string::npos);
  EXPECT_NE(html.find("kitti&lt;00&gt; &amp; &quot;friends&quot;"), std::string::npos);
  EXPECT_NE(html.find("R&amp;D &#39;b&#39;"), std::string::npos);
  EXPECT_NE(html.find("a&lt;b"), std::string::npos);
  // Trajectories, ATE bars, traffic.
  EXPECT_EQ(count(html, "<svg "), 3u);
  EXPECT_EQ(count(html, "</svg>"), 3u);
  // Per robot ground truth, full system and odometry; one line per loop; one per message kind.
  EXPECT_EQ(count(html, "<polyline class=\"gt\""), kRobots);
  EXPECT_EQ(count(html, "<polyline class=\"est\""), kRobots);
  EXPECT_EQ(count(html, "<polyline class=\"odo\""), kRobots);
  EXPECT_EQ(count(html, "<polyline class=\"loop\""), run.loops.size());
  EXPECT_EQ(count(html, "<polyline class=\"traffic\""), 4u);
  EXPECT_GT(run.loops.size(), 5u);
  EXPECT_LT(html.size(), 400'000u);
}

TEST(RunReport, HtmlIsDeterministic) {
  const RunSummary run = hostileNames();
  const std::string first = reportHtml(run, evaluateRun(run));
  const RunSummary copy = hostileNames();
  EXPECT_EQ(reportHtml(copy, evaluateRun(copy)), first);
  // Changing a result changes the page.
  RunSummary other = hostileNames();
  other.robots[1].bytes_sent += 1;
  EXPECT_NE(reportHtml(other, evaluateRun(other)), first);
}

TEST(RunReport, LongRunsAreThinned) {
  RunSummary run;
  run.dataset = "long";
  run.duration = 5000.0;
  RobotRun robot;
  robot.name = "long";
  // All of KITTI 00 twice, the second time 0.05 s later: 9082 poses per line.
  const core::Trajectory& gt = kitti00();
  for (const double shift : {0.0, 0.05})
    for (std::size_t i = 0; i < gt.size(); ++i)
      robot.estimate.push_back(gt.stamp(i) + shift, gt.pose(i));
  robot.odometry = robot.estimate;
  robot.ground_truth = robot.estimate;
  robot.sent_over_time["descriptor"] = std::vector<std::size_t>(4000, 1500);
  run.robots.push_back(robot);
  const std::string html = reportHtml(run, evaluateRun(run));
  const std::regex points("points=\"([^\"]*)\"");
  std::size_t lines = 0;
  for (auto it = std::sregex_iterator(html.begin(), html.end(), points);
       it != std::sregex_iterator(); ++it, ++lines) {
    const std::string list = (*it)[1].str();
    EXPECT_LE(count(list, " ") + 1, 2000u);
    EXPECT_GT(count(list, " ") + 1, 1000u);
  }
  EXPECT_EQ(lines, 4u);
  // 4000 one-second traffic bins are drawn as 2000 bins of two seconds.
  EXPECT_NE(html.find("sent per 2.00 s"), std::string::npos);
}

TEST(RunReport, SparseRunsStillMakeAPage) {
  RunSummary run;
  run.dataset = "empty";
  EXPECT_TRUE(evaluateRun(run).empty());
  EXPECT_EQ(count(reportHtml(run, {}), "<svg "), 0u);
  // A robot that left before its third keyframe, without traffic: no ATE, an empty plot.
  RobotRun robot;
  robot.name = "early";
  robot.ground_truth = slice(kitti00(), 0, 50, 1);
  robot.estimate = slice(kitti00(), 0, 10, 5);
  run.robots.push_back(robot);
  const std::vector<RobotMetrics> metrics = evaluateRun(run);
  EXPECT_FALSE(metrics[0].ate_rmse || metrics[0].ate_rmse_joint ||
               metrics[0].ate_rmse_odometry_only);
  const std::string html = reportHtml(run, metrics);
  EXPECT_EQ(count(html, "<svg "), 1u);
  EXPECT_NE(html.find("No traffic recorded."), std::string::npos);
  EXPECT_NE(html.find("Not aligned to ground truth"), std::string::npos);
}

TEST(RunReport, RejectsInconsistentInput) {
  RunSummary run = swarm().run;
  const std::vector<RobotMetrics> metrics = evaluateRun(run);
  EXPECT_THROW(reportHtml(run, {metrics[0]}), core::Error);
  RunSummary map = withMap(run);
  map.map_robots.pop_back();
  EXPECT_THROW(reportHtml(map, metrics), core::Error);
  map.map_robots.push_back(7);
  EXPECT_THROW(reportHtml(map, metrics), core::Error);
  run.loops.push_back({0, 7, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), true});
  try {
    reportHtml(run, metrics);
    FAIL() << "expected core::Error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("loop"), std::string::npos) << e.what();
  }
}

// RFC 4648 base64, as the report embeds its map.
std::string fromBase64(const std::string& text) {
  const std::string digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::uint32_t v = 0;
  int bits = 0;
  for (const char c : text) {
    if (c == '=') break;
    const auto d = digits.find(c);
    if (d == std::string::npos) throw std::runtime_error("not base64");
    v = (v << 6) | static_cast<std::uint32_t>(d);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out += static_cast<char>((v >> bits) & 0xFF);
    }
  }
  return out;
}

std::size_t pixelsOf(const io::Image& image, const std::array<std::uint8_t, 3>& c, int tolerance) {
  std::size_t n = 0;
  const auto& d = image.data();
  for (std::size_t i = 0; i + 2 < d.size(); i += 3) {
    if (std::abs(d[i] - c[0]) <= tolerance && std::abs(d[i + 1] - c[1]) <= tolerance &&
        std::abs(d[i + 2] - c[2]) <= tolerance)
      ++n;
  }
  return n;
}

TEST(RunReport, MergedMapIsDrawnInEachRobotsColourWithTheAcceptedLoops) {
  EXPECT_EQ(reportHtml(swarm().run, evaluateRun(swarm().run)).find("merged map"), std::string::npos)
      << "no map, no picture";
  const RunSummary run = withMap(swarm().run);
  const std::string html = reportHtml(run, evaluateRun(run));
  EXPECT_EQ(count(html, "<svg "), 4u);
  const std::string prefix = "<image class=\"map\"";
  ASSERT_EQ(count(html, prefix), 1u);
  const std::size_t at = html.find("base64,", html.find(prefix)) + 7;
  const std::string png = fromBase64(html.substr(at, html.find('"', at) - at));
  const fs::path file =
      fs::temp_directory_path() / ("dcl_map_" + std::to_string(::getpid()) + ".png");
  std::ofstream(file, std::ios::binary) << png;
  const io::Image image = io::readPng(file.string());
  fs::remove(file);
  // A pixel of the plot a pixel of the picture.
  EXPECT_EQ(image.width(), 640);
  std::size_t drawn = 0;
  for (std::size_t r = 0; r < kRobots; ++r) {
    const std::size_t n = pixelsOf(image, core::robotColour(r), 0);
    EXPECT_GT(n, 1000u) << "robot " << r;
    drawn += n;
  }
  EXPECT_GT(pixelsOf(image, {255, 255, 255}, 0), drawn) << "points on white";
  // On the map, the accepted loops only (the trajectory plot draws all).
  std::size_t accepted = 0;
  for (const RunLoop& loop : run.loops) accepted += loop.accepted ? 1 : 0;
  EXPECT_EQ(count(html, "<polyline class=\"loop\""), run.loops.size() + accepted);
}

TEST(RunReport, TrafficKindsHaveTheirOwnColours) {
  const RunSummary run = hostileNames();
  const std::string html = reportHtml(run, evaluateRun(run));
  const std::string traffic = html.substr(html.find("aria-label=\"traffic over time\""));
  const std::regex stroke("<line class=\"traffic\" stroke=\"(#[0-9a-f]{6})\"");
  std::set<std::string> legend;
  for (auto it = std::sregex_iterator(traffic.begin(), traffic.end(), stroke);
       it != std::sregex_iterator(); ++it)
    legend.insert((*it)[1].str());
  EXPECT_EQ(legend.size(), 4u) << "one colour per kind";
  for (std::size_t r = 0; r < kRobots; ++r) {
    const auto c = core::robotColour(r);
    EXPECT_EQ(legend.count(fmt::format("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])), 0u)
        << "a kind is not a robot";
  }
}

TEST(RunReport, AteBarsTellCloseValuesApart) {
  const RunSummary& run = swarm().run;
  std::vector<RobotMetrics> metrics = evaluateRun(run);
  metrics[0].ate_rmse = 0.0121;
  metrics[1].ate_rmse = 0.0127;
  metrics[2].ate_rmse = 1.5;
  const std::string html = reportHtml(run, metrics);
  EXPECT_NE(html.find(">0.0121</text>"), std::string::npos);
  EXPECT_NE(html.find(">0.0127</text>"), std::string::npos);
  EXPECT_NE(html.find(">1.5000</text>"), std::string::npos);
}

bool haveChromium() {
  return std::system("command -v chromium > /dev/null 2>&1") == 0;
}

std::string readText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Pixels clearly coloured (not white, grey or black): plot lines and bars, not text.
std::size_t colouredPixels(const io::Image& image) {
  std::size_t n = 0;
  const auto& d = image.data();
  for (std::size_t i = 0; i + 2 < d.size(); i += 3) {
    const int hi = std::max({d[i], d[i + 1], d[i + 2]}), lo = std::min({d[i], d[i + 1], d[i + 2]});
    if (hi - lo > 80) ++n;
  }
  return n;
}

// `html` rendered by headless Chromium into DIR/NAME.png (a 1200 x 5000 window: the whole page),
// and the DOM it built; fails the test when Chromium does.
struct Rendered {
  io::Image page;
  std::string dom;
};

Rendered render(const fs::path& dir, const std::string& name, const std::string& html) {
  const fs::path page = dir / (name + ".html"), png = dir / (name + ".png");
  std::ofstream(page) << html;
  // Its profile, caches and crash folders go to the temporary folder, not the user's home.
  const std::string home = (dir / "home").string();
  const std::string command =
      "HOME='" + home + "' XDG_CONFIG_HOME='" + home + "' XDG_CACHE_HOME='" + home +
      "' timeout 60 chromium --headless --no-sandbox --disable-gpu "
      "--hide-scrollbars --user-data-dir='" +
      (dir / "profile").string() + "' --screenshot='" + png.string() +
      "' --window-size=1200,5000 --dump-dom 'file://" + page.string() + "' > '" +
      (dir / (name + ".dom")).string() + "' 2> '" + (dir / "chromium.log").string() + "'";
  EXPECT_EQ(std::system(command.c_str()), 0) << readText(dir / "chromium.log");
  if (!fs::exists(png)) {
    ADD_FAILURE() << "no screenshot: " << readText(dir / "chromium.log");
    return {};
  }
  return {io::readPng(png.string()), readText(dir / (name + ".dom"))};
}

TEST(RunReport, RendersInHeadlessChromium) {
  ASSERT_TRUE(haveChromium()) << "chromium is not installed (scripts/setup installs it)";
  const fs::path dir = fs::temp_directory_path() / ("dcl_run_report_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const RunSummary run = hostileNames();
  const std::string html = reportHtml(run, evaluateRun(run));
  const Rendered plain = render(dir, "report", html);
  ASSERT_FALSE(plain.page.empty());
  EXPECT_EQ(plain.page.width(), 1200);
  EXPECT_EQ(plain.page.height(), 5000);
  // A blank page has none; the plots colour thousands.
  EXPECT_GT(colouredPixels(plain.page), 5000u);
  EXPECT_EQ(count(plain.dom, "<svg "), 3u);
  EXPECT_EQ(count(plain.dom, "<polyline "), count(html, "<polyline "));
  EXPECT_EQ(count(plain.dom, "<rect "), count(html, "<rect "));
  EXPECT_EQ(plain.dom.find("<script"), std::string::npos);
  EXPECT_NE(plain.dom.find("&lt;script&gt;alert(\"x\")&lt;/script&gt;"), std::string::npos);

  // With the merged map: its picture shows, each robot's points in its colour
  // (many more pixels of it than its lines alone colour).
  const RunSummary mapped = withMap(run);
  const Rendered with_map = render(dir, "report_map", reportHtml(mapped, evaluateRun(mapped)));
  ASSERT_FALSE(with_map.page.empty());
  EXPECT_EQ(count(with_map.dom, "<svg "), 4u);
  EXPECT_EQ(count(with_map.dom, "<image class=\"map\""), 1u);
  for (std::size_t r = 0; r < kRobots; ++r) {
    const std::size_t before = pixelsOf(plain.page, core::robotColour(r), 40);
    const std::size_t after = pixelsOf(with_map.page, core::robotColour(r), 40);
    EXPECT_GT(after, before + 1500) << "robot " << r << ": the map picture is empty";
  }
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace dcl::eval
