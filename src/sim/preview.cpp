#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <dcl/core/colour.hpp>
#include <dcl/sim/preview.hpp>

namespace dcl::sim {

namespace {

/// Maps world xy to pixel coordinates of a north-up raster.
struct Raster {
  Eigen::Vector2d min;  ///< world xy of the image's lower-left corner
  double mpp = 1.0;     ///< metres per pixel
  int width = 1;
  int height = 1;

  [[nodiscard]] Eigen::Vector2d toPixel(const Eigen::Vector2d& xy) const {
    return {(xy.x() - min.x()) / mpp, height - (xy.y() - min.y()) / mpp};
  }
  [[nodiscard]] Eigen::Vector2d toWorld(const Eigen::Vector2d& pixel) const {
    return {min.x() + pixel.x() * mpp, min.y() + (height - pixel.y()) * mpp};
  }
};

io::Rgb scaled(io::Rgb c, double f) {
  const auto s = [f](std::uint8_t v) {
    return static_cast<std::uint8_t>(std::clamp(v * f, 0.0, 255.0));
  };
  return {s(c.r), s(c.g), s(c.b)};
}

io::Rgb lerp(io::Rgb a, io::Rgb b, double t) {
  const auto l = [t](std::uint8_t x, std::uint8_t y) {
    return static_cast<std::uint8_t>(std::lround(x + t * (y - x)));
  };
  return {l(a.r, b.r), l(a.g, b.g), l(a.b, b.b)};
}

/// Blue - cyan - green - yellow - red over t in [0, 1].
io::Rgb colourMap(double t) {
  static const io::Rgb stops[] = {
      {40, 40, 200}, {0, 200, 220}, {40, 200, 60}, {240, 220, 0}, {230, 40, 30}};
  t = std::clamp(t, 0.0, 1.0) * 4.0;
  const int i = std::min(3, static_cast<int>(t));
  return lerp(stops[i], stops[i + 1], t - i);
}

void fillDisc(io::Image& image, const Eigen::Vector2d& c, double radius, io::Rgb colour) {
  const int r = static_cast<int>(std::ceil(radius));
  const int cx = static_cast<int>(std::floor(c.x())), cy = static_cast<int>(std::floor(c.y()));
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx)
      if (dx * dx + dy * dy <= radius * radius) image.set(cx + dx, cy + dy, colour);
}

void drawLine(io::Image& image, const Eigen::Vector2d& a, const Eigen::Vector2d& b, double width,
              io::Rgb colour) {
  const int steps = std::max(1, static_cast<int>(std::ceil((b - a).norm() * 2.0)));
  for (int i = 0; i <= steps; ++i) fillDisc(image, a + (b - a) * i / steps, width / 2, colour);
}

void drawCircle(io::Image& image, const Eigen::Vector2d& c, double radius, io::Rgb colour) {
  const int steps = std::max(16, static_cast<int>(radius * 8));
  for (int i = 0; i < steps; ++i) {
    const double a = 2.0 * M_PI * i / steps;
    image.set(static_cast<int>(c.x() + radius * std::cos(a)),
              static_cast<int>(c.y() + radius * std::sin(a)), colour);
  }
}

Raster worldRaster(const World& world, std::span<const core::Trajectory> routes,
                   const PreviewOptions& options) {
  Eigen::AlignedBox2d box;
  for (const auto& v : world.vertices) box.extend(v.head<2>().cast<double>());
  for (const auto& route : routes)
    for (const auto& T : route.poses()) box.extend(T.translation().head<2>());
  if (box.isEmpty()) box.extend(Eigen::Vector2d::Zero());
  box.min().array() -= 5.0;
  box.max().array() += 5.0;
  const Eigen::Vector2d size = box.sizes();
  Raster raster;
  raster.min = box.min();
  raster.mpp =
      std::max(options.metres_per_pixel, size.maxCoeff() / std::max(1, options.max_pixels));
  raster.width = std::max(1, static_cast<int>(std::ceil(size.x() / raster.mpp)));
  raster.height = std::max(1, static_cast<int>(std::ceil(size.y() / raster.mpp)));
  return raster;
}

/// Per pixel: the height of the highest triangle and its surface (none: -inf).
struct TopView {
  std::vector<float> z;
  std::vector<Surface> surface;
};

void rasterizeTriangle(const Raster& raster, const std::array<Eigen::Vector3d, 3>& v, Surface s,
                       TopView& top) {
  std::array<Eigen::Vector2d, 3> p;
  for (int i = 0; i < 3; ++i) p[i] = raster.toPixel(v[i].head<2>());
  const double area = (p[1] - p[0]).x() * (p[2] - p[0]).y() - (p[1] - p[0]).y() * (p[2] - p[0]).x();
  if (std::abs(area) < 1e-12) return;
  const int x0 =
      std::max(0, static_cast<int>(std::floor(std::min({p[0].x(), p[1].x(), p[2].x()}))));
  const int x1 =
      std::min(raster.width - 1, static_cast<int>(std::max({p[0].x(), p[1].x(), p[2].x()})));
  const int y0 =
      std::max(0, static_cast<int>(std::floor(std::min({p[0].y(), p[1].y(), p[2].y()}))));
  const int y1 =
      std::min(raster.height - 1, static_cast<int>(std::max({p[0].y(), p[1].y(), p[2].y()})));
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const Eigen::Vector2d q(x + 0.5, y + 0.5);
      const auto edge = [&](int i, int j) {
        return ((p[j] - p[i]).x() * (q - p[i]).y() - (p[j] - p[i]).y() * (q - p[i]).x()) / area;
      };
      const double w0 = edge(1, 2), w1 = edge(2, 0), w2 = edge(0, 1);
      if (w0 < 0 || w1 < 0 || w2 < 0) continue;
      const auto z = static_cast<float>(w0 * v[0].z() + w1 * v[1].z() + w2 * v[2].z());
      const std::size_t i = static_cast<std::size_t>(y) * raster.width + x;
      if (z <= top.z[i]) continue;
      top.z[i] = z;
      top.surface[i] = s;
    }
  }
}

TopView topView(const World& world, const Raster& raster) {
  const std::size_t n = static_cast<std::size_t>(raster.width) * raster.height;
  TopView top{std::vector<float>(n, -std::numeric_limits<float>::infinity()),
              std::vector<Surface>(n, Surface::ground)};
  for (std::size_t t = 0; t < world.triangles.size(); ++t) {
    std::array<Eigen::Vector3d, 3> v;
    for (int k = 0; k < 3; ++k) v[k] = world.vertices[world.triangles[t][k]].cast<double>();
    rasterizeTriangle(raster, v, world.surfaces[t], top);
  }
  return top;
}

void paintTopView(io::Image& image, const TopView& top, const World& world) {
  const Eigen::AlignedBox3f bounds = world.bounds();
  const double z0 = bounds.isEmpty() ? 0.0 : bounds.min().z();
  const double span = bounds.isEmpty() ? 1.0 : std::max(1.0f, bounds.max().z() - bounds.min().z());
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * image.width() + x;
      if (!std::isfinite(top.z[i])) continue;
      const double t = (top.z[i] - z0) / span;
      image.set(x, y, scaled(surfaceColour(top.surface[i]), 0.55 + 0.6 * t));
    }
  }
}

void drawRoutes(io::Image& image, const Raster& raster, std::span<const core::Trajectory> routes,
                const PreviewOptions& options) {
  const double width = std::max(1, options.route_width);
  for (std::size_t r = 0; r < routes.size(); ++r) {
    const auto& poses = routes[r].poses();
    for (std::size_t i = 1; i < poses.size(); ++i)
      drawLine(image, raster.toPixel(poses[i - 1].translation().head<2>()),
               raster.toPixel(poses[i].translation().head<2>()), width, routeColour(r));
  }
  for (std::size_t r = 0; r < routes.size(); ++r) {
    if (routes[r].empty()) continue;
    const Eigen::Vector2d start = raster.toPixel(routes[r].poses().front().translation().head<2>());
    const Eigen::Vector2d end = raster.toPixel(routes[r].poses().back().translation().head<2>());
    fillDisc(image, start, 3 * width + 2, {255, 255, 255});
    fillDisc(image, start, 3 * width, routeColour(r));
    for (int dy = -2 * width; dy <= 2 * width; ++dy)
      for (int dx = -2 * width; dx <= 2 * width; ++dx)
        image.set(static_cast<int>(end.x()) + dx, static_cast<int>(end.y()) + dy,
                  std::abs(dx) == 2 * width || std::abs(dy) == 2 * width ? io::Rgb{255, 255, 255}
                                                                         : routeColour(r));
  }
}

/// Every actor of `traffic` where it is halfway through the traffic's time
/// span: its footprint filled, outlined in white.
void drawTraffic(io::Image& image, const Raster& raster, const Traffic& traffic) {
  double t0 = std::numeric_limits<double>::infinity(), t1 = -t0;
  for (const Actor& a : traffic.actors) {
    if (a.poses.empty()) continue;
    t0 = std::min(t0, a.start);
    t1 = std::max(t1, a.end());
  }
  const double t = (t0 + t1) / 2;
  for (const Actor& a : traffic.actors) {
    const auto pose = a.at(t);
    if (!pose) continue;
    const Eigen::Vector2d half = a.footprint().cast<double>();
    const Eigen::Vector2d centre(pose->x, pose->y);
    const Eigen::Vector2d along(std::cos(pose->yaw), std::sin(pose->yaw));
    const Eigen::Vector2d left(-along.y(), along.x());
    // At least two pixels across, so that a pedestrian shows at coarse scales.
    const double ha = std::max(half.x(), raster.mpp), hb = std::max(half.y(), raster.mpp);
    const double outline = raster.mpp;
    const io::Rgb fill =
        a.kind == ActorKind::parked_car ? io::Rgb{150, 190, 250} : surfaceColour(a.surface);
    const Eigen::Vector2d reach = Eigen::Vector2d::Constant((ha + hb + outline) / raster.mpp);
    const Eigen::Vector2d lo = raster.toPixel(centre) - reach;
    const Eigen::Vector2d hi = raster.toPixel(centre) + reach;
    for (int y = static_cast<int>(lo.y()); y <= static_cast<int>(hi.y()); ++y) {
      for (int x = static_cast<int>(lo.x()); x <= static_cast<int>(hi.x()); ++x) {
        const Eigen::Vector2d d = raster.toWorld({x + 0.5, y + 0.5}) - centre;
        const double u = std::abs(d.dot(along)), v = std::abs(d.dot(left));
        if (u > ha + outline || v > hb + outline) continue;
        image.set(x, y, u > ha || v > hb ? io::Rgb{255, 255, 255} : fill);
      }
    }
  }
}

}  // namespace

io::Rgb surfaceColour(Surface surface) {
  switch (surface) {
    case Surface::ground:
      return {125, 145, 95};
    case Surface::road:
      return {75, 75, 80};
    case Surface::kerb:
      return {175, 172, 160};
    case Surface::building:
      return {205, 130, 95};
    case Surface::vegetation:
      return {45, 150, 50};
    case Surface::trunk:
      return {115, 85, 55};
    case Surface::pole:
      return {235, 230, 70};
    case Surface::vehicle:
      return {60, 110, 225};
    case Surface::wall:
      return {160, 155, 180};
    case Surface::person:
      return {240, 60, 200};
  }
  return {255, 0, 255};
}

io::Rgb routeColour(std::size_t index) {
  const std::array<std::uint8_t, 3> c = core::robotColour(index);
  return {c[0], c[1], c[2]};
}

io::Image renderWorldPreview(const World& world, std::span<const core::Trajectory> routes,
                             const PreviewOptions& options, const Traffic* traffic) {
  const Raster raster = worldRaster(world, routes, options);
  io::Image image(raster.width, raster.height, {250, 250, 250});
  paintTopView(image, topView(world, raster), world);
  drawRoutes(image, raster, routes, options);
  if (traffic != nullptr) drawTraffic(image, raster, *traffic);
  return image;
}

io::Image renderScanPreview(const core::PointCloud& scan, const PreviewOptions& options) {
  const int size =
      std::max(1, static_cast<int>(2 * options.scan_half_extent / options.scan_metres_per_pixel));
  io::Image image(size, size, {18, 18, 24});
  const Eigen::Vector2d centre(size / 2.0, size / 2.0);
  for (double r = 20.0; r <= options.scan_half_extent; r += 20.0)
    drawCircle(image, centre, r / options.scan_metres_per_pixel, {70, 70, 80});
  std::vector<std::size_t> order(scan.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return scan.points[a].z() < scan.points[b].z();
  });
  const bool by_intensity = options.scan_by_intensity && scan.hasIntensity();
  for (const std::size_t i : order) {
    const Eigen::Vector3f& p = scan.points[i];
    const double t = by_intensity ? scan.intensity[i] : (p.z() + 2.5) / 8.0;
    const Eigen::Vector2d px =
        centre - Eigen::Vector2d(p.y(), p.x()) / options.scan_metres_per_pixel;
    image.set(static_cast<int>(std::floor(px.x())), static_cast<int>(std::floor(px.y())),
              colourMap(t));
  }
  for (int d = -6; d <= 6; ++d) {
    image.set(size / 2 + d, size / 2, {255, 255, 255});
    image.set(size / 2, size / 2 + d, {255, 255, 255});
  }
  return image;
}

void writeWorldPreview(const World& world, std::span<const core::Trajectory> routes,
                       const std::string& png_path, const PreviewOptions& options,
                       const Traffic* traffic) {
  io::writePng(png_path, renderWorldPreview(world, routes, options, traffic));
}

void writeScanPreview(const core::PointCloud& scan, const std::string& png_path,
                      const PreviewOptions& options) {
  io::writePng(png_path, renderScanPreview(scan, options));
}

}  // namespace dcl::sim
