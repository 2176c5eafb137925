#pragma once

/// Pictures of what the simulator made: a bird's-eye view of a world with the
/// robots' routes, and one scan seen from above.

#include <span>
#include <string>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/trajectory.hpp>
#include <dcl/io/image.hpp>
#include <dcl/sim/traffic.hpp>
#include <dcl/sim/world.hpp>

namespace dcl::sim {

/// Resolution and colouring of the previews.
struct PreviewOptions {
  double metres_per_pixel = 0.5;       ///< world view resolution (coarsened to fit max_pixels)
  int max_pixels = 4000;               ///< longest side of the world view, pixels
  int route_width = 3;                 ///< pixels, width of the route lines
  double scan_half_extent = 60.0;      ///< m, the scan view covers +/- this around the sensor
  double scan_metres_per_pixel = 0.1;  ///< scan view resolution
  bool scan_by_intensity = false;      ///< colour scan points by intensity instead of height
};

/// The colour of a surface class in the world view.
io::Rgb surfaceColour(Surface surface);

/// Route `index`'s colour: its robot's (core::robotColour), as in the report and the map.
io::Rgb routeColour(std::size_t index);

/// The world from above, north up: every triangle projected top-down, the
/// highest one kept per pixel, coloured by surface and brightened with height;
/// the routes drawn over it in routeColour, each start marked by a ringed disc
/// and each end by a square. With `traffic`, its actors where they are halfway
/// through its time span, each a footprint in its surface's colour outlined in
/// white (cars parked for a while in a paler blue).
io::Image renderWorldPreview(const World& world, std::span<const core::Trajectory> routes,
                             const PreviewOptions& options = {}, const Traffic* traffic = nullptr);

/// A scan from above in its sensor frame, x (forward) up, y (left) left: points
/// coloured by height (or intensity), higher points over lower ones, range
/// rings every 20 m, the sensor marked by a cross at the centre.
io::Image renderScanPreview(const core::PointCloud& scan, const PreviewOptions& options = {});

/// renderWorldPreview written as a PNG. Throws core::FileError on a write failure.
void writeWorldPreview(const World& world, std::span<const core::Trajectory> routes,
                       const std::string& png_path, const PreviewOptions& options = {},
                       const Traffic* traffic = nullptr);

/// renderScanPreview written as a PNG. Throws core::FileError on a write failure.
void writeScanPreview(const core::PointCloud& scan, const std::string& png_path,
                      const PreviewOptions& options = {});

}  // namespace dcl::sim
