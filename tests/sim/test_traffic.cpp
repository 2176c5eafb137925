#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/se3.hpp>
#include <dcl/sim/scan_simulator.hpp>
#include <dcl/sim/traffic.hpp>
#include <dcl/sim/world_gen.hpp>

#include "world_test_util.hpp"

namespace dcl::sim {
namespace {

/// Two robots: one winding 600 m along +x, one crossing its street on a
/// straight line along +y a minute later, both at 10 m/s.
std::vector<core::Trajectory> twoRoutes() {
  core::Trajectory crossing;
  for (int i = 0; i <= 200; ++i) {
    crossing.push_back(60.0 + 0.1 * i, test::headingPose(300.0, -100.0 + i, test::kMount, 0, 1));
  }
  return {test::windingRoute(600), crossing};
}

Traffic cityTrafficOf(const std::vector<core::Trajectory>& routes, double density,
                      std::uint64_t seed = 3) {
  return generateTraffic({routes, test::kMount, seed}, cityStyle(), cityTraffic(), density);
}

/// Horizontal distance from `p` to the footprint of `actor` standing at `pose`.
double footprintDistance(const Actor& actor, const ActorPose& pose, const Eigen::Vector2d& p) {
  const Eigen::Vector2d d = p - Eigen::Vector2d(pose.x, pose.y);
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  const Eigen::Vector2d local(c * d.x() + s * d.y(), -s * d.x() + c * d.y());
  double best = std::numeric_limits<double>::infinity();
  for (const ActorBox& b : actor.boxes) {
    const Eigen::Vector2d q = local - b.centre.head<2>().cast<double>();
    best = std::min(best, (q.cwiseAbs() - b.half.head<2>().cast<double>()).cwiseMax(0.0).norm());
  }
  return best;
}

/// How many actors of `kind` are there at time `t`.
std::size_t presentAt(const Traffic& traffic, double t, ActorKind kind) {
  return static_cast<std::size_t>(
      std::count_if(traffic.actors.begin(), traffic.actors.end(),
                    [&](const Actor& a) { return a.kind == kind && a.at(t).has_value(); }));
}

TEST(Traffic, EveryKindMovesAsItShould) {
  const Traffic traffic = cityTrafficOf(twoRoutes(), 1.0);
  for (ActorKind kind :
       {ActorKind::car, ActorKind::cyclist, ActorKind::pedestrian, ActorKind::parked_car}) {
    EXPECT_GT(traffic.count(kind), 0u) << toString(kind);
  }
  // Speeds over each actor's life: cars at 6-13 m/s when cruising, and some
  // standing still for seconds (stops, waiting for a robot, queues);
  // pedestrians at walking pace; parked cars never move.
  std::size_t cars_that_stood = 0;
  for (const Actor& a : traffic.actors) {
    double fastest = 0.0, standing = 0.0, longest_stand = 0.0;
    for (std::size_t i = 1; i < a.poses.size(); ++i) {
      const double v =
          std::hypot(a.poses[i].x - a.poses[i - 1].x, a.poses[i].y - a.poses[i - 1].y) / a.step;
      fastest = std::max(fastest, v);
      standing = v < 0.05 ? standing + a.step : 0.0;
      longest_stand = std::max(longest_stand, standing);
    }
    switch (a.kind) {
      case ActorKind::car:
        EXPECT_LT(fastest, 13.5);
        if (a.poses.size() > 100) {
          EXPECT_GT(fastest, 5.0);
        }
        if (longest_stand >= 2.0) ++cars_that_stood;
        break;
      case ActorKind::cyclist:
        EXPECT_LT(fastest, 6.5);
        break;
      case ActorKind::pedestrian:
        EXPECT_LT(fastest, 2.0);  // 1.6 m/s walking, a little more across a bend
        break;
      case ActorKind::parked_car:
        EXPECT_EQ(fastest, 0.0);
        EXPECT_LT(a.end() - a.start, 0.61 * 80.0);  // parked for part of the time only
        break;
    }
  }
  EXPECT_GT(cars_that_stood, 0u);
}

TEST(Traffic, KeepsOffTheRobotsAndIsDeterministic) {
  const auto routes = twoRoutes();
  const Traffic traffic = cityTrafficOf(routes, 1.0);
  const Traffic again = cityTrafficOf(routes, 1.0);
  ASSERT_EQ(traffic.actors.size(), again.actors.size());
  for (std::size_t i = 0; i < traffic.actors.size(); ++i) {
    const Actor& a = traffic.actors[i];
    const Actor& b = again.actors[i];
    ASSERT_EQ(a.poses.size(), b.poses.size());
    EXPECT_EQ(a.start, b.start);
    for (std::size_t k = 0; k < a.poses.size(); ++k) {
      EXPECT_EQ(a.poses[k].x, b.poses[k].x);
      EXPECT_EQ(a.poses[k].yaw, b.poses[k].yaw);
    }
  }
  // Wherever an actor is, no robot's sensor is within 0.5 m of its footprint
  // (checked every 0.05 s, between the actors' own poses too).
  std::size_t checked = 0;
  for (const auto& route : routes) {
    for (double t = route.stamps().front(); t <= route.stamps().back(); t += 0.05) {
      const Eigen::Vector2d robot = route.at(t)->translation().head<2>();
      for (const Actor& a : traffic.actors) {
        const auto pose = a.at(t);
        if (!pose) continue;
        ++checked;
        ASSERT_GE(footprintDistance(a, *pose, robot), 0.45) << toString(a.kind) << " at t = " << t;
      }
    }
  }
  EXPECT_GT(checked, 10000u);
  // Another seed, other traffic.
  const Traffic other = cityTrafficOf(routes, 1.0, 4);
  EXPECT_NE(other.actors.front().poses.front().x, traffic.actors.front().poses.front().x);
}

TEST(Traffic, DensityScalesWhatIsThere) {
  const auto routes = twoRoutes();
  EXPECT_TRUE(cityTrafficOf(routes, 0.0).empty());
  const Traffic one = cityTrafficOf(routes, 1.0);
  const Traffic three = cityTrafficOf(routes, 3.0);
  std::size_t n1 = 0, n3 = 0;
  for (double t = 5.0; t < 80.0; t += 5.0) {
    for (ActorKind kind : {ActorKind::car, ActorKind::cyclist, ActorKind::pedestrian}) {
      n1 += presentAt(one, t, kind);
      n3 += presentAt(three, t, kind);
    }
  }
  // The city's 66 moving actors a km over about 0.75 km of street: some 50 at a time.
  EXPECT_GT(n1 / 15, 25u);
  EXPECT_LT(n1 / 15, 90u);
  EXPECT_GT(static_cast<double>(n3), 2.2 * static_cast<double>(n1));
  EXPECT_LT(static_cast<double>(n3), 3.8 * static_cast<double>(n1));
}

/// A flat ground quad, 200 m square, around the origin.
World flatGround() {
  World world;
  const auto a = world.addVertex({-100.f, -100.f, 0.f});
  const auto b = world.addVertex({100.f, -100.f, 0.f});
  const auto c = world.addVertex({100.f, 100.f, 0.f});
  const auto d = world.addVertex({-100.f, 100.f, 0.f});
  world.addQuad(a, b, c, d, Surface::road);
  return world;
}

/// A 4 x 2 x 1.5 m box "car" driving along +y at `speed` from y = -20 at t = 0,
/// 10 m ahead of a sensor that stands at the origin.
Traffic oneCar(double speed) {
  Actor car;
  car.kind = ActorKind::car;
  car.surface = Surface::vehicle;
  car.boxes = {{{0.f, 0.f, 0.75f}, {2.f, 1.f, 0.75f}}};
  car.radius = std::sqrt(5.f);
  car.start = 0.0;
  car.step = 0.1;
  for (int k = 0; k <= 60; ++k) {
    const auto y = static_cast<float>(-20.0 + speed * 0.1 * k);
    car.poses.push_back({10.f, y, 0.f, static_cast<float>(M_PI / 2)});
    car.absent.push_back(0);
  }
  return {{car}};
}

core::Trajectory standing() {
  core::Trajectory t;
  t.push_back(0.0, core::makePose2d(0, 0, 0) * Eigen::Translation3d(0, 0, 1.73));
  t.push_back(10.0, core::makePose2d(0, 0, 0) * Eigen::Translation3d(0, 0, 1.73));
  return t;
}

TEST(Traffic, ASweepSeesACarWhereItIsAtEachColumnsTime) {
  const World world = flatGround();
  const ScanOptions exact{.motion_distortion = true, .noise = false, .parallel = false};
  const double speed = 20.0;
  const ScanSimulator with(world, LidarModel::hdl64(), exact, oneCar(speed));
  const ScanSimulator without(world, LidarModel::hdl64(), exact);
  // At t = 1 s the car's middle passes x = 10 right ahead of the sensor.
  const double stamp = 1.0 - LidarModel::hdl64().sweepDuration() / 2;
  const core::Trajectory sensor = standing();
  const core::PointCloud seen = with.scan(sensor, stamp, 1);
  const core::PointCloud ground = without.scan(sensor, stamp, 1);
  // Each beam returns as in the empty street, or from the car's box where the
  // car was at its column's time.
  std::map<std::pair<float, std::uint16_t>, Eigen::Vector3f> street;  // by (column time, ring)
  for (std::size_t i = 0; i < ground.size(); ++i)
    street[{ground.time[i], ground.ring[i]}] = ground.points[i];
  std::size_t on_car = 0;
  for (std::size_t i = 0; i < seen.size(); ++i) {
    const auto it = street.find({seen.time[i], seen.ring[i]});
    if (it != street.end() && it->second == seen.points[i]) continue;
    const Eigen::Vector3f p = seen.points[i] + Eigen::Vector3f(0, 0, 1.73f);
    const double y_car = -20.0 + speed * (stamp + seen.time[i]);
    const double dx = std::abs(p.x() - 10.0), dy = std::abs(p.y() - y_car);
    EXPECT_LT(std::max(dx - 1.0, dy - 2.0), 0.03) << p.transpose();
    EXPECT_LT(p.z(), 1.51);
    ++on_car;
  }
  EXPECT_GT(on_car, 200u);
  // Once the car is gone the sweep is the empty street's, bit for bit.
  const core::PointCloud late = with.scan(sensor, 7.0, 1);
  const core::PointCloud empty = without.scan(sensor, 7.0, 1);
  ASSERT_EQ(late.size(), empty.size());
  EXPECT_TRUE(std::equal(late.points.begin(), late.points.end(), empty.points.begin()));
}

TEST(Traffic, ARobotInACityStreetSeesMovingActors) {
  const auto routes = twoRoutes();
  const WorldRequest request{routes, test::kMount, 3};
  const World world = generateCityWorld(request);
  const ScanOptions options{.motion_distortion = true, .noise = false, .parallel = true};
  const ScanSimulator with(world, LidarModel::hdl64(), options,
                           generateTraffic(request, cityStyle(), cityTraffic(), 1.0));
  const ScanSimulator without(world, LidarModel::hdl64(), options);
  // Along robot a's route, a scan every 5 s: points that are not in the static
  // world's scan (beams that met an actor first) in most of them.
  std::size_t scans_with_actors = 0, scans = 0;
  for (double t = 0.0; t < 55.0; t += 5.0, ++scans) {
    const core::PointCloud a = with.scan(routes[0], t, 1);
    const core::PointCloud b = without.scan(routes[0], t, 1);
    std::map<std::pair<float, std::uint16_t>, float> range;  // by (column time, ring)
    for (std::size_t i = 0; i < b.size(); ++i) range[{b.time[i], b.ring[i]}] = b.points[i].norm();
    std::size_t nearer = 0;  // beams that met something before the static world
    for (std::size_t i = 0; i < a.size(); ++i) {
      const auto it = range.find({a.time[i], a.ring[i]});
      if (it == range.end() || a.points[i].norm() < it->second - 0.3f) ++nearer;
    }
    if (nearer > 100) ++scans_with_actors;
  }
  EXPECT_GE(scans_with_actors, scans / 2) << "of " << scans;
}

}  // namespace
}  // namespace dcl::sim
