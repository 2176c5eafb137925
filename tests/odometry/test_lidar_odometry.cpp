// The LiDAR odometry pipeline: real KITTI 00 frames, a simulated VLP-16 run
// with motion distortion, and bad input.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <dcl/core/se3.hpp>
#include <dcl/core/trajectory.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/odometry/lidar_odometry.hpp>
#include <dcl/odometry/local_mapper.hpp>
#include <dcl/odometry/preprocessing.hpp>
#include <dcl/sim/presets.hpp>
#include <dcl/sim/routes.hpp>
#include <dcl/sim/sim_source.hpp>

#include "odometry_test_data.hpp"

namespace dcl::odometry {
namespace {

using test::poseError;

// --- Real scans -------------------------------------------------------------

TEST(LidarOdometryKitti, Frames0To5) {
  // The target is 10 cm at frame 5. These six scans disagree with the
  // ground truth: registering scan 5 straight onto scan 0, starting *at* the
  // ground truth, point-to-plane and point-to-point both settle at 3.59 m of
  // forward motion (ground truth 4.29 m) with residuals that pull backwards
  // uniformly in every direction around the car, and KISS-ICP finds the same
  // 3.58 m. Frames 94-95 and 198-199 match the ground truth to 1-3 cm. So this
  // test checks that the odometry agrees with direct registration over the
  // stretch, and records the ground-truth error (about 0.75 m, KISS-ICP 0.72 m).
  LidarOdometry odometry;
  OdometryResult result;
  for (int frame = 0; frame <= 5; ++frame) {
    result = odometry.process(0.1 * frame, test::kittiScan(frame));
    EXPECT_TRUE(result.health.accepted) << "frame " << frame << ": " << result.health.problem;
    EXPECT_FALSE(result.health.degenerate) << "frame " << frame;
  }
  const auto error = poseError(result.T_odom_sensor, test::kittiMotion(0, 5));
  RecordProperty("ground_truth_error_m", std::to_string(error.translation));
  std::printf("frames 0..5: %.3f m, %.3f deg from ground truth; travelled %.3f m (truth %.3f m)\n",
              error.translation, error.rotation_deg, result.T_odom_sensor.translation().norm(),
              test::kittiMotion(0, 5).translation().norm());
  // Direct registration of scan 5 onto scan 0 from the odometry's answer.
  const double voxel = odometry.config().mapVoxelSize();
  VoxelHashMap map(voxel, 20);
  map.addPoints(
      voxelDownsample(toPoints(cleanScan(test::kittiScan(0), 2.0, 100.0).cloud), 0.5 * voxel));
  IcpConfig icp;
  icp.max_correspondence_distance = 1.0;
  icp.kernel_scale = 0.3;
  const auto direct = registerScan(
      voxelDownsample(toPoints(cleanScan(test::kittiScan(5), 2.0, 100.0).cloud), 1.5 * voxel), map,
      test::kittiMotion(0, 5), icp);
  const auto disagreement = poseError(result.T_odom_sensor, direct.T_target_source);
  EXPECT_LT(disagreement.translation, 0.05);
  EXPECT_LT(disagreement.rotation_deg, 0.1);
}

// --- Simulated scans --------------------------------------------------------

/// The odometry's error from frame `from` to frame `to` of robot `robot`,
/// tracked from frame `first` with `config`; `sharp` collects the frames
/// whose motion changed sharply (their own twist estimated).
test::PoseError trackedMotionError(const sim::SimWorld& world, std::size_t robot, std::size_t first,
                                   std::size_t from, std::size_t to,
                                   std::vector<std::size_t>* sharp,
                                   const OdometryConfig& config = {}) {
  LidarOdometry odometry(config);
  const core::Trajectory& truth = world.groundTruth(robot);
  std::vector<Eigen::Isometry3d> poses;
  for (std::size_t i = first; i <= to; ++i) {
    const auto result = odometry.process(truth.stamp(i), world.scan(robot, i));
    EXPECT_TRUE(result.health.accepted) << "frame " << i << ": " << result.health.problem;
    if (result.health.sharp_motion && sharp) sharp->push_back(i);
    poses.push_back(result.T_odom_sensor);
  }
  const Eigen::Isometry3d estimate = poses[from - first].inverse() * poses[to - first];
  return poseError(estimate, truth.pose(from).inverse() * truth.pose(to));
}

/// Campus-3 robot a (VLP-16), scans regenerated with motion distortion.
class SimulatedCampus : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto folder = std::filesystem::temp_directory_path() /
                        ("dcl_odometry_test_" + std::to_string(::getpid()));
    sim::PresetOptions options;
    options.data_dir = test::dataDir();
    // Perfect lasers: these tests look at the front-end's handling of motion
    // (deskewing, starts, turns); a unit's calibration error drifts it by as
    // much over these few metres, either way.
    const auto spec = sim::writeSimDataset(folder.string(), sim::makePreset("campus-3", options),
                                           {.calibration_error = false});
    world_ = new sim::SimWorld(spec);
    std::filesystem::remove_all(folder);
  }
  static void TearDownTestSuite() {
    delete world_;
    world_ = nullptr;
  }

  /// The odometry's poses over frames [first, last] of robot `robot` (T_odom_sensor,
  /// the odometry frame being the sensor at `first`); every frame must be accepted.
  static std::vector<Eigen::Isometry3d> track(const OdometryConfig& config, std::size_t robot,
                                              std::size_t first, std::size_t last) {
    LidarOdometry odometry(config);
    const core::Trajectory& truth = world_->groundTruth(robot);
    std::vector<Eigen::Isometry3d> poses;
    for (std::size_t i = first; i <= last; ++i) {
      const auto result = odometry.process(truth.stamp(i), world_->scan(robot, i));
      EXPECT_TRUE(result.health.accepted) << "frame " << i << ": " << result.health.problem;
      poses.push_back(result.T_odom_sensor);
    }
    return poses;
  }

  /// The translation error (m) of the estimated motion from frame `from` to frame
  /// `to` of a run `poses` that started at frame `first`.
  static double motionError(const std::vector<Eigen::Isometry3d>& poses, std::size_t robot,
                            std::size_t first, std::size_t from, std::size_t to) {
    const core::Trajectory& truth = world_->groundTruth(robot);
    const Eigen::Isometry3d estimate = poses[from - first].inverse() * poses[to - first];
    return poseError(estimate, truth.pose(from).inverse() * truth.pose(to)).translation;
  }

  static inline sim::SimWorld* world_ = nullptr;
};

TEST_F(SimulatedCampus, DeskewingKeepsDriftSmallWhileTurning) {
  // Robot a starts from rest and turns at up to 11 deg/s until frame 60, so a
  // sweep smears by a degree (50 cm at 30 m). The drift is measured over frames
  // 10-64, once the robot moves: the first registrations, against a one-sweep
  // map, carry a few centimetres of error either way that would mask the turn.
  constexpr std::size_t kRobot = 0, kFirst = 0, kFrom = 10, kTo = 64;
  OdometryConfig config;
  const double with_deskew =
      motionError(track(config, kRobot, kFirst, kTo), kRobot, kFirst, kFrom, kTo);
  config.deskew = false;
  const double without_deskew =
      motionError(track(config, kRobot, kFirst, kTo), kRobot, kFirst, kFrom, kTo);
  std::printf("drift over frames %zu-%zu (7 m, 34 deg of turn): %.3f m deskewed, %.3f m not\n",
              kFrom, kTo, with_deskew, without_deskew);
  EXPECT_LT(with_deskew, 0.03);
  EXPECT_LT(with_deskew, 0.5 * without_deskew);
}

TEST_F(SimulatedCampus, TracksTheFirstTurnAfterAStandstillAndAStraight) {
  // Robot c stands until frame 277, drives straight along x, and at frame 542
  // turns at 11 deg/s from one frame to the next. The straight stretch shrinks
  // the adaptive threshold to its floor; a correspondence gate below the map's
  // point spacing then kept too few pairs at the unpredicted turn, and the
  // estimate stopped at the corner for good (7 m off by frame 600).
  constexpr std::size_t kRobot = 2, kFirst = 265, kLast = 600;
  const auto poses = track(OdometryConfig{}, kRobot, kFirst, kLast);
  const double error = motionError(poses, kRobot, kFirst, kFirst, kLast);
  std::printf("error after the corner (frames %zu-%zu, 48 m): %.3f m\n", kFirst, kLast, error);
  EXPECT_LT(error, 0.25);
}

TEST_F(SimulatedCampus, EstimatesASweepsOwnMotionWhenATurnStartsAbruptly) {
  // Robot c's turn at frame 542 starts from one frame to the next: that sweep
  // was deskewed as if it went straight, 0.5 deg short of the turn at its
  // ends. The registered motion tells, and that sweep has its own twist
  // estimated; the steady straight before it keeps the last velocity.
  constexpr std::size_t kRobot = 2, kFirst = 265, kFrom = 535, kTo = 560;
  std::vector<std::size_t> sharp;
  const test::PoseError error = trackedMotionError(*world_, kRobot, kFirst, kFrom, kTo, &sharp);
  std::printf(
      "turn onset (frames %zu-%zu): own twist at %zu frames (first %zu): %.4f m, %.4f deg\n", kFrom,
      kTo, sharp.size(), sharp.empty() ? 0 : sharp.front(), error.translation, error.rotation_deg);
  ASSERT_FALSE(sharp.empty());
  EXPECT_GE(sharp.front(), 540u);  // the steady straight before it needs no twist of its own
  EXPECT_LE(sharp.front(), 544u);
  EXPECT_LT(sharp.size(), 10u);
  // A gentle turn, 5 m: the sweep is bent by millimetres, and the heading
  // holds to a fifth of what a sweep deskewed as if straight loses (0.05 deg
  // among the crowns' scattered returns, 0.02 deg with solid crowns).
  EXPECT_LT(error.translation, 0.02);
  EXPECT_LT(error.rotation_deg, 0.1);
}

TEST_F(SimulatedCampus, AStandingRobotStaysPutAndStartsCleanly) {
  // Robot c stands until frame 277, robot a starts from rest. Before any motion
  // the correspondence gate is KISS-ICP's initial guess of metres; against a map
  // of one sparse VLP-16 sweep its far pairs pulled the first poses 3-6 cm off,
  // mostly upwards, and the offset stayed in every later pose (5.5 cm while
  // standing, 6.1 cm over the first 2 m; now 1.0 and 3.0 cm).
  const auto standing = track(OdometryConfig{}, 2, 0, 30);
  double worst = 0.0;
  for (const Eigen::Isometry3d& T : standing) worst = std::max(worst, T.translation().norm());
  const double start = motionError(track(OdometryConfig{}, 0, 0, 25), 0, 0, 0, 25);
  std::printf("standing: %.4f m at most; starting (frames 0-25): %.4f m\n", worst, start);
  EXPECT_LT(worst, 0.02);
  EXPECT_LT(start, 0.04);
}

/// A car at 5-6 m/s on a grid of 120 m blocks in the city (HDL-64 at 1.73
/// m): its corners, arcs of 8 m, swing the heading by 90 deg at 36-43 deg/s,
/// from one frame to the next, after straights of a hundred metres.
std::unique_ptr<sim::SimWorld> fastCornerWorld(const std::filesystem::path& folder,
                                               std::uint64_t seed) {
  sim::CampusRouteConfig routes;
  routes.block_pitch = 120.0;
  routes.u_route_share = 1.0;
  routes.min_speed = 5.0;
  routes.max_speed = 6.0;
  routes.acceleration = 2.0;
  sim::Preset preset;
  preset.name = "fast-corner";
  preset.world = "city";
  preset.sensor = "hdl64";
  preset.routes = sim::campusRoutes(1, seed, routes);
  preset.seed = seed;
  auto world = std::make_unique<sim::SimWorld>(sim::writeSimDataset(folder.string(), preset));
  std::filesystem::remove_all(folder);
  return world;
}

/// The first frame of `truth` that turns faster than `deg_per_s`.
std::size_t firstFastTurn(const core::Trajectory& truth, double deg_per_s) {
  for (std::size_t i = 1; i < truth.size(); ++i) {
    const double turned = core::rad2deg(
        core::rotationAngle((truth.pose(i - 1).inverse() * truth.pose(i)).rotation()));
    if (turned > deg_per_s * (truth.stamp(i) - truth.stamp(i - 1))) return i;
  }
  return truth.size();
}

class SimulatedFastCorner : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(SimulatedFastCorner, TracksACornerTheCarSwingsIntoAfterAStraight) {
  // A hundred metres of straight shrink the correspondence gate to
  // decimetres; the corner's first sweep then moves the far points metres
  // beyond it. The fit kept the near points, turned part of the way, and the
  // next prediction started from there: worlds 1 and 3 ended 2.9 and 2.2 m,
  // 10.9 and 9.5 deg off over these 45 frames. A frame that pairs far fewer
  // points than the frames before is fitted again, coarse to fine from the
  // wide first gate. World 3 still lost 1.8 deg in the turn's second sweep:
  // deskewed with the straight's velocity, bent by 1.8 deg at its ends, and
  // its own twist, fitted from the bent fit's pose with the straight's
  // narrow gate, fitted worse than the bent sweep. Such a sweep is now
  // deskewed with the motion its rigid fit measured and fitted again coarse
  // to fine before its own twist is: 0.1 deg in every world.
  const std::uint64_t seed = GetParam();
  const std::unique_ptr<sim::SimWorld> world = fastCornerWorld(
      std::filesystem::temp_directory_path() /
          ("dcl_odometry_corner_" + std::to_string(::getpid()) + "_" + std::to_string(seed)),
      seed);
  const std::size_t corner = firstFastTurn(world->groundTruth(0), 30.0);
  ASSERT_GT(corner, 100u);
  ASSERT_LT(corner + 40, world->groundTruth(0).size());
  const test::PoseError error =
      trackedMotionError(*world, 0, corner - 80, corner - 5, corner + 40, nullptr);
  std::printf("seed %llu: the corner at frame %zu (frames %zu-%zu): %.3f m, %.3f deg\n",
              static_cast<unsigned long long>(seed), corner, corner - 5, corner + 40,
              error.translation, error.rotation_deg);
  EXPECT_LT(error.translation, 0.3);
  EXPECT_LT(error.rotation_deg, 0.5);
}

INSTANTIATE_TEST_SUITE_P(Worlds, SimulatedFastCorner, ::testing::Values(1u, 2u, 3u));

/// The median distance from a few hundred of `cloud`'s points to the nearest
/// of `reference`'s (brute force: a test's sizes).
double medianNearest(const core::PointCloud& cloud, const std::vector<Eigen::Vector3f>& reference) {
  std::vector<double> nearest;
  const std::size_t step = std::max<std::size_t>(1, cloud.size() / 400);
  for (std::size_t i = 0; i < cloud.size(); i += step) {
    float best = std::numeric_limits<float>::infinity();
    for (const Eigen::Vector3f& q : reference)
      best = std::min(best, (cloud.points[i] - q).squaredNorm());
    nearest.push_back(std::sqrt(static_cast<double>(best)));
  }
  std::nth_element(nearest.begin(),
                   nearest.begin() + static_cast<std::ptrdiff_t>(nearest.size() / 2),
                   nearest.end());
  return nearest[nearest.size() / 2];
}

TEST(SimulatedFastStart, TheFirstFrameIsDeskewedAgainOnceTheVelocityIsKnown) {
  // A robot whose odometry starts at speed (5-6 m/s, the straight before the
  // fast corner): its first sweep has no velocity to be deskewed with, and
  // went out smeared by half a metre along the road. Its cloud became the
  // route's first keyframe, and loops to it (where a teammate's route hands
  // over to this one's) were decimetres off. The next frame measures the
  // velocity and gives the first frame's cloud again, deskewed with it.
  const std::unique_ptr<sim::SimWorld> world =
      fastCornerWorld(std::filesystem::temp_directory_path() /
                          ("dcl_odometry_fast_start_" + std::to_string(::getpid())),
                      2);
  const core::Trajectory& truth = world->groundTruth(0);
  const std::size_t first = firstFastTurn(truth, 30.0) - 80;
  const core::PointCloud scan = world->scan(0, first);
  ASSERT_TRUE(scan.hasTime());
  // The sweep as it was: each point where the sensor was at the stamp.
  const double stamp = truth.stamp(first);
  const Eigen::Isometry3d T_world_stamp = truth.pose(first);
  std::vector<Eigen::Vector3f> exact;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const auto T_world_firing = truth.at(stamp + scan.time[i]);
    ASSERT_TRUE(T_world_firing.has_value());
    exact.push_back(
        (T_world_stamp.inverse() * *T_world_firing * scan.points[i].cast<double>()).cast<float>());
  }
  LidarOdometry odometry;
  const OdometryResult at_first = odometry.process(stamp, scan);
  ASSERT_TRUE(at_first.health.accepted);
  EXPECT_FALSE(at_first.first_frame_redone.has_value());
  const OdometryResult at_second =
      odometry.process(truth.stamp(first + 1), world->scan(0, first + 1));
  ASSERT_TRUE(at_second.health.accepted);
  ASSERT_TRUE(at_second.first_frame_redone.has_value());
  EXPECT_EQ(at_second.first_frame_redone->stamp, stamp);
  const double smeared = medianNearest(at_first.registered, exact);
  const double redone = medianNearest(at_second.first_frame_redone->registered, exact);
  std::printf(
      "the first frame's cloud against the sweep as it was: %.3f m undeskewed, %.3f m "
      "deskewed again\n",
      smeared, redone);
  EXPECT_LT(redone, 0.5 * smeared);
  // The route's first keyframe keeps the cloud deskewed again.
  LocalMapper mapper(core::RobotId(0));
  (void)mapper.process(at_first);
  (void)mapper.process(at_second);
  const core::PointCloud kept =
      KeyframeSelector(core::RobotId(0)).keyframeCloud(at_second.first_frame_redone->registered);
  EXPECT_EQ(mapper.keyframes().front().cloud.points, kept.points);
  const OdometryResult at_third =
      odometry.process(truth.stamp(first + 2), world->scan(0, first + 2));
  EXPECT_FALSE(at_third.first_frame_redone.has_value());
}

/// One way to run KITTI 00's braking turn: a world, a nudge of the route,
/// a thread count. The test's bound must hold for every one of them.
struct TurnVariant {
  std::string name;
  std::uint64_t seed = 1;   ///< the simulated world (city, route noise, LiDAR unit)
  bool jitter = false;      ///< robot b's whole route moved by 1 mm and 0.01 deg
  std::size_t threads = 2;  ///< the odometry's TBB threads
};

void PrintTo(const TurnVariant& variant, std::ostream* os) {
  *os << variant.name;
}

class SimulatedKittiTurn : public ::testing::TestWithParam<TurnVariant> {};

TEST_P(SimulatedKittiTurn, TracksTheCarBrakingIntoATurn) {
  // KITTI 00 at 134 s (robot b, frames 1280-1320): the car brakes from 7 to 5
  // m/s and turns at up to 41 deg/s. Its ground truth, which the simulator
  // drives, changes the yaw rate from 11 to 34 deg/s and the speed by 2.6 m/s
  // from one frame to the next: a sweep deskewed with the last velocity is
  // bent by a degree at its ends. Such a sweep gets a twist of its own, but
  // one sweep's bend pins its twist only weakly: the estimate stayed near its
  // prior, the last velocity (14-16 deg/s for two sweeps where the car turned
  // at 34-37), and the next sweep, deskewed with that, was fitted 1.2 deg
  // off. Which sweeps it happened on depended on the last bits of the scans,
  // so the turn was lost on some machines and tracked on others. The sweep
  // is now deskewed with the motion its rigid fit measured, fitted again
  // coarse to fine, and its twist's prior is that motion. The bound holds
  // for every world, nudge and thread count here, and held for the scans of
  // both ray casters (before and after their bits were made the same
  // everywhere): 0.21 deg at most over 13 variants.
  const TurnVariant& variant = GetParam();
  const auto folder = std::filesystem::temp_directory_path() /
                      ("dcl_odometry_turn_" + std::to_string(::getpid()) + "_" + variant.name);
  sim::PresetOptions options;
  options.data_dir = test::dataDir();
  options.seed = variant.seed;
  io::DatasetSpec spec =
      sim::writeSimDataset(folder.string(), sim::makePreset("kitti00-3", options));
  constexpr std::size_t kRobot = 1;
  if (variant.jitter) {
    const std::string path = (folder / spec.robots[kRobot].ground_truth).string();
    core::Trajectory route = io::readTumPoses(path);
    route.transformWorld(
        core::expSE3((core::Vector6d() << 1e-3, 0, 0, 0, 0, core::deg2rad(0.01)).finished()));
    io::writeTumPoses(path, route);
  }
  const sim::SimWorld world(spec);
  std::filesystem::remove_all(folder);
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, variant.threads);
  constexpr std::size_t kFirst = 1200, kFrom = 1280, kTo = 1320;
  std::vector<std::size_t> sharp;
  const test::PoseError error = trackedMotionError(world, kRobot, kFirst, kFrom, kTo, &sharp);
  std::printf(
      "%s: braking into the turn (frames %zu-%zu): %.3f m, %.3f deg; %zu sweeps with "
      "their own twist\n",
      variant.name.c_str(), kFrom, kTo, error.translation, error.rotation_deg, sharp.size());
  EXPECT_LT(error.translation, 0.3);
  EXPECT_LT(error.rotation_deg, 0.5);
  EXPECT_LT(sharp.size(), 20u);  // of 121 frames: only where the motion changed
}

INSTANTIATE_TEST_SUITE_P(Perturbed, SimulatedKittiTurn,
                         ::testing::Values(TurnVariant{"seed1", 1, false, 2},
                                           TurnVariant{"seed1_one_thread", 1, false, 1},
                                           TurnVariant{"seed1_jittered", 1, true, 2},
                                           TurnVariant{"seed2", 2, false, 2},
                                           TurnVariant{"seed3", 3, false, 2},
                                           TurnVariant{"seed4_jittered_one_thread", 4, true, 1}),
                         [](const ::testing::TestParamInfo<TurnVariant>& info) {
                           return info.param.name;
                         });

/// One world in which KITTI's car drives with its IMU: a seed and a thread count.
struct LevelVariant {
  std::string name;
  std::uint64_t seed = 1;   ///< the simulated world (city, traffic, LiDAR and IMU units)
  std::size_t threads = 2;  ///< the odometry's TBB threads
};

void PrintTo(const LevelVariant& variant, std::ostream* os) {
  *os << variant.name;
}

class SimulatedKittiLevel : public ::testing::TestWithParam<LevelVariant> {};

/// The largest angle (deg) between the estimated and the true up over the
/// first `frames` frames of robot 0 of `world`, the odometry levelled with
/// the robot's IMU readings.
double largestLean(const sim::SimWorld& world, std::size_t frames) {
  LidarOdometry odometry;
  const core::Trajectory& truth = world.groundTruth(0);
  double largest = 0.0;
  for (std::size_t i = 0; i < frames; ++i) {
    const std::optional<Eigen::Vector3d> up = world.up(0, i);
    EXPECT_TRUE(up.has_value());
    if (up) odometry.observeUp(*up);
    const auto result = odometry.process(truth.stamp(i), world.scan(0, i));
    EXPECT_TRUE(result.health.accepted) << "frame " << i << ": " << result.health.problem;
    const Eigen::Vector3d z = truth.pose(0).rotation() * result.T_odom_sensor.rotation().col(2);
    const Eigen::Vector3d true_z = truth.pose(i).rotation().col(2);
    largest = std::max(largest, core::rad2deg(std::atan2(z.cross(true_z).norm(), z.dot(true_z))));
  }
  return largest;
}

TEST_P(SimulatedKittiLevel, TheImuKeepsRollAndPitchFromDriftingAlongTheRoute) {
  // KITTI 05's first 300 frames (robot a of kitti05-3, 210 m among traffic).
  // Every laser of KITTI's HDL-64E points 0.2 deg high (the simulated unit
  // too): the road ahead reads as a shallow cone, and registration alone
  // lets roll and pitch drift, and the height with them (0.004 deg/m over
  // whole sequences, BENCHMARKS.md): by 0.72-0.97 deg over these frames in
  // seeds 1-3. The IMU's reading of up does not drift: levelled with it, the
  // pose stays within its unit's tilt and noise (0.03 and 0.02 deg a axis)
  // and the filter's lag, 0.14-0.16 deg at worst in the same worlds.
  const LevelVariant& variant = GetParam();
  const auto folder = std::filesystem::temp_directory_path() /
                      ("dcl_odometry_level_" + std::to_string(::getpid()) + "_" + variant.name);
  sim::PresetOptions options;
  options.data_dir = test::dataDir();
  options.seed = variant.seed;
  sim::Preset preset = sim::makePreset("kitti05-3", options);
  constexpr std::size_t kFrames = 300;
  preset.routes.resize(1);
  const core::Trajectory& full = preset.routes[0].T_world_sensor;
  ASSERT_GT(full.size(), kFrames);
  preset.routes[0].T_world_sensor =
      core::Trajectory({full.stamps().begin(), full.stamps().begin() + kFrames},
                       {full.poses().begin(), full.poses().begin() + kFrames});
  const io::DatasetSpec spec = sim::writeSimDataset(folder.string(), preset, {.traffic = 1.0});
  ASSERT_TRUE(spec.sim->imu);
  const sim::SimWorld world(spec);
  std::filesystem::remove_all(folder);
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, variant.threads);
  const double levelled = largestLean(world, kFrames);
  std::printf("%s: largest error of up over %zu frames, levelled: %.4f deg\n", variant.name.c_str(),
              kFrames, levelled);
  EXPECT_LT(levelled, 0.25);
}

INSTANTIATE_TEST_SUITE_P(Perturbed, SimulatedKittiLevel,
                         ::testing::Values(LevelVariant{"seed1", 1, 2},
                                           LevelVariant{"seed2_one_thread", 2, 1}),
                         [](const ::testing::TestParamInfo<LevelVariant>& info) {
                           return info.param.name;
                         });

// --- Bad input --------------------------------------------------------------

/// A room (floor, walls, ceiling, two pillars) seen from (x, 0, 0).
core::PointCloud roomScan(double x) {
  core::PointCloud scan;
  const auto add = [&](double px, double py, double pz) {
    scan.points.emplace_back(static_cast<float>(px - x), static_cast<float>(py),
                             static_cast<float>(pz));
  };
  for (double a = -15.0; a <= 15.0; a += 0.2) {
    for (double b = -2.0; b <= 4.0; b += 0.2) {
      add(a, 12.0, b);
      add(a, -9.0, b);
      add(15.0, a, b);
      add(-15.0, a, b);
    }
    for (double b = -12.0; b <= 12.0; b += 0.4) add(a, b, -2.0);
  }
  for (double z = -2.0; z <= 4.0; z += 0.2) {
    for (double t = 0.0; t < 2.0 * M_PI; t += 0.2) {
      add(4.0 + 0.5 * std::cos(t), 3.0 + 0.5 * std::sin(t), z);
      add(-6.0 + 0.5 * std::cos(t), -4.0 + 0.5 * std::sin(t), z);
    }
  }
  return scan;
}

/// An odometry after three good frames at 1 m/s along x.
LidarOdometry warmedUp() {
  LidarOdometry odometry;
  for (int i = 0; i < 3; ++i) odometry.process(0.1 * i, roomScan(0.1 * i));
  return odometry;
}

// --- Levelling with the IMU -------------------------------------------------

/// The angle (deg) by which the pose's z axis leans from the odometry frame's.
double leanDeg(const Eigen::Isometry3d& pose) {
  const Eigen::Vector3d z = pose.rotation().col(2);
  return core::rad2deg(std::atan2(z.head<2>().norm(), z.z()));
}

/// The pose's heading (deg): its x axis about the odometry frame's z.
double headingDeg(const Eigen::Isometry3d& pose) {
  const Eigen::Matrix3d R = pose.rotation();
  return core::rad2deg(std::atan2(R(1, 0), R(0, 0)));
}

/// The IMU's reading of up for a sensor rolled by `roll_deg` about its x axis.
Eigen::Vector3d upWhenRolled(double roll_deg) {
  return Eigen::AngleAxisd(core::deg2rad(roll_deg), Eigen::Vector3d::UnitX()).inverse() *
         Eigen::Vector3d::UnitZ();
}

/// An odometry that saw the level room four times at 1 m/s along x, each
/// scan with the IMU reading straight up.
LidarOdometry levelInTheRoom(const OdometryConfig& config) {
  LidarOdometry odometry(config);
  for (int i = 0; i < 4; ++i) {
    odometry.observeUp(Eigen::Vector3d::UnitZ());
    EXPECT_TRUE(odometry.process(0.1 * i, roomScan(0.1 * i)).health.accepted);
  }
  return odometry;
}

TEST(LidarOdometryImu, TurnsRollAndPitchTowardTheReadingButNotTheHeading) {
  OdometryConfig config;
  config.imu_time_constant = 0.3;  // s
  LidarOdometry odometry = levelInTheRoom(config);
  EXPECT_LT(leanDeg(odometry.pose()), 0.01);
  const double heading = headingDeg(odometry.pose());
  // The room stays level, and registration says so; the IMU now reads a
  // sensor rolled by 1 deg. After registration the pose turns toward the
  // reading by the share 1 - exp(-0.1 s / 0.3 s) = 28 %, about a horizontal axis.
  odometry.observeUp(upWhenRolled(1.0));
  const auto result = odometry.process(0.4, roomScan(0.4));
  ASSERT_TRUE(result.health.accepted);
  EXPECT_NEAR(leanDeg(result.T_odom_sensor), 1.0 - std::exp(-0.1 / 0.3), 0.02);
  EXPECT_NEAR(result.T_odom_sensor.rotation().col(2).y(), -std::sin(core::deg2rad(0.2835)), 2e-4);
  EXPECT_NEAR(headingDeg(result.T_odom_sensor), heading, 1e-3);
  EXPECT_NEAR(result.T_odom_sensor.translation().x(), 0.4, 0.01);  // turned about the sensor
  // A levelled frame's roll and pitch are as good as two readings, not as registration's floor.
  const double imu_floor = config.imu_tilt_sigma * config.imu_tilt_sigma;
  for (const int axis : {3, 4}) {
    EXPECT_GE(result.covariance(axis, axis), imu_floor);
    EXPECT_LT(result.covariance(axis, axis),
              0.5 * config.min_rotation_sigma * config.min_rotation_sigma);
  }
  // A scan without a reading keeps what registration finds: the room pulls it back level.
  const auto next = odometry.process(0.5, roomScan(0.5));
  EXPECT_LT(leanDeg(next.T_odom_sensor), 0.1);
}

TEST(LidarOdometryImu, IgnoresTheReadingsWhenToldToAndReadingsThatSayNothing) {
  OdometryConfig lidar_only;
  lidar_only.use_imu = false;
  LidarOdometry odometry = levelInTheRoom(lidar_only);
  odometry.observeUp(upWhenRolled(1.0));
  const auto unlevelled = odometry.process(0.4, roomScan(0.4));
  EXPECT_LT(leanDeg(unlevelled.T_odom_sensor), 0.01);
  EXPECT_GE(unlevelled.covariance(3, 3),
            lidar_only.min_rotation_sigma * lidar_only.min_rotation_sigma);

  LidarOdometry levelled = levelInTheRoom({});
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const Eigen::Vector3d& nothing :
       std::vector<Eigen::Vector3d>{Eigen::Vector3d(nan, 0.0, 1.0), Eigen::Vector3d::Zero(),
                                    Eigen::Vector3d(1e-9, 0.0, 0.0)}) {
    levelled.observeUp(nothing);
  }
  const auto result = levelled.process(0.4, roomScan(0.4));
  EXPECT_TRUE(result.health.accepted);
  EXPECT_TRUE(result.T_odom_sensor.matrix().allFinite());
  EXPECT_LT(leanDeg(result.T_odom_sensor), 0.01);
}

TEST(LidarOdometryInput, TracksASimpleRoom) {
  LidarOdometry odometry = warmedUp();
  const auto result = odometry.process(0.3, roomScan(0.3));
  EXPECT_TRUE(result.health.accepted);
  EXPECT_TRUE(result.health.converged);
  EXPECT_FALSE(result.health.degenerate);
  EXPECT_TRUE(result.health.problem.empty()) << result.health.problem;
  EXPECT_NEAR(result.T_odom_sensor.translation().x(), 0.3, 0.01);
  EXPECT_GT(result.health.correspondences, 100u);
  EXPECT_FALSE(result.registered.empty());
  EXPECT_TRUE(result.covariance.allFinite());
  EXPECT_GT(result.covariance.llt().matrixL().determinant(), 0.0);  // positive definite
  EXPECT_EQ(odometry.name(), "lidar");
}

TEST(LidarOdometryInput, EmptyScanIsSkippedAndThePosePredicted) {
  LidarOdometry odometry = warmedUp();
  const auto skipped = odometry.process(0.3, core::PointCloud{});
  EXPECT_FALSE(skipped.health.accepted);
  EXPECT_NE(skipped.health.problem.find("too few usable points"), std::string::npos);
  EXPECT_NEAR(skipped.T_odom_sensor.translation().x(), 0.3, 0.02);  // constant velocity
  EXPECT_NEAR(odometry.pose().translation().x(), 0.2, 0.01);        // state untouched
  const auto next = odometry.process(0.4, roomScan(0.4));
  EXPECT_TRUE(next.health.accepted);
  EXPECT_NEAR(next.T_odom_sensor.translation().x(), 0.4, 0.01);
}

TEST(LidarOdometryInput, NonFinitePointsAreDroppedAndReported) {
  LidarOdometry odometry = warmedUp();
  auto scan = roomScan(0.3);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  for (std::size_t i = 0; i < scan.size(); i += 10) scan.points[i] = {nan, inf, -inf};
  const auto result = odometry.process(0.3, scan);
  EXPECT_TRUE(result.health.accepted);
  EXPECT_NE(result.health.problem.find("non-finite"), std::string::npos);
  EXPECT_TRUE(result.T_odom_sensor.matrix().allFinite());
  EXPECT_NEAR(result.T_odom_sensor.translation().x(), 0.3, 0.01);
}

TEST(LidarOdometryInput, TimeGoingBackwardsIsSkippedAndThePoseHeld) {
  LidarOdometry odometry = warmedUp();
  const Eigen::Isometry3d before = odometry.pose();
  for (const double stamp : {0.15, 0.2, std::numeric_limits<double>::quiet_NaN()}) {
    const auto result = odometry.process(stamp, roomScan(0.3));
    EXPECT_FALSE(result.health.accepted) << stamp;
    EXPECT_FALSE(result.health.problem.empty());
    EXPECT_TRUE(result.T_odom_sensor.isApprox(before));
  }
  EXPECT_TRUE(odometry.pose().isApprox(before));
  EXPECT_TRUE(odometry.process(0.3, roomScan(0.3)).health.accepted);
}

TEST(LidarOdometryInput, ASingleplaneIsFlaggedDegenerate) {
  const auto plane = [](double x) {
    core::PointCloud scan;
    for (double a = -30.0; a <= 30.0; a += 0.3) {
      for (double b = -30.0; b <= 30.0; b += 0.3) {
        scan.points.emplace_back(static_cast<float>(a - x), static_cast<float>(b), -1.7f);
      }
    }
    return scan;
  };
  LidarOdometry odometry;
  odometry.process(0.0, plane(0.0));
  const auto result = odometry.process(0.1, plane(0.1));
  EXPECT_TRUE(result.health.degenerate);
  EXPECT_NE(result.health.problem.find("degenerate"), std::string::npos);
  EXPECT_TRUE(result.T_odom_sensor.matrix().allFinite());
  // Unobservable directions get a large covariance, not a confident one.
  EXPECT_GT(result.covariance(0, 0), 1.0);
}

}  // namespace
}  // namespace dcl::odometry

namespace dcl::odometry {
namespace {

/// A street 20 m wide between two long building walls, with a car parked
/// 8 m ahead of a sensor that creeps forward at 1 m/s; at t = 1 s the car
/// drives off ahead at 10 m/s (and is gone from view by t = 3 s).
struct LeavingCar {
  sim::World world;
  sim::Traffic traffic;
  core::Trajectory sensor;

  LeavingCar() {
    const auto v = [&](float x, float y, float z) { return world.addVertex({x, y, z}); };
    world.addQuad(v(-50, -30, 0), v(250, -30, 0), v(250, 30, 0), v(-50, 30, 0), sim::Surface::road);
    world.addBox(core::makePose2d(100, 11, 0), {300, 2, 12}, sim::Surface::building);
    world.addBox(core::makePose2d(100, -11, 0), {300, 2, 12}, sim::Surface::building);
    for (int i = 0; i < 9; ++i) {  // a pole every 12 m on each side: things to register on
      world.addCylinder({6.0 + 12.0 * i, 7.5, 0}, 0.2, 5, 8, sim::Surface::pole);
      world.addCylinder({12.0 + 12.0 * i, -7.5, 0}, 0.2, 5, 8, sim::Surface::pole);
    }
    sim::Actor car;
    car.kind = sim::ActorKind::car;
    car.surface = sim::Surface::vehicle;
    car.boxes = {{{0.f, 0.f, 0.8f}, {2.2f, 0.9f, 0.7f}}};
    car.radius = 2.4f;
    car.step = 0.1;
    for (int k = 0; k <= 60; ++k) {
      const double t = 0.1 * k;
      const double x = 8.0 + (t > 1.0 ? 10.0 * (t - 1.0) : 0.0);
      car.poses.push_back({static_cast<float>(x), 0.f, 0.f, 0.f});
      car.absent.push_back(0);
    }
    traffic.actors.push_back(car);
    for (int k = 0; k <= 60; ++k) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() = Eigen::Vector3d(0.1 * k, 0.0, 1.73);
      sensor.push_back(0.1 * k, T);
    }
  }

  /// Map points of `odometry` where the car stood higher than `min_z` above
  /// the road, in the world frame.
  [[nodiscard]] std::size_t ghostPoints(const LidarOdometry& odometry, double min_z = 0.2) const {
    const Eigen::Isometry3d T_world_odom = sensor.pose(0);
    std::size_t ghosts = 0;
    for (const Eigen::Vector3d& p : odometry.localMap().pointCloud()) {
      const Eigen::Vector3d w = T_world_odom * p;
      if (std::abs(w.x() - 8.0) < 2.4 && std::abs(w.y()) < 1.1 && w.z() > min_z) ++ghosts;
    }
    return ghosts;
  }
};

TEST(LidarOdometryFreeSpace, ACarThatDroveOffLeavesNoGhostInTheMap) {
  const LeavingCar street;
  const sim::ScanSimulator simulator(street.world, sim::LidarModel::hdl64(),
                                     {.motion_distortion = true, .noise = true, .parallel = true},
                                     street.traffic);
  OdometryConfig carving;
  carving.free_space_radius = 40.0;
  const OdometryConfig keeping;  // the default: off
  LidarOdometry with(carving), without(keeping);
  std::size_t parked = 0;
  for (int k = 0; k < 50; ++k) {
    const core::PointCloud scan = simulator.scan(street.sensor, 0.1 * k, 100 + k);
    ASSERT_TRUE(with.process(0.1 * k, scan).health.accepted) << k;
    ASSERT_TRUE(without.process(0.1 * k, scan).health.accepted) << k;
    if (k == 8) parked = with.localMap().pointCount() > 0 ? street.ghostPoints(with) : 0;
  }
  // Parked, the car is in both maps; gone, it stays only in the map that
  // never removes what the sweeps see through.
  EXPECT_GT(parked, 20u);
  EXPECT_GT(street.ghostPoints(without), 20u);
  // What stays is the foot of the car's faces: a later beam to a point a few
  // decimetres above the road meets the road within the carving's margin
  // behind it, so it never sees through it.
  EXPECT_LT(street.ghostPoints(with), street.ghostPoints(without) / 5);
  EXPECT_LT(street.ghostPoints(with, 0.7), street.ghostPoints(without, 0.7) / 20 + 1);
  // The road, walls and poles stay: carving removes only what moved.
  EXPECT_GT(static_cast<double>(with.localMap().pointCount()),
            0.95 * static_cast<double>(without.localMap().pointCount()) -
                static_cast<double>(street.ghostPoints(without)));
  EXPECT_LT((with.pose().translation() - without.pose().translation()).norm(), 0.05);
}

}  // namespace
}  // namespace dcl::odometry
