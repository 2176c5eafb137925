// The World mesh and its primitive adders.

#include <cmath>

#include <gtest/gtest.h>

#include <dcl/core/se3.hpp>
#include <dcl/sim/world.hpp>

namespace dcl::sim {
namespace {

/// Sum over triangles of the signed volume against the origin: a closed
/// counter-clockwise mesh gives its enclosed volume.
double enclosedVolume(const World& world) {
  double volume = 0.0;
  for (const auto& t : world.triangles) {
    const Eigen::Vector3d a = world.vertices[t[0]].cast<double>();
    const Eigen::Vector3d b = world.vertices[t[1]].cast<double>();
    const Eigen::Vector3d c = world.vertices[t[2]].cast<double>();
    volume += a.dot(b.cross(c)) / 6.0;
  }
  return volume;
}

TEST(World, BoxHasTwelveOutwardTrianglesAndItsBounds) {
  World world;
  world.addBox(core::makePose2d(10, 20, 0), {4, 2, 3}, Surface::building);
  EXPECT_EQ(world.triangleCount(), 12u);
  EXPECT_EQ(world.vertices.size(), 8u);
  const auto box = world.bounds();
  EXPECT_TRUE(box.min().isApprox(Eigen::Vector3f(8, 19, 0)));
  EXPECT_TRUE(box.max().isApprox(Eigen::Vector3f(12, 21, 3)));
  EXPECT_NEAR(enclosedVolume(world), 24.0, 1e-4);  // positive: faces wind outwards
}

TEST(World, RotatedBoxKeepsItsVolume) {
  World world;
  world.addBox(core::makePose2d(-3, 5, 0.7), {4, 2, 3}, Surface::vehicle);
  EXPECT_NEAR(enclosedVolume(world), 24.0, 1e-3);
  EXPECT_NEAR(world.bounds().max().z(), 3.0f, 1e-6);
}

TEST(World, PrismHasWallsAndAFanRoof) {
  World world;
  const std::vector<Eigen::Vector2d> square = {{0, 0}, {2, 0}, {2, 2}, {0, 2}};
  world.addPrism(square, 1.0, 4.0, Surface::wall);
  EXPECT_EQ(world.triangleCount(), 4u * 2u + 2u);  // two per wall, n - 2 for the roof
  EXPECT_NEAR(world.bounds().min().z(), 1.0f, 1e-6);
  EXPECT_NEAR(world.bounds().max().z(), 4.0f, 1e-6);
  world.addPrism(std::vector<Eigen::Vector2d>{{0, 0}, {1, 0}}, 0, 1, Surface::wall);
  EXPECT_EQ(world.triangleCount(), 10u) << "a degenerate footprint adds nothing";
}

TEST(World, CylinderAndEllipsoidCounts) {
  World world;
  world.addCylinder({1, 2, 0}, 0.5, 3.0, 8, Surface::trunk);
  EXPECT_EQ(world.triangleCount(), 8u * 2u + 6u);
  const auto c = world.bounds();
  EXPECT_NEAR(c.max().x(), 1.5f, 1e-5);
  EXPECT_NEAR(c.max().z(), 3.0f, 1e-6);
  World crown;
  crown.addEllipsoid({0, 0, 5}, {2, 3, 1}, 6, Surface::vegetation);
  EXPECT_EQ(crown.triangleCount(), 6u * 12u * 2u);
  const auto e = crown.bounds();
  EXPECT_NEAR(e.max().x(), 2.0f, 1e-5);
  EXPECT_NEAR(e.max().y(), 3.0f, 0.1f);  // longitude samples miss the exact extreme a little
  EXPECT_NEAR(e.min().z(), 4.0f, 1e-5);
  EXPECT_NEAR(e.max().z(), 6.0f, 1e-5);
}

TEST(World, AppendOffsetsIndicesAndKeepsSurfaces) {
  World a, b;
  a.addBox(core::makePose2d(0, 0, 0), {1, 1, 1}, Surface::building);
  b.addBox(core::makePose2d(5, 0, 0), {1, 1, 1}, Surface::vehicle);
  a.append(b);
  ASSERT_EQ(a.triangleCount(), 24u);
  EXPECT_EQ(a.surfaces[12], Surface::vehicle);
  EXPECT_EQ(a.triangles[12][0], b.triangles[0][0] + 8);
  EXPECT_TRUE(a.vertices[a.triangles[12][0]].isApprox(b.vertices[b.triangles[0][0]]));
  const auto histogram = a.surfaceHistogram();
  EXPECT_EQ(histogram[static_cast<std::size_t>(Surface::building)], 12u);
  EXPECT_EQ(histogram[static_cast<std::size_t>(Surface::vehicle)], 12u);
}

TEST(World, EmptyWorldHasEmptyBounds) {
  EXPECT_TRUE(World().bounds().isEmpty());
  EXPECT_EQ(World().triangleCount(), 0u);
}

TEST(World, ReflectivityIsInRangeAndAsphaltIsDark) {
  for (std::size_t s = 0; s < kSurfaceCount; ++s) {
    const float r = reflectivity(static_cast<Surface>(s));
    EXPECT_GT(r, 0.0f);
    EXPECT_LE(r, 1.0f);
  }
  EXPECT_LT(reflectivity(Surface::road), reflectivity(Surface::vegetation));
}

}  // namespace
}  // namespace dcl::sim
