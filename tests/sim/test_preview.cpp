// Bird's-eye previews of worlds and scans.

#include <filesystem>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/io/image.hpp>
#include <dcl/sim/preview.hpp>

#include "world_test_util.hpp"

namespace dcl::sim {
namespace {

/// A flat 100 x 60 m ground with a 10 m tall building at (50, 30), one route along y = 10.
struct Scene {
  World world;
  std::vector<core::Trajectory> routes;
  Scene() {
    world.addBox(core::makePose2d(50, 30, 0), {100, 60, 0.1}, Surface::ground);
    world.addBox(core::makePose2d(50, 45, 0), {10, 10, 10}, Surface::building);
    routes.push_back(test::straightRoute(10, 10, 70));
  }
};

/// Pixel of world xy for a preview of `scene` at 0.5 m/pixel (5 m margin, north up).
std::pair<int, int> pixelOf(double x, double y, const io::Image& image) {
  return {static_cast<int>((x + 5.0) / 0.5),
          image.height() - 1 - static_cast<int>((y + 5.0) / 0.5)};
}

TEST(Preview, WorldViewShowsSurfacesAndRoutes) {
  const Scene scene;
  PreviewOptions options;
  options.metres_per_pixel = 0.5;
  const io::Image image = renderWorldPreview(scene.world, scene.routes, options);
  EXPECT_EQ(image.width(), 220);   // 100 m plus two 5 m margins
  EXPECT_EQ(image.height(), 140);  // 60 m plus margins
  const auto building = pixelOf(50, 45, image);
  const auto ground = pixelOf(80, 50, image);
  const auto route = pixelOf(40, 10, image);
  const auto start = pixelOf(10, 10, image);
  const io::Rgb b = image.get(building.first, building.second);
  const io::Rgb g = image.get(ground.first, ground.second);
  EXPECT_GT(b.r, b.g) << "buildings are brick red";
  EXPECT_GT(g.g, g.b) << "ground is green";
  EXPECT_EQ(image.get(route.first, route.second), routeColour(0));
  EXPECT_EQ(image.get(start.first, start.second), routeColour(0));
  EXPECT_EQ(image.get(start.first, start.second - 10), (io::Rgb{255, 255, 255})) << "start ring";
}

TEST(Preview, BigWorldsAreCoarsenedToMaxPixels) {
  const Scene scene;
  PreviewOptions options;
  options.metres_per_pixel = 0.01;
  options.max_pixels = 300;
  const io::Image image = renderWorldPreview(scene.world, scene.routes, options);
  EXPECT_EQ(std::max(image.width(), image.height()), 300);
}

TEST(Preview, RouteColoursAreDistinct) {
  for (std::size_t a = 0; a < 30; ++a)
    for (std::size_t b = a + 1; b < 30; ++b)
      EXPECT_NE(routeColour(a), routeColour(b)) << a << " " << b;
}

TEST(Preview, ScanViewPutsPointsWhereTheyAre) {
  core::PointCloud scan;
  scan.points = {{10, 0, -1.7f}, {0, 20, 3.0f}, {0, 20, -1.7f}};
  scan.intensity = {0.1f, 0.9f, 0.5f};
  PreviewOptions options;
  options.scan_half_extent = 30;
  options.scan_metres_per_pixel = 0.5;
  const io::Image image = renderScanPreview(scan, options);
  ASSERT_EQ(image.width(), 120);
  const io::Rgb background = image.get(5, 5);
  const io::Rgb ahead = image.get(60, 60 - 20);  // x forward is up
  const io::Rgb left = image.get(60 - 40, 60);   // y left is left
  EXPECT_NE(ahead, background);
  EXPECT_NE(left, background);
  EXPECT_GT(left.r, ahead.r)
      << "the higher point (3 m) is drawn over the lower one, in a warmer colour";
  options.scan_by_intensity = true;
  EXPECT_NE(renderScanPreview(scan, options).get(60 - 40, 60), left);
}

TEST(Preview, WritesPngFiles) {
  const Scene scene;
  const auto dir = std::filesystem::path(::testing::TempDir()) / "dcl_preview_test";
  std::filesystem::remove_all(dir);
  writeWorldPreview(scene.world, scene.routes, (dir / "world.png").string());
  core::PointCloud scan;
  scan.points = {{5, 5, 0}};
  writeScanPreview(scan, (dir / "scan.png").string());
  EXPECT_EQ(io::readPng((dir / "world.png").string()).width(),
            renderWorldPreview(scene.world, scene.routes).width());
  EXPECT_EQ(io::readPng((dir / "scan.png").string()).width(), 1200);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace dcl::sim
