#include <algorithm>
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/eval/scan_statistics.hpp>
#include <dcl/sim/routes.hpp>

namespace dcl::sim {
namespace {

const std::string kData = DCL_DATA_DIR;

core::Trajectory kittiLidar(const std::string& sequence) {
  const KittiFiles files = kittiFiles(kData, sequence);
  return loadKittiLidarTrajectory(files.poses, files.calib, files.times);
}

/// A straight drive along `direction` from `start`, `n` poses 1 m and 0.1 s apart, facing the
/// motion.
core::Trajectory straight(const Eigen::Vector2d& start, const Eigen::Vector2d& direction, int n) {
  core::Trajectory t;
  const double yaw = std::atan2(direction.y(), direction.x());
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d p = start + i * direction.normalized();
    t.push_back(0.1 * i, core::makePose2d(p.x(), p.y(), yaw));
  }
  return t;
}

std::vector<Route> twoRoutes(core::Trajectory a, core::Trajectory b) {
  return {Route{"a", std::move(a)}, Route{"b", std::move(b)}};
}

/// True when some overlap of `kind` joins two different robots and is not a split seam.
bool hasGenuine(const std::vector<Overlap>& overlaps, OverlapKind kind, double min_length = 5.0) {
  return std::any_of(overlaps.begin(), overlaps.end(), [&](const Overlap& o) {
    return o.kind == kind && !o.handover && o.robot_a != o.robot_b && o.length >= min_length;
  });
}

double longest(const std::vector<Overlap>& overlaps, OverlapKind kind) {
  double best = 0.0;
  for (const Overlap& o : overlaps)
    if (o.kind == kind && !o.handover) best = std::max(best, o.length);
  return best;
}

/// The overlaps of a whole trajectory with itself: cut into 25 m pieces, pieces
/// at least three apart (75 m of travel) compared. Shows what a sequence offers
/// to any split.
std::vector<Overlap> selfRevisits(const core::Trajectory& t) {
  const std::vector<double> pieces(std::size_t(t.length() / 27.0) - 2, 25.0);
  const std::vector<Route> routes = splitByLength(t, pieces);
  std::vector<Overlap> far;
  for (const Overlap& o : findOverlaps(routes))
    if (o.robot_b >= o.robot_a + 3) far.push_back(o);
  return far;
}

// ---------------------------------------------------------------- conversion

TEST(KittiToLidar, AppliesTheCalibrationAndStartsAtIdentity) {
  const Eigen::Isometry3d T_cam_velo = core::makePose(
      Eigen::Vector3d(0.1, -0.2, 0.3), Eigen::Matrix3d(core::expSO3({0.2, -1.4, 0.5})));
  core::Trajectory cam;
  cam.push_back(0.0, Eigen::Isometry3d::Identity());
  cam.push_back(0.1, core::makePose(Eigen::Vector3d(1, 2, 3), core::expSO3({0.1, 0.2, -0.3})));
  const core::Trajectory velo = kittiToLidar(cam, T_cam_velo);
  ASSERT_EQ(velo.size(), 2u);
  EXPECT_TRUE(velo.pose(0).isApprox(Eigen::Isometry3d::Identity(), 1e-12));
  const Eigen::Isometry3d expected = T_cam_velo.inverse() * cam.pose(1) * T_cam_velo;
  EXPECT_TRUE(velo.pose(1).isApprox(expected, 1e-12));
  EXPECT_DOUBLE_EQ(velo.stamp(1), 0.1);
}

TEST(KittiToLidar, ReanchorsAFirstPoseThatIsNotTheIdentity) {
  core::Trajectory cam;
  const Eigen::Isometry3d T0 = core::makePose2d(5, -3, 0.7);
  const Eigen::Isometry3d T1 = core::makePose2d(6, -1, 0.9);
  cam.push_back(0.0, T0);
  cam.push_back(1.0, T1);
  const core::Trajectory velo = kittiToLidar(cam, Eigen::Isometry3d::Identity());
  EXPECT_TRUE(velo.pose(0).isApprox(Eigen::Isometry3d::Identity(), 1e-12));
  EXPECT_TRUE(velo.pose(1).isApprox(T0.inverse() * T1, 1e-12));
}

TEST(KittiToLidar, RealGroundTruthBecomesExactRigidPosesInALevelLidarFrame) {
  const core::Trajectory t = kittiLidar("05");
  ASSERT_EQ(t.size(), 2761u);
  EXPECT_TRUE(t.pose(0).isApprox(Eigen::Isometry3d::Identity(), 1e-12));
  for (const Eigen::Isometry3d& T : t.poses()) {
    const Eigen::Matrix3d R = T.linear();
    ASSERT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    ASSERT_NEAR(R.determinant(), 1.0, 1e-12);
    ASSERT_GT(R(2, 2), 0.99) << "the LiDAR's z axis should point up";
  }
}

TEST(KittiToLidar, HeightProfileOfKitti05IsPlausible) {
  const core::Trajectory t = kittiLidar("05");
  const std::vector<double> d = t.distances();
  double z_min = 0.0, z_max = 0.0, grade = 0.0;
  std::size_t j = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    const double z = t.pose(i).translation().z();
    z_min = std::min(z_min, z);
    z_max = std::max(z_max, z);
    while (j < t.size() && d[j] < d[i] + 20.0) ++j;
    if (j < t.size()) grade = std::max(grade, std::abs(t.pose(j).translation().z() - z) / 20.0);
  }
  // 2.2 km of city streets: a few metres up and down, no climb steeper than a street.
  EXPECT_GT(z_min, -8.0);
  EXPECT_LT(z_max, 12.0);
  EXPECT_LT(grade, 0.10);
}

TEST(KittiToLidar, TheLidarLooksAlongItsXAxis) {
  const core::Trajectory t = kittiLidar("05");
  std::size_t moving = 0, forward = 0;
  for (std::size_t i = 0; i + 1 < t.size(); ++i) {
    const Eigen::Vector3d v_body =
        t.pose(i).linear().transpose() * (t.pose(i + 1).translation() - t.pose(i).translation());
    if (v_body.norm() < 0.1) continue;  // standing still
    ++moving;
    if (v_body.x() > 0.95 * v_body.norm()) ++forward;
  }
  ASSERT_GT(moving, 2000u);
  EXPECT_GT(double(forward) / double(moving), 0.99);
}

TEST(KittiToLidar, StampsComeFromTheTimesFileOrTenHertz) {
  const core::Trajectory t05 = kittiLidar("05");
  EXPECT_DOUBLE_EQ(t05.stamp(0), 0.0);
  EXPECT_NEAR(t05.stamp(10), 1.0, 1e-12);
  const core::Trajectory t00 = kittiLidar("00");
  ASSERT_EQ(t00.size(), 4541u);
  EXPECT_NEAR(t00.stamp(1), 0.1037, 1e-3);  // KITTI_00_gt_times.txt, not exactly 0.1
  EXPECT_TRUE(t00.isSorted());
}

TEST(LimitGrade, FlattensTheImpossibleClimbAtTheStartOfKitti08) {
  const core::Trajectory raw = kittiLidar("08");
  // The ground truth rises about 0.18 m a frame while the car creeps forward level.
  EXPECT_GT(raw.pose(100).translation().z(), 15.0);
  const core::Trajectory limited = limitGrade(raw, kKittiMaxGrade);
  EXPECT_LT(limited.pose(100).translation().z(), 0.5 * raw.pose(100).translation().z());
  for (std::size_t i = 1; i < limited.size(); ++i) {
    const Eigen::Vector3d step = limited.pose(i).translation() - limited.pose(i - 1).translation();
    ASSERT_LE(std::abs(step.z()), kKittiMaxGrade * step.head<2>().norm() + 1e-9);
    ASSERT_TRUE(limited.pose(i).linear().isApprox(raw.pose(i).linear()));
    ASSERT_TRUE(
        limited.pose(i).translation().head<2>().isApprox(raw.pose(i).translation().head<2>()));
  }
}

TEST(LimitGrade, LeavesADrivableProfileAlone) {
  const core::Trajectory raw = kittiLidar("05");
  const core::Trajectory limited = limitGrade(raw, kKittiMaxGrade);
  double change = 0.0;
  for (std::size_t i = 0; i < raw.size(); ++i)
    change = std::max(change,
                      std::abs(limited.pose(i).translation().z() - raw.pose(i).translation().z()));
  EXPECT_LT(change, 0.1);  // only millimetre jitter while standing still is removed
}

/// The largest height difference between poses of `t` within `radius` of each
/// other horizontally and at least `min_travel` metres of driving apart.
double worstRevisitHeight(const core::Trajectory& t, double radius, double min_travel) {
  const std::vector<double> d = t.distances();
  double worst = 0.0;
  for (std::size_t i = 0; i < t.size(); i += 3)
    for (std::size_t j = 0; j < i; j += 3) {
      if (d[i] - d[j] < min_travel) continue;
      const Eigen::Vector3d a = t.pose(i).translation(), b = t.pose(j).translation();
      if ((a - b).head<2>().norm() < radius) worst = std::max(worst, std::abs(a.z() - b.z()));
    }
  return worst;
}

TEST(LevelRevisits, SpreadsAHeightDriftOverTheDriveBetweenPasses) {
  // Out along x, and back 3 m to the side: the return drifts 3 m down.
  core::Trajectory t = straight({0, 0}, {1, 0}, 200);
  const core::Trajectory back = straight({199, 3}, {-1, 0}, 200);
  for (std::size_t i = 0; i < back.size(); ++i) {
    Eigen::Isometry3d T = back.pose(i);
    T.translation().z() = -3.0 * static_cast<double>(i) / 199.0;
    t.push_back(20.0 + back.stamp(i), T);
  }
  ASSERT_GT(worstRevisitHeight(t, 5.0, 100.0), 2.5);
  const core::Trajectory level = levelRevisits(t);
  EXPECT_LT(worstRevisitHeight(level, 5.0, 100.0), 0.1);
  for (std::size_t i = 0; i < t.size(); ++i) {
    ASSERT_TRUE(level.pose(i).linear().isApprox(t.pose(i).linear()));
    ASSERT_EQ(level.pose(i).translation().head<2>(), t.pose(i).translation().head<2>());
  }
  // A drive that never comes back keeps its profile.
  core::Trajectory hill = straight({0, 0}, {1, 0}, 300);
  for (std::size_t i = 0; i < hill.size(); ++i)
    hill.pose(i).translation().z() = 0.05 * static_cast<double>(i);
  const core::Trajectory same = levelRevisits(hill);
  for (std::size_t i = 0; i < hill.size(); ++i)
    ASSERT_NEAR(same.pose(i).translation().z(), hill.pose(i).translation().z(), 1e-6);
}

TEST(LevelRevisits, PutsKitti08sReturnOnTheRoadItLeft) {
  // KITTI 08's ground truth comes back to its streets up to metres off in
  // height; a simulated robot there would drive under the road.
  const core::Trajectory raw = limitGrade(kittiLidar("08"), kKittiMaxGrade);
  ASSERT_GT(worstRevisitHeight(raw, 4.0, 100.0), 2.0);
  const core::Trajectory level = levelRevisits(raw);
  EXPECT_LT(worstRevisitHeight(level, 4.0, 100.0), 0.3);
  // Still a drivable profile: no 10 m stretch climbs more than 11 %.
  for (std::size_t i = 10; i < level.size(); ++i) {
    const Eigen::Vector3d step = level.pose(i).translation() - level.pose(i - 10).translation();
    if (step.head<2>().norm() > 2.0) {
      ASSERT_LT(std::abs(step.z()), 0.11 * step.head<2>().norm()) << i;
    }
  }
}

// ---------------------------------------------------------------- splitting

TEST(SplitByLength, CutsConsecutivePiecesAndRetimesEach) {
  const core::Trajectory line = straight({0, 0}, {1, 0}, 101);  // 100 m
  const std::vector<double> lengths{30.0, 25.0};
  const std::vector<Route> routes = splitByLength(line, lengths);
  ASSERT_EQ(routes.size(), 3u);
  EXPECT_EQ(routes[0].name, "a");
  EXPECT_EQ(routes[2].name, "c");
  EXPECT_DOUBLE_EQ(routes[0].length(), 30.0);
  EXPECT_DOUBLE_EQ(routes[1].length(), 25.0);
  EXPECT_DOUBLE_EQ(routes[2].length(), 43.0);  // 100 - 30 - 25 - two seams of 1 m
  std::size_t poses = 0;
  for (const Route& r : routes) {
    EXPECT_DOUBLE_EQ(r.T_world_sensor.stamp(0), 0.0);
    poses += r.T_world_sensor.size();
  }
  EXPECT_EQ(poses, line.size());
  EXPECT_DOUBLE_EQ(routes[1].T_world_sensor.pose(0).translation().x(), 31.0);
}

TEST(SplitByLength, OdometryFrameIsTheFirstPose) {
  const std::vector<double> lengths{30.0};
  const std::vector<Route> routes = splitByLength(straight({0, 0}, {0, 1}, 61), lengths);
  const Route& b = routes[1];
  EXPECT_TRUE(b.T_world_odom().isApprox(b.T_world_sensor.pose(0)));
  const core::Trajectory odom = b.inOdomFrame();
  EXPECT_TRUE(odom.pose(0).isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_TRUE(odom.pose(10).translation().isApprox(Eigen::Vector3d(10, 0, 0)));
  EXPECT_NEAR(b.duration(), 2.9, 1e-12);
}

TEST(SplitByLength, RejectsLengthsTheTrajectoryCannotGive) {
  const core::Trajectory line = straight({0, 0}, {1, 0}, 11);
  EXPECT_THROW(splitByLength(line, std::vector<double>{20.0}), core::Error);
  EXPECT_THROW(splitByLength(line, std::vector<double>{-1.0}), core::Error);
  EXPECT_THROW(splitByLength(line, std::vector<double>{5.0, 4.0}), core::Error);
}

TEST(KittiRoutes, SplitsMatchThePaperWithinOneFrame) {
  for (const std::string sequence : {"05", "08"}) {
    const std::vector<Route> routes = kittiRoutes(kData, sequence);
    const KittiSplit split = kittiSplit(sequence);
    ASSERT_EQ(routes.size(), split.lengths.size() + 1) << sequence;
    for (std::size_t i = 0; i < split.lengths.size(); ++i) {
      const double frame = (routes[i + 1].T_world_odom().translation() -
                            routes[i].T_world_sensor.poses().back().translation())
                               .norm();  // the travel of the frame at the seam
      EXPECT_NEAR(routes[i].length(), split.lengths[i], frame) << sequence << " robot " << i;
    }
    for (const Route& r : routes) EXPECT_DOUBLE_EQ(r.T_world_sensor.stamp(0), 0.0);
  }
  EXPECT_EQ(kittiSplit("05").lengths, (std::vector<double>{424.9, 599.9}));
  EXPECT_EQ(kittiSplit("08").lengths, (std::vector<double>{1252.8}));
  EXPECT_EQ(kittiRoutes(kData, "00").size(), 3u);
  EXPECT_THROW(kittiSplit("09"), core::Error);
}

// ---------------------------------------------------------------- overlaps

TEST(FindOverlaps, ClassifiesSameOppositeAndCrossing) {
  const auto same =
      findOverlaps(twoRoutes(straight({0, 0}, {1, 0}, 60), straight({20, 3}, {1, 0}, 60)));
  ASSERT_EQ(same.size(), 1u);
  EXPECT_EQ(same[0].kind, OverlapKind::same_direction);
  // a is within 10 m of b from x = 20 - sqrt(10^2 - 3^2) on.
  EXPECT_NEAR(same[0].length, 59.0 - (20.0 - std::sqrt(10.0 * 10.0 - 3.0 * 3.0)), 1.0);
  EXPECT_EQ(same[0].first_b, 0u);
  EXPECT_FALSE(same[0].handover);

  const auto opposite =
      findOverlaps(twoRoutes(straight({0, 0}, {1, 0}, 60), straight({59, -3}, {-1, 0}, 60)));
  ASSERT_EQ(opposite.size(), 1u);
  EXPECT_EQ(opposite[0].kind, OverlapKind::opposite_direction);
  EXPECT_NEAR(opposite[0].length, 59.0, 1.0);

  const auto crossing =
      findOverlaps(twoRoutes(straight({0, 0}, {1, 0}, 60), straight({30, -30}, {0, 1}, 60)));
  ASSERT_EQ(crossing.size(), 1u);
  EXPECT_EQ(crossing[0].kind, OverlapKind::crossing);
  EXPECT_NEAR(crossing[0].position.x(), 30.0, 1.0);

  EXPECT_TRUE(
      findOverlaps(twoRoutes(straight({0, 0}, {1, 0}, 60), straight({0, 30}, {1, 0}, 60))).empty());
}

TEST(FindOverlaps, FlagsTheSeamOfASplitAsAHandover) {
  const std::vector<double> lengths{50.0};
  const auto overlaps = findOverlaps(splitByLength(straight({0, 0}, {1, 0}, 101), lengths));
  ASSERT_EQ(overlaps.size(), 1u);
  EXPECT_TRUE(overlaps[0].handover);
  EXPECT_FALSE(overlapGraphConnected(2, overlaps));
}

TEST(FindOverlaps, GraphConnectivity) {
  Overlap ab{}, cd{};
  ab.robot_a = 0, ab.robot_b = 1;
  cd.robot_a = 2, cd.robot_b = 3;
  std::vector<Overlap> overlaps{ab, cd};
  EXPECT_FALSE(overlapGraphConnected(4, overlaps));
  Overlap bc{};
  bc.robot_a = 1, bc.robot_b = 2;
  overlaps.push_back(bc);
  EXPECT_TRUE(overlapGraphConnected(4, overlaps));
  EXPECT_TRUE(overlapGraphConnected(1, {}));
}

TEST(KittiOverlaps, Kitti00SplitHasBothKindsAndEveryRobotOverlaps) {
  const std::vector<Route> routes = kittiRoutes(kData, "00");
  const std::vector<Overlap> overlaps = findOverlaps(routes);
  EXPECT_GT(longest(overlaps, OverlapKind::same_direction), 300.0);
  EXPECT_TRUE(hasGenuine(overlaps, OverlapKind::opposite_direction, 10.0));
  EXPECT_TRUE(overlapGraphConnected(routes.size(), overlaps));
}

TEST(KittiOverlaps, Kitti05SplitRevisitsTheSameWay) {
  const std::vector<Overlap> overlaps = findOverlaps(kittiRoutes(kData, "05"));
  EXPECT_GT(longest(overlaps, OverlapKind::same_direction), 100.0);
  EXPECT_TRUE(overlapGraphConnected(3, overlaps));
  // No split of 05 can have an opposite-direction overlap: the whole sequence
  // never drives a street the other way for more than a junction's width.
  EXPECT_LT(longest(selfRevisits(limitGrade(kittiLidar("05"), kKittiMaxGrade)),
                    OverlapKind::opposite_direction),
            10.0);
}

TEST(KittiOverlaps, Kitti08SplitRevisitsTheOtherWay) {
  const std::vector<Overlap> overlaps = findOverlaps(kittiRoutes(kData, "08"));
  EXPECT_GT(longest(overlaps, OverlapKind::opposite_direction), 150.0);
  // 08 never drives a street twice the same way; the only same-direction
  // overlap between its robots is the seam where b takes over from a.
  EXPECT_FALSE(hasGenuine(overlaps, OverlapKind::same_direction));
  EXPECT_TRUE(std::any_of(overlaps.begin(), overlaps.end(), [](const Overlap& o) {
    return o.handover && o.kind == OverlapKind::same_direction;
  }));
  EXPECT_EQ(longest(selfRevisits(limitGrade(kittiLidar("08"), kKittiMaxGrade)),
                    OverlapKind::same_direction),
            0.0);
}

// ---------------------------------------------------------------- campus

/// Largest speed, speed change per pose, yaw rate and tilt over all routes.
struct Motion {
  double speed = 0.0, speed_change = 0.0, yaw_rate = 0.0, tilt = 0.0, sideways = 0.0;
};

Motion motionOf(const std::vector<Route>& routes) {
  Motion m;
  for (const Route& r : routes) {
    const core::Trajectory& t = r.T_world_sensor;
    double last_speed = 0.0;
    for (std::size_t i = 0; i + 1 < t.size(); ++i) {
      const double dt = t.stamp(i + 1) - t.stamp(i);
      const Eigen::Vector3d v = t.pose(i).linear().transpose() *
                                (t.pose(i + 1).translation() - t.pose(i).translation()) / dt;
      const Eigen::Matrix3d dR = t.pose(i).linear().transpose() * t.pose(i + 1).linear();
      m.speed = std::max(m.speed, v.norm());
      m.speed_change = std::max(m.speed_change, std::abs(v.norm() - last_speed));
      m.yaw_rate = std::max(m.yaw_rate, std::abs(core::logSO3(dR).z()) / dt);
      m.tilt = std::max(m.tilt, std::acos(std::min(1.0, t.pose(i).linear()(2, 2))));
      if (v.norm() > 0.5) m.sideways = std::max(m.sideways, std::abs(v.y()) / v.norm());
      last_speed = v.norm();
    }
  }
  return m;
}

/// Closest approach of robot k to any other robot at the same stamp.
double closestMeeting(const std::vector<Route>& routes, std::size_t k) {
  double best = INFINITY;
  const core::Trajectory& a = routes[k].T_world_sensor;
  for (std::size_t j = 0; j < routes.size(); ++j) {
    if (j == k) continue;
    const core::Trajectory& b = routes[j].T_world_sensor;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i)
      best = std::min(best, (a.pose(i).translation() - b.pose(i).translation()).norm());
  }
  return best;
}

class CampusRoutes : public ::testing::TestWithParam<int> {};

TEST_P(CampusRoutes, OverlapGraphIsConnectedAndEveryRobotHasARendezvous) {
  const int n = GetParam();
  const std::vector<Route> routes = campusRoutes(n, 7);
  ASSERT_EQ(routes.size(), std::size_t(n));
  const std::vector<Overlap> overlaps = findOverlaps(routes);
  EXPECT_TRUE(overlapGraphConnected(routes.size(), overlaps));
  EXPECT_TRUE(hasGenuine(overlaps, OverlapKind::same_direction, 30.0));
  EXPECT_TRUE(hasGenuine(overlaps, OverlapKind::opposite_direction, 30.0));
  for (std::size_t k = 0; k < routes.size(); ++k)
    EXPECT_LT(closestMeeting(routes, k), 10.0) << "robot " << routes[k].name;
}

TEST_P(CampusRoutes, RoutesAreSmoothUgvDrives) {
  const CampusRouteConfig config;
  const std::vector<Route> routes = campusRoutes(GetParam(), 3, config);
  const Motion m = motionOf(routes);
  EXPECT_LE(m.speed, config.max_speed * 1.001);  // planar speed, plus the gentle slope
  EXPECT_LE(m.speed_change, config.acceleration / config.rate + 0.01);
  EXPECT_LE(m.yaw_rate, config.max_speed / config.corner_radius * 1.05);
  EXPECT_LT(m.tilt, core::deg2rad(3.0));
  EXPECT_LT(m.sideways, 0.05);  // yaw follows the path
  for (std::size_t i = 0; i < routes.size(); ++i) {
    for (std::size_t j = i + 1; j < routes.size(); ++j) {
      const double d =
          (routes[i].T_world_odom().translation() - routes[j].T_world_odom().translation()).norm();
      EXPECT_GE(d, config.min_start_separation)
          << "robots " << i << " and " << j << " start together";
    }
  }
  for (const Route& r : routes) {
    EXPECT_GT(r.length(), 250.0);
    EXPECT_DOUBLE_EQ(r.T_world_sensor.stamp(0), 0.0);
    EXPECT_NEAR(r.T_world_sensor.stamp(1), 0.1, 1e-12);
  }
}

INSTANTIATE_TEST_SUITE_P(Robots, CampusRoutes, ::testing::Values(3, 9, 27));

TEST(CampusRoutesMix, LoopsAndURoutes) {
  std::size_t loops = 0, us = 0;
  for (const Route& r : campusRoutes(27, 1)) {
    const double gap =
        (r.T_world_sensor.poses().back().translation() - r.T_world_odom().translation()).norm();
    (gap < 5.0 ? loops : us) += 1;
  }
  EXPECT_GT(loops, 3u);
  EXPECT_GT(us, 3u);
}

TEST(CampusRoutesDeterminism, SameSeedSameRoutes) {
  const auto a = campusRoutes(9, 42);
  const auto b = campusRoutes(9, 42);
  const auto c = campusRoutes(9, 43);
  ASSERT_EQ(a.size(), b.size());
  bool differs = false;
  for (std::size_t k = 0; k < a.size(); ++k) {
    ASSERT_EQ(a[k].T_world_sensor.size(), b[k].T_world_sensor.size());
    for (std::size_t i = 0; i < a[k].T_world_sensor.size(); ++i)
      ASSERT_EQ(a[k].T_world_sensor.pose(i).matrix(), b[k].T_world_sensor.pose(i).matrix());
    differs |= a[k].T_world_sensor.size() != c[k].T_world_sensor.size() ||
               !a[k].T_world_sensor.pose(0).isApprox(c[k].T_world_sensor.pose(0));
  }
  EXPECT_TRUE(differs);
}

TEST(CampusRoutesErrors, RejectsNoRobots) {
  EXPECT_THROW(campusRoutes(0, 1), core::Error);
  EXPECT_THROW(aliasingRoutes(0, 1), core::Error);
  CampusRouteConfig config;
  config.columns = -1;
  EXPECT_THROW(campusRoutes(3, 1, config), core::Error);
}

TEST(CampusRoutes, OneColumnStacksTheBlocks) {
  CampusRouteConfig config;
  config.columns = 1;
  config.u_route_share = 0.0;
  const std::vector<Route> routes = campusRoutes(4, 2, config);
  ASSERT_EQ(routes.size(), 4u);
  for (std::size_t i = 0; i < routes.size(); ++i) {
    // Every loop around a block of its own, each block above the last.
    double min_x = INFINITY, max_x = -INFINITY, min_y = INFINITY, max_y = -INFINITY;
    for (std::size_t k = 0; k < routes[i].T_world_sensor.size(); ++k) {
      const Eigen::Vector3d p = routes[i].T_world_sensor.pose(k).translation();
      min_x = std::min(min_x, p.x()), max_x = std::max(max_x, p.x());
      min_y = std::min(min_y, p.y()), max_y = std::max(max_y, p.y());
    }
    const double y0 = double(i) * config.block_pitch;
    EXPECT_NEAR(min_x, 0.0, 3.0) << i;
    EXPECT_NEAR(max_x, config.block_pitch, 3.0) << i;
    EXPECT_NEAR(min_y, y0, 3.0) << i;
    EXPECT_NEAR(max_y, y0 + config.block_pitch, 3.0) << i;
  }
  // Neighbours share a street, the same way; no one meets another head-on.
  const std::vector<Overlap> overlaps = findOverlaps(routes);
  for (std::size_t i = 0; i + 1 < routes.size(); ++i)
    EXPECT_TRUE(std::any_of(overlaps.begin(), overlaps.end(), [&](const Overlap& o) {
      return o.robot_a == i && o.robot_b == i + 1 && o.kind == OverlapKind::same_direction;
    })) << i;
  for (const Overlap& o : overlaps) EXPECT_NE(o.kind, OverlapKind::opposite_direction);
}

// ---------------------------------------------------------------- aliasing

TEST(AliasingRoutes, OneCorridorDrivenBothWaysAtDifferentOffsets) {
  const AliasingRouteConfig config;
  const std::vector<Route> routes = aliasingRoutes(3, 5, config);
  ASSERT_EQ(routes.size(), 3u);
  for (const Route& r : routes) {
    EXPECT_NEAR(r.length(), config.route_length, 0.5);
    for (const Eigen::Isometry3d& T : r.T_world_sensor.poses()) {
      ASSERT_LE(std::abs(T.translation().y()), config.lane_offset + 1e-9);
      ASSERT_GE(T.translation().x(), -1e-9);
      ASSERT_LE(T.translation().x(), config.corridor_length + 1e-9);
    }
  }
  const std::vector<Overlap> overlaps = findOverlaps(routes);
  EXPECT_GT(longest(overlaps, OverlapKind::same_direction), 50.0);
  EXPECT_GT(longest(overlaps, OverlapKind::opposite_direction), 50.0);
  const double x_a = routes[0].T_world_odom().translation().x();
  const double x_c = routes[2].T_world_odom().translation().x();
  EXPECT_GT(std::abs(x_c - x_a), 50.0);  // the same corridor entered at different places
  const auto again = aliasingRoutes(3, 5, config);
  EXPECT_EQ(again[1].T_world_sensor.pose(100).matrix(),
            routes[1].T_world_sensor.pose(100).matrix());
}

// ---------------------------------------------------------------- the body

/// `n` poses 0.1 s apart along `path(t)` (x, y, yaw), flat.
template <typename Path>
core::Trajectory drive(int n, Path path) {
  core::Trajectory t;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p = path(0.1 * i);
    t.push_back(0.1 * i, core::makePose2d(p.x(), p.y(), p.z()));
  }
  return t;
}

/// Only the accelerations' tilt: no road.
BodyMotion smoothRoad() {
  BodyMotion motion;
  motion.road_sigma_deg = 0.0;
  motion.bump_spacing = 0.0;
  return motion;
}

double deg(double rad) {
  return rad * 180.0 / M_PI;
}

TEST(BodyMotion, BrakingDipsTheNoseAndATurnRollsTheBodyOut) {
  // Braking from 10 m/s at 2 m/s^2: 0.25 deg a m/s^2 -> 0.5 deg nose down.
  const auto braking =
      rockBody(drive(50, [](double t) { return Eigen::Vector3d(10 * t - t * t, 0, 0); }), 1.73, 1,
               smoothRoad());
  const Eigen::Isometry3d& settled = braking.pose(35);
  EXPECT_NEAR(deg(std::asin(-settled.linear()(2, 0))), 0.5, 0.05);  // x points down
  // The mast turned about the ground: the sensor 1.73 m * 0.5 deg ahead.
  EXPECT_NEAR(settled.translation().x() - (3.5 * 10 - 3.5 * 3.5), 1.73 * std::sin(0.5 * M_PI / 180),
              0.002);
  // A left circle of 20 m at 5 m/s: 1.25 m/s^2 across, 0.625 deg out (the left side up).
  const auto turning =
      rockBody(drive(100,
                     [](double t) {
                       const double a = 0.25 * t;
                       return Eigen::Vector3d(20 * std::sin(a), 20 - 20 * std::cos(a), a);
                     }),
               1.73, 1, smoothRoad());
  for (int i : {10, 50, 90})
    EXPECT_NEAR(deg(std::asin(turning.pose(i).linear()(2, 1))), 0.625, 0.01) << i;
}

TEST(BodyMotion, ABodyStandingStillDoesNotRock) {
  const core::Trajectory standing = drive(100, [](double) { return Eigen::Vector3d(3, 4, 0.5); });
  const core::Trajectory rocked = rockBody(standing, 1.0, 7);  // road and bumps on
  for (std::size_t i = 0; i < standing.size(); ++i)
    EXPECT_TRUE(rocked.pose(i).isApprox(standing.pose(i), 1e-15)) << i;
}

TEST(BodyMotion, GeneratedRoutesRockAsKittisCarDoes) {
  // The band of the real drives: KITTI 00, 05 and 08's fast pitch and roll.
  double sigma_lo = INFINITY, sigma_hi = 0, p99_lo = INFINITY, p99_hi = 0;
  for (const char* sequence : {"00", "05", "08"}) {
    const eval::AttitudeStatistics real = eval::measureAttitude(kittiLidar(sequence));
    for (double v : {real.pitch_sigma_deg, real.roll_sigma_deg})
      sigma_lo = std::min(sigma_lo, v), sigma_hi = std::max(sigma_hi, v);
    for (double v : {real.pitch_p99_deg, real.roll_p99_deg})
      p99_lo = std::min(p99_lo, v), p99_hi = std::max(p99_hi, v);
  }
  ASSERT_GT(sigma_lo, 0.1);  // the real car does rock
  for (std::uint64_t seed : {1, 2, 3}) {
    const std::vector<Route> routes = campusRoutes(3, seed);
    for (std::size_t r = 0; r < routes.size(); ++r) {
      // Unrocked, a generated route is a plank on smooth terrain.
      EXPECT_LT(eval::measureAttitude(routes[r].T_world_sensor).pitch_sigma_deg, 0.01);
      const eval::AttitudeStatistics a =
          eval::measureAttitude(rockBody(routes[r].T_world_sensor, 1.0, seed * 10 + r));
      const std::string what = "seed " + std::to_string(seed) + " robot " + routes[r].name;
      for (double v : {a.pitch_sigma_deg, a.roll_sigma_deg}) {
        EXPECT_GT(v, sigma_lo - 0.05) << what;
        EXPECT_LT(v, sigma_hi + 0.05) << what;
      }
      for (double v : {a.pitch_p99_deg, a.roll_p99_deg}) {
        EXPECT_GT(v, p99_lo - 0.2) << what;
        EXPECT_LT(v, p99_hi + 0.2) << what;
      }
    }
  }
}

}  // namespace
}  // namespace dcl::sim
