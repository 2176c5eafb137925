// External odometry: recorded poses from real TUM, KITTI and ROS1-bag files
// (read by io::readExternalOdometry), replayed at scan times, in the odometry
// frame of the first frame.

#include <cmath>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/io/external_odometry.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/io/rosbag.hpp>
#include <dcl/odometry/external_odometry.hpp>

namespace dcl::odometry {
namespace {

std::string data(const std::string& relative) {
  return std::string(DCL_DATA_DIR) + "/" + relative;
}

Eigen::Matrix<double, 7, 1> asVector(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  Eigen::Matrix<double, 7, 1> v;
  v << T.translation(), q.x(), q.y(), q.z(), q.w();
  return v;
}

double poseError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return core::logSE3(a.inverse() * b).norm();
}

/// The poses `config` names, as the application reads them.
core::Trajectory recorded(const ExternalOdometryConfig& config) {
  return io::readExternalOdometry(
      config.file, {.format = config.format, .times = config.times, .topic = config.topic});
}

ExternalOdometryConfig kittiConfig() {
  ExternalOdometryConfig config;
  config.file = data("trajectories/evo/KITTI_00_gt.txt");
  config.times = data("trajectories/evo/KITTI_00_gt_times.txt");
  config.format = "kitti";
  return config;
}

TEST(ExternalOdometry, KittiCameraPosesBecomeLidarOdometryWithTheCalibration) {
  // The ground truth tracks the left camera; the LiDAR sits at Tr in the camera
  // frame, so T_odom_lidar(t) = Tr^-1 T_cam0_cam(t) Tr.
  ExternalOdometryConfig config = kittiConfig();
  const Eigen::Isometry3d Tr =
      io::readKittiCalib(data("lidar_scans/kitti_00/calib.txt")).T_cam_velo;
  config.T_body_sensor = asVector(Tr);
  ExternalOdometry odometry(recorded(config), config);
  const core::Trajectory gt = io::readPoses(config.file, io::PoseFormat::kitti, config.times);
  for (std::size_t i = 0; i < 300; i += 7) {
    const OdometryResult r = odometry.process(gt.stamp(i), {});
    ASSERT_TRUE(r.health.accepted) << r.health.problem;
    Eigen::Isometry3d T_cam = gt.pose(i);
    T_cam.linear() = core::projectToSO3(T_cam.linear());
    EXPECT_LT(poseError(r.T_odom_sensor, Tr.inverse() * T_cam * Tr), 1e-6) << "frame " << i;
  }
  // KITTI 00 drives forward along the LiDAR's x axis.
  EXPECT_GT(odometry.pose().translation().x(), 100.0);
  EXPECT_EQ(odometry.name(), "external");
}

TEST(ExternalOdometry, FirstProcessedFrameIsTheOriginAndPosesInterpolate) {
  const core::Trajectory tum =
      io::readTumPoses(data("trajectories/evo/freiburg1_xyz-groundtruth.txt"));
  ExternalOdometry odometry(tum);
  const std::size_t first = 100;
  const OdometryResult r0 = odometry.process(tum.stamp(first), {});
  EXPECT_LT(poseError(r0.T_odom_sensor, Eigen::Isometry3d::Identity()), 1e-12);
  const Eigen::Isometry3d T_first = tum.pose(first);
  for (std::size_t i = first + 10; i < first + 200; i += 10) {
    // Half way between two recorded poses: the interpolated pose, in the first frame's frame.
    const double t = 0.5 * (tum.stamp(i) + tum.stamp(i + 1));
    const OdometryResult r = odometry.process(t, {});
    ASSERT_TRUE(r.health.accepted);
    EXPECT_LT(poseError(r.T_odom_sensor, T_first.inverse() * *tum.at(t)), 1e-9);
    EXPECT_TRUE(r.covariance.allFinite());
    EXPECT_GT(r.covariance(0, 0), 0.0);
  }
}

TEST(ExternalOdometry, AStreamedFrontEndPlacesFramesAsTheWholeTrajectoryDoes) {
  // A live front-end's poses arrive one by one, frames in between; all 3000
  // poses of the recording go through a window of a few thousand.
  const core::Trajectory tum =
      io::readTumPoses(data("trajectories/evo/freiburg1_xyz-groundtruth.txt"));
  ASSERT_GT(tum.size(), 2500u);
  ExternalOdometry whole(tum);
  ExternalOdometry live = ExternalOdometry::streaming({});
  EXPECT_FALSE(live.reaches(tum.stamp(0)));
  for (std::size_t i = 0; i < tum.size(); ++i) {
    ASSERT_TRUE(live.append(tum.stamp(i), tum.pose(i)));
    if (i < 2 || i % 5 != 0) {
      continue;
    }
    const double t = 0.5 * (tum.stamp(i - 1) + tum.stamp(i));
    ASSERT_TRUE(live.reaches(t));
    const OdometryResult a = live.process(t, {});
    const OdometryResult b = whole.process(t, {});
    ASSERT_TRUE(a.health.accepted) << i;
    EXPECT_LT(poseError(a.T_odom_sensor, b.T_odom_sensor), 1e-9) << i;
  }
  // Not after the last pose, or not finite: refused, nothing kept.
  EXPECT_FALSE(live.append(tum.stamp(tum.size() - 1), tum.pose(0)));
  EXPECT_FALSE(live.append(std::numeric_limits<double>::quiet_NaN(), tum.pose(0)));
  Eigen::Isometry3d bad = tum.pose(0);
  bad.translation().x() = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(live.append(tum.stamp(tum.size() - 1) + 1.0, bad));
  EXPECT_FALSE(live.reaches(tum.stamp(tum.size() - 1) + 0.5));
  // Hours of a 100 Hz front-end keep a window, not every pose.
  double t = tum.stamp(tum.size() - 1);
  for (int i = 0; i < 20000; ++i) {
    t += 0.01;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation().x() = 0.01 * i;
    ASSERT_TRUE(live.append(t, T));
    if (i % 10 == 0) {
      ASSERT_TRUE(live.process(t, {}).health.accepted);
    }
  }
  EXPECT_LE(live.posesHeld(), 4096u + 1u);
}

TEST(ExternalOdometry, BadStampsAreReportedAndThePoseHeld) {
  const core::Trajectory tum =
      io::readTumPoses(data("trajectories/evo/freiburg1_xyz-groundtruth.txt"));
  ExternalOdometry odometry(tum);
  const OdometryResult before = odometry.process(tum.stamp(0) - 1.0, {});
  EXPECT_FALSE(before.health.accepted);
  EXPECT_FALSE(before.health.problem.empty());
  const OdometryResult good = odometry.process(tum.stamp(50), {});
  ASSERT_TRUE(good.health.accepted);
  const OdometryResult later = odometry.process(tum.stamp(80), {});
  ASSERT_TRUE(later.health.accepted);
  for (const double t :
       {tum.stamp(60), odometry.lastStamp() + 1.0, std::numeric_limits<double>::quiet_NaN()}) {
    const OdometryResult r = odometry.process(t, {});
    EXPECT_FALSE(r.health.accepted) << t;
    EXPECT_FALSE(r.health.problem.empty());
    EXPECT_TRUE(r.T_odom_sensor.isApprox(later.T_odom_sensor));
  }
  EXPECT_TRUE(odometry.pose().isApprox(later.T_odom_sensor));
}

TEST(ExternalOdometry, ScansThatNeverMeetThePosesInTimeAreRefused) {
  const core::Trajectory tum =
      io::readTumPoses(data("trajectories/evo/freiburg1_xyz-groundtruth.txt"));
  const ExternalOdometry odometry(tum);
  // Partly inside, or the whole trajectory inside the scans' span: frames get poses.
  odometry.requireOverlap(tum.stamp(0) - 5.0, tum.stamp(0));
  odometry.requireOverlap(odometry.lastStamp() - 1.0, odometry.lastStamp() + 1.0);
  odometry.requireOverlap(0.0, 2e9);
  // Seconds since the start against the file's Unix times: every frame would be held.
  try {
    odometry.requireOverlap(0.0, 12.5);
    FAIL() << "scans outside the poses' time range were accepted";
  } catch (const core::Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("poses span 1305031098.665900 .. 1305031128.755500 s"),
              std::string::npos)
        << message;
    EXPECT_NE(message.find("the scans 0.000000 .. 12.500000 s"), std::string::npos) << message;
  }
  EXPECT_THROW(odometry.requireOverlap(odometry.lastStamp() + 1.0, odometry.lastStamp() + 9.0),
               core::Error);
}

TEST(ExternalOdometry, ReadsPoseStampedFromARealBag) {
  ExternalOdometryConfig config;
  config.file = data("rosbags/evo_ROS_example.bag");  // format "auto": by the .bag extension
  config.topic = "/groundtruth";
  ExternalOdometry odometry(recorded(config), config);
  const core::Trajectory bag = io::readBagTrajectory(config.file, config.topic);
  ASSERT_EQ(bag.size(), 12765u);
  const OdometryResult r0 = odometry.process(bag.stamp(0), {});
  ASSERT_TRUE(r0.health.accepted);
  EXPECT_LT(poseError(r0.T_odom_sensor, Eigen::Isometry3d::Identity()), 1e-12);
  const OdometryResult r = odometry.process(bag.stamp(1000), {});
  ASSERT_TRUE(r.health.accepted);
  // Message 1000's position as python-rosbag (an independent reader) prints it.
  const Eigen::Vector3d expected(-1.861040072496155, -3.019153243585831, 21.184413495268355);
  EXPECT_LT(((bag.pose(0) * r.T_odom_sensor).translation() - expected).norm(), 1e-9);
}

TEST(ExternalOdometry, RejectsUnusableSources) {
  // (Unreadable files: io's ExternalOdometryFile tests.)
  ExternalOdometryConfig config;
  config.file = data("rosbags/evo_ROS_example.bag");
  EXPECT_THROW(validate(config), core::Error);  // a bag needs a topic
  config.format = "csv";
  EXPECT_THROW(validate(config), core::Error);
  EXPECT_THROW(ExternalOdometry{core::Trajectory{}}, core::Error);
  config = {};
  config.T_body_sensor << 0, 0, 0, 0, 0, 0, 0;  // not a rotation
  EXPECT_THROW((ExternalOdometry{core::Trajectory({0.0}, {Eigen::Isometry3d::Identity()}), config}),
               core::Error);
}

}  // namespace
}  // namespace dcl::odometry
