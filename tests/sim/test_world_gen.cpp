// Procedural worlds: determinism, nothing on the routes, road under every
// pose, surface classes, sizes, and the aliasing world's repetition.

#include <algorithm>
#include <cstring>
#include <map>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/sim/world_gen.hpp>

#include "world_test_util.hpp"

namespace dcl::sim {
namespace {

using test::kMount;

World city(const std::vector<core::Trajectory>& routes, std::uint64_t seed = 7) {
  return generateCityWorld({routes, kMount, seed});
}

bool sameMesh(const World& a, const World& b) {
  return a.vertices.size() == b.vertices.size() && a.triangles == b.triangles &&
         a.surfaces == b.surfaces &&
         std::memcmp(a.vertices.data(), b.vertices.data(),
                     a.vertices.size() * sizeof(Eigen::Vector3f)) == 0;
}

TEST(WorldGen, SameSeedSameWorldOtherSeedOtherWorld) {
  const std::vector<core::Trajectory> routes = {test::windingRoute(250)};
  const World a = city(routes, 7), b = city(routes, 7), c = city(routes, 8);
  EXPECT_TRUE(sameMesh(a, b));
  EXPECT_FALSE(sameMesh(a, c));
  EXPECT_GT(a.triangleCount(), 10000u);
}

/// Checks the two promises for every pose of every route.
void expectRoutesClear(const World& world, const std::vector<core::Trajectory>& routes) {
  EXPECT_EQ(test::obstaclesNearRoutes(world, routes, 3.0), 0u)
      << "triangles other than road, kerb and ground within 3 m of a route pose";
  std::size_t checked = 0;
  for (const auto& route : routes) {
    for (const auto& T : route.poses()) {
      const auto hit = test::castDown(world, T.translation());
      ASSERT_TRUE(hit) << "no ground under " << T.translation().transpose();
      EXPECT_EQ(hit->surface, Surface::road) << "at " << T.translation().transpose();
      EXPECT_NEAR(T.translation().z() - hit->z, kMount, 0.05)
          << "at " << T.translation().transpose();
      ++checked;
    }
  }
  EXPECT_GT(checked, 100u);
}

TEST(WorldGen, CityKeepsWindingClimbingRoutesClearWithRoadAtMountHeight) {
  // A winding climb, the same street driven back a lane over, and two level
  // streets crossing each other beside it.
  std::vector<core::Trajectory> routes = {test::windingRoute(220)};
  core::Trajectory back;
  for (std::size_t i = routes[0].size(); i-- > 0;) {
    Eigen::Isometry3d T = routes[0].pose(i);
    T.linear() = T.linear() * Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() += T.linear() * Eigen::Vector3d(0, 3.0, 0);  // its right lane: 3 m across
    back.push_back(0.1 * back.size(), T);
  }
  routes.push_back(back);
  routes.push_back(test::straightRoute(0, 80, 200));
  routes.push_back(test::straightRoute(0, 0, 150));
  routes.back().transformWorld(core::makePose2d(100, 20, M_PI / 2));
  expectRoutesClear(city(routes), routes);
}

TEST(WorldGen, CityAroundRealKittiGroundTruthKeepsItClear) {
  const std::vector<core::Trajectory> routes = {test::kittiExcerpt(250)};
  expectRoutesClear(city(routes), routes);
}

TEST(WorldGen, CampusAndAliasingKeepRoutesClear) {
  // A winding climb and, on a parallel level street 60 m away, a route the other way.
  const std::vector<core::Trajectory> routes = {test::windingRoute(200),
                                                test::straightRoute(200, 60, 200, -1)};
  expectRoutesClear(generateCampusWorld({routes, kMount, 3}), routes);
  expectRoutesClear(generateAliasingWorld({routes, kMount, 3}), routes);
}

TEST(WorldGen, CityHasEverySurfaceClass) {
  const World world = city({test::windingRoute(400)});
  const auto histogram = world.surfaceHistogram();
  for (std::size_t s = 0; s < kSurfaceCount; ++s) {
    if (static_cast<Surface>(s) == Surface::person) continue;  // moving actors only (traffic)
    EXPECT_GT(histogram[s], 0u) << "no triangles of surface " << s;
  }
}

TEST(WorldGen, GeometryStaysWithinTheExtent) {
  const std::vector<core::Trajectory> routes = {test::straightRoute(0, 0, 100)};
  WorldStyle style = cityStyle();
  style.extent = 60.0;
  const auto box = generateWorld({routes, kMount, 1}, style).bounds();
  const double tile_slack = 16.0 * std::sqrt(2.0);  // ground comes in whole 16 m tiles
  EXPECT_GT(box.min().x(), -60.0 - tile_slack);
  EXPECT_LT(box.max().x(), 160.0 + tile_slack);
  EXPECT_LT(box.max().y(), 60.0 + tile_slack);
  EXPECT_GT(box.max().y(), 40.0) << "the ground reaches out towards the extent";
}

TEST(WorldGen, CampusIsLowerAndGreenerThanTheCity) {
  const std::vector<core::Trajectory> routes = {test::straightRoute(0, 0, 400)};
  const World c = city(routes), k = generateCampusWorld({routes, kMount, 7});
  const auto top = [](const World& w, Surface s) {
    float z = -1e9f;
    for (std::size_t t = 0; t < w.triangleCount(); ++t)
      if (w.surfaces[t] == s)
        for (auto v : w.triangles[t]) z = std::max(z, w.vertices[v].z());
    return z;
  };
  // Four storeys at most, a roof parapet (1.5 m), a cornice (0.3 m), the terrain's relief (1 m).
  EXPECT_LT(top(k, Surface::building), 4 * 3.0 + 1.5 + 0.3 + campusStyle().terrain_amplitude);
  EXPECT_GT(top(c, Surface::building), top(k, Surface::building));
  // By area: a shrub's many small triangles cover less than a facade's two.
  const auto share = [](const World& w, Surface s) {
    double of = 0.0, all = 0.0;
    for (std::size_t t = 0; t < w.triangleCount(); ++t) {
      const auto& v = w.triangles[t];
      const Eigen::Vector3f a = w.vertices[v[1]] - w.vertices[v[0]];
      const Eigen::Vector3f b = w.vertices[v[2]] - w.vertices[v[0]];
      const double area = 0.5 * a.cross(b).norm();
      all += area;
      if (w.surfaces[t] == s) of += area;
    }
    return of / all;
  };
  EXPECT_GT(share(k, Surface::vegetation), share(c, Surface::vegetation));
}

/// Centroids of the props (everything above the street) whose centroid x lies in [x0, x1),
/// shifted by -x0 and rounded to centimetres, with their surfaces, sorted.
std::vector<std::tuple<int, long, long, long>> propsIn(const World& world, double x0, double x1) {
  std::vector<std::tuple<int, long, long, long>> out;
  for (std::size_t t = 0; t < world.triangleCount(); ++t) {
    const Surface s = world.surfaces[t];
    if (s == Surface::ground || s == Surface::road) continue;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (auto v : world.triangles[t]) c += world.vertices[v].cast<double>() / 3.0;
    if (c.x() < x0 || c.x() >= x1) continue;
    out.emplace_back(static_cast<int>(s), std::lround((c.x() - x0) * 100), std::lround(c.y() * 100),
                     std::lround(c.z() * 100));
  }
  std::sort(out.begin(), out.end());
  return out;
}

TEST(WorldGen, AliasingBlocksRepeatWithTheirPeriod) {
  const double period = aliasingStyle().repeat_period;
  for (const double direction : {1.0, -1.0}) {
    // Driving +x from 0 or -x from 480: the same street, blocks at the same places.
    const std::vector<core::Trajectory> routes = {
        test::straightRoute(direction > 0 ? 0 : 480, 0, 480, direction)};
    const World world = generateAliasingWorld({routes, kMount, 11});
    const auto first = propsIn(world, 2 * period, 3 * period);
    EXPECT_GT(first.size(), 500u);
    for (int k = 3; k < 7; ++k) {
      const auto other = propsIn(world, k * period, (k + 1) * period);
      EXPECT_EQ(other.size(), first.size()) << "block " << k;
      EXPECT_TRUE(other == first) << "block " << k << " differs from block 2";
    }
  }
  const World plus =
      generateAliasingWorld({std::vector{test::straightRoute(0, 0, 480)}, kMount, 11});
  const World minus =
      generateAliasingWorld({std::vector{test::straightRoute(480, 0, 480, -1)}, kMount, 11});
  EXPECT_TRUE(propsIn(plus, 3 * period, 4 * period) == propsIn(minus, 3 * period, 4 * period))
      << "a block looks the same whichever way the route runs";
}

TEST(WorldGen, CityBlocksDoNotRepeat) {
  const World world = city({test::straightRoute(0, 0, 480)});
  const double period = aliasingStyle().repeat_period;
  EXPECT_FALSE(propsIn(world, 2 * period, 3 * period) == propsIn(world, 3 * period, 4 * period));
}

}  // namespace
}  // namespace dcl::sim
