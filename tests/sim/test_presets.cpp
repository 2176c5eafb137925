#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/sim/presets.hpp>

namespace dcl::sim {
namespace {

PresetOptions withData() {
  PresetOptions options;
  options.data_dir = DCL_DATA_DIR;
  return options;
}

bool hasKind(const std::vector<Overlap>& overlaps, OverlapKind kind) {
  return std::any_of(overlaps.begin(), overlaps.end(),
                     [&](const Overlap& o) { return o.kind == kind && !o.handover; });
}

TEST(Presets, NamesAreListedInOrder) {
  const std::vector<std::string> expected{"kitti00-3", "kitti05-3", "kitti08-2",
                                          "campus-3",  "campus-9",  "aliasing-3",
                                          "small-3",   "demo",      "crossing-2"};
  EXPECT_EQ(presetNames(), expected);
}

struct Expected {
  std::string name;
  std::string world;
  std::string sensor;
  std::size_t robots;
  bool shared_unit = false;  ///< one car's drive split into robots
};

class EveryPreset : public ::testing::TestWithParam<Expected> {};

TEST_P(EveryPreset, BuildsWithItsWorldSensorAndRobots) {
  const Expected& e = GetParam();
  const Preset p = makePreset(e.name, withData());
  EXPECT_EQ(p.name, e.name);
  EXPECT_EQ(p.world, e.world);
  EXPECT_EQ(p.sensor, e.sensor);
  EXPECT_EQ(p.shared_unit, e.shared_unit);
  EXPECT_FALSE(p.description.empty());
  EXPECT_GT(p.mount_height, 0.5);
  EXPECT_LT(p.mount_height, 2.5);
  ASSERT_EQ(p.routes.size(), e.robots);
  for (std::size_t i = 0; i < p.routes.size(); ++i) {
    EXPECT_EQ(p.routes[i].name, std::string(1, char('a' + i)));
    ASSERT_GT(p.routes[i].T_world_sensor.size(), 100u);
    EXPECT_DOUBLE_EQ(p.routes[i].T_world_sensor.stamp(0), 0.0);
    EXPECT_TRUE(p.routes[i].T_world_sensor.isSorted());
  }
  EXPECT_TRUE(overlapGraphConnected(p.routes.size(), findOverlaps(p.routes)));
}

INSTANTIATE_TEST_SUITE_P(Presets, EveryPreset,
                         ::testing::Values(Expected{"kitti00-3", "city", "hdl64", 3, true},
                                           Expected{"kitti05-3", "city", "hdl64", 3, true},
                                           Expected{"kitti08-2", "city", "hdl64", 2, true},
                                           Expected{"campus-3", "campus", "vlp16", 3},
                                           Expected{"campus-9", "campus", "vlp16", 9},
                                           Expected{"aliasing-3", "aliasing", "vlp16", 3},
                                           Expected{"small-3", "campus", "vlp16", 3},
                                           Expected{"demo", "city", "vlp16", 3},
                                           Expected{"crossing-2", "campus", "vlp16", 2}),
                         [](const ::testing::TestParamInfo<Expected>& info) {
                           std::string name = info.param.name;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

TEST(Presets, SmallIsSmallWithLoopsBetweenRobots) {
  const Preset small = makePreset("small-3");
  ASSERT_EQ(small.routes.size(), 3u);
  for (const Route& r : small.routes) {
    EXPECT_GE(r.length(), 150.0);
    EXPECT_LE(r.length(), 250.0);
    EXPECT_LT(r.duration(), 150.0);
  }
  const std::vector<Overlap> overlaps = findOverlaps(small.routes);
  EXPECT_TRUE(hasKind(overlaps, OverlapKind::opposite_direction));
  EXPECT_TRUE(hasKind(overlaps, OverlapKind::same_direction));
}

/// Whether routes `a` and `b` drive a stretch together the same way.
bool shareSameDirection(const std::vector<Overlap>& overlaps, std::size_t a, std::size_t b) {
  return std::any_of(overlaps.begin(), overlaps.end(), [&](const Overlap& o) {
    return o.kind == OverlapKind::same_direction && !o.handover &&
           ((o.robot_a == a && o.robot_b == b) || (o.robot_a == b && o.robot_b == a));
  });
}

TEST(Presets, DemoCarsDriveLongLoopsWithTheirNeighbours) {
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    PresetOptions options;
    options.seed = seed;
    const Preset demo = makePreset("demo", options);
    ASSERT_EQ(demo.routes.size(), 3u);
    for (const Route& r : demo.routes) {
      // A car's loop: long enough for its odometry to drift, short enough
      // for the demo's two minutes.
      EXPECT_GE(r.length(), 550.0) << r.name;
      EXPECT_LE(r.length(), 650.0) << r.name;
      EXPECT_LT(r.duration(), 120.0) << r.name;
      EXPECT_GT(r.length() / r.duration(), 5.0) << r.name;
    }
    // The blocks in a column: a shares a street with b, b with c, each the same way.
    const std::vector<Overlap> overlaps = findOverlaps(demo.routes);
    EXPECT_TRUE(shareSameDirection(overlaps, 0, 1)) << seed;
    EXPECT_TRUE(shareSameDirection(overlaps, 1, 2)) << seed;
    EXPECT_FALSE(hasKind(overlaps, OverlapKind::opposite_direction)) << seed;
  }
}

TEST(Presets, OptionsChangeSensorRobotsAndSeed) {
  PresetOptions options;
  options.sensor = "hdl64";
  options.robots = 5;
  const Preset campus = makePreset("campus-3", options);
  EXPECT_EQ(campus.sensor, "hdl64");
  EXPECT_EQ(campus.routes.size(), 5u);
  EXPECT_EQ(makePreset("aliasing-3", options).routes.size(), 5u);

  PresetOptions seeded;
  seeded.seed = 9;
  const Preset a = makePreset("campus-9", seeded);
  const Preset b = makePreset("campus-9", seeded);
  EXPECT_EQ(a.seed, 9u);
  EXPECT_EQ(a.routes[4].T_world_sensor.pose(200).matrix(),
            b.routes[4].T_world_sensor.pose(200).matrix());
  seeded.seed = 10;
  const Preset c = makePreset("campus-9", seeded);
  EXPECT_FALSE(a.routes[0].T_world_odom().isApprox(c.routes[0].T_world_odom()));
}

TEST(Presets, BodyMotionRocksGeneratedRoutesOnly) {
  PresetOptions rocking = withData();
  rocking.body_motion = true;
  // A generated route gets its body's pitch and roll, on the same path.
  const Preset plank = makePreset("small-3", withData());
  const Preset car = makePreset("small-3", rocking);
  ASSERT_EQ(plank.routes[0].T_world_sensor.size(), car.routes[0].T_world_sensor.size());
  double largest_tilt = 0.0;
  for (std::size_t i = 0; i < plank.routes[0].T_world_sensor.size(); ++i) {
    const Eigen::Isometry3d a = plank.routes[0].T_world_sensor.pose(i);
    const Eigen::Isometry3d b = car.routes[0].T_world_sensor.pose(i);
    EXPECT_LT((a.translation() - b.translation()).norm(), 0.1) << i;  // a metre's mast, a few deg
    largest_tilt =
        std::max(largest_tilt, Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle());
  }
  EXPECT_GT(largest_tilt, 0.2 * M_PI / 180);
  // KITTI's ground truth is a real car's, rocking already: untouched.
  const Preset kitti = makePreset("kitti05-3", withData());
  const Preset kitti_rocking = makePreset("kitti05-3", rocking);
  EXPECT_EQ(kitti.routes[2].T_world_sensor.pose(500).matrix(),
            kitti_rocking.routes[2].T_world_sensor.pose(500).matrix());
}

TEST(Presets, KittiPresetsKeepTheirRobotCount) {
  PresetOptions options = withData();
  options.robots = 3;
  EXPECT_EQ(makePreset("kitti05-3", options).routes.size(), 3u);
  options.robots = 4;
  EXPECT_THROW(makePreset("kitti05-3", options), core::Error);
  EXPECT_THROW(makePreset("kitti08-2"), core::Error);  // no data folder
}

TEST(Presets, ErrorsNameTheChoices) {
  try {
    makePreset("kitti99-3");
    FAIL() << "an unknown preset was accepted";
  } catch (const core::Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("kitti99-3"), std::string::npos);
    for (const std::string& name : presetNames()) EXPECT_NE(what.find(name), std::string::npos);
  }
  PresetOptions options;
  options.sensor = "os1-64";
  EXPECT_THROW(makePreset("small-3", options), core::Error);
  options.sensor.clear();
  options.robots = -1;
  EXPECT_THROW(makePreset("small-3", options), core::Error);
}

}  // namespace
}  // namespace dcl::sim
