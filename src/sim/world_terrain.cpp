// The ground height field, the ground mesh and the road strips with their pavements.

#include <algorithm>
#include <cmath>

#include "world_detail.hpp"

namespace dcl::sim::detail {

namespace {

constexpr double kTile = 16.0;             // m, ground tile
constexpr double kFineRadius = 50.0;       // m, tiles nearer a route get fine cells
constexpr double kCoarseGroundCell = 8.0;  // m, ground cell far from routes
constexpr double kUnderRoad = 0.05;        // m, ground sunk under roads and pavements
constexpr double kRoadOverhang = 3.0;      // m, road strip beyond the first and last sample
constexpr double kPavementPiece = 4.0;     // m, pavement box length along the road

double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

/// A hash of a lattice point mapped to [-1, 1].
double latticeValue(std::int64_t x, std::int64_t y, std::uint64_t seed) {
  const std::uint64_t h =
      mix(mix(seed, static_cast<std::uint64_t>(x)), static_cast<std::uint64_t>(y));
  return static_cast<double>(h >> 11) * 0x1.0p-52 - 1.0;
}

}  // namespace

Terrain::Terrain(const RouteIndex& index, const WorldStyle& style, std::uint64_t seed)
    : index_(index), style_(style), seed_(mix(seed, 0x7e77a1)) {}

double Terrain::valueNoise(const Eigen::Vector2d& p, std::uint64_t octave) const {
  const double fx = std::floor(p.x()), fy = std::floor(p.y());
  const auto x = static_cast<std::int64_t>(fx), y = static_cast<std::int64_t>(fy);
  const double tx = smoothstep(p.x() - fx), ty = smoothstep(p.y() - fy);
  const std::uint64_t s = mix(seed_, octave);
  const double v0 =
      latticeValue(x, y, s) + tx * (latticeValue(x + 1, y, s) - latticeValue(x, y, s));
  const double v1 =
      latticeValue(x, y + 1, s) + tx * (latticeValue(x + 1, y + 1, s) - latticeValue(x, y + 1, s));
  return v0 + ty * (v1 - v0);
}

double Terrain::relief(const Eigen::Vector2d& p) const {
  if (style_.terrain_amplitude == 0.0) return 0.0;
  const double broad = valueNoise(p / 90.0, 0), detail = valueNoise(p / 35.0, 1);
  return style_.terrain_amplitude * (0.7 * broad + 0.3 * detail);
}

double Terrain::height(const Eigen::Vector2d& p) const {
  const double inner = style_.road_half_width + style_.pavement_width;
  const auto near = index_.nearest(p, inner + style_.terrain_blend, true);
  if (near && near->distance <= inner) return near->z_road;
  const double far = index_.smoothRoadHeight(p, 100.0) + relief(p);
  if (!near) return far;
  const double t = smoothstep((near->distance - inner) / style_.terrain_blend);
  return near->z_road + t * (far - near->z_road);
}

double Terrain::groundVertexHeight(const Eigen::Vector2d& p) const {
  const double inner = style_.road_half_width + style_.pavement_width;
  if (index_.nearest(p, inner, true)) return height(p) - kUnderRoad;
  const auto qx = static_cast<std::int64_t>(std::llround(p.x() * 100.0));
  const auto qy = static_cast<std::int64_t>(std::llround(p.y() * 100.0));
  return height(p) + style_.ground_roughness * latticeValue(qx, qy, mix(seed_, 2));
}

double Terrain::routeDistance(const Eigen::Vector2d& p) const {
  const auto near = index_.nearest(p, style_.extent);
  return near ? near->distance : style_.extent;
}

namespace {

using TileKey = std::pair<int, int>;

/// Tiles within reach of some route sample (a superset of those within the extent).
std::vector<TileKey> candidateTiles(const RouteIndex& index, double extent) {
  std::vector<TileKey> tiles;
  const int reach = static_cast<int>(std::ceil(extent / kTile)) + 1;
  for (std::size_t r = 0; r < index.routeCount(); ++r) {
    double next = 0.0;
    for (const RouteSample& sample : index.samples(r)) {
      if (sample.s < next) continue;
      next = sample.s + kTile / 2;
      const int cx = static_cast<int>(std::floor(sample.xy.x() / kTile));
      const int cy = static_cast<int>(std::floor(sample.xy.y() / kTile));
      for (int dx = -reach; dx <= reach; ++dx)
        for (int dy = -reach; dy <= reach; ++dy) tiles.emplace_back(cx + dx, cy + dy);
    }
  }
  std::sort(tiles.begin(), tiles.end());
  tiles.erase(std::unique(tiles.begin(), tiles.end()), tiles.end());
  return tiles;
}

void addTile(World& world, const Terrain& terrain, const Eigen::Vector2d& corner, double cell) {
  const int n = static_cast<int>(std::lround(kTile / cell));
  const auto first = static_cast<std::uint32_t>(world.vertices.size());
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const Eigen::Vector2d p = corner + cell * Eigen::Vector2d(i, j);
      world.addVertex(Eigen::Vector3d(p.x(), p.y(), terrain.groundVertexHeight(p)).cast<float>());
    }
  }
  const auto at = [&](int i, int j) { return first + static_cast<std::uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      world.addQuad(at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1), Surface::ground);
}

}  // namespace

void addGround(World& world, const Terrain& terrain, const RouteIndex& index,
               const WorldStyle& style) {
  const double half_diagonal = kTile * std::sqrt(0.5);
  for (const auto& [tx, ty] : candidateTiles(index, style.extent)) {
    const Eigen::Vector2d corner(tx * kTile, ty * kTile);
    const Eigen::Vector2d centre = corner + Eigen::Vector2d::Constant(kTile / 2);
    const auto near = index.nearest(centre, style.extent + half_diagonal);
    if (!near) continue;
    addTile(world, terrain, corner,
            near->distance < kFineRadius ? style.ground_cell : kCoarseGroundCell);
  }
}

namespace {

Eigen::Vector2d leftNormal(const std::vector<RouteSample>& samples, std::size_t i) {
  const std::size_t a = i > 0 ? i - 1 : 0, b = std::min(i + 1, samples.size() - 1);
  const Eigen::Vector2d d = samples[b].xy - samples[a].xy;
  if (d.norm() < 1e-9) return Eigen::Vector2d::UnitY();
  return Eigen::Vector2d(-d.y(), d.x()).normalized();
}

/// The route's samples with a sample added kRoadOverhang before the first and after the last.
std::vector<RouteSample> withOverhang(const std::vector<RouteSample>& samples) {
  std::vector<RouteSample> out = samples;
  if (samples.size() < 2) return out;
  const auto extend = [](const RouteSample& end, const RouteSample& inner) {
    RouteSample extra = end;
    extra.xy = end.xy + kRoadOverhang * (end.xy - inner.xy).normalized();
    return extra;
  };
  out.insert(out.begin(), extend(samples[0], samples[1]));
  out.push_back(extend(samples.back(), samples[samples.size() - 2]));
  return out;
}

/// Lateral vertices of a road cross-section, as fractions of the half width.
constexpr std::array<double, 3> kAcross = {-1.0, 0.0, 1.0};

void addRoadStrip(World& world, const std::vector<RouteSample>& samples, double half_width) {
  const auto first = static_cast<std::uint32_t>(world.vertices.size());
  const auto across = static_cast<std::uint32_t>(kAcross.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const Eigen::Vector2d n = leftNormal(samples, i);
    for (const double f : kAcross) {
      const Eigen::Vector2d p = samples[i].xy + f * half_width * n;
      world.addVertex(Eigen::Vector3f(float(p.x()), float(p.y()), float(samples[i].z_road)));
    }
  }
  for (std::uint32_t i = 0; i + 1 < samples.size(); ++i) {
    for (std::uint32_t k = 0; k + 1 < across; ++k) {
      const std::uint32_t a = first + across * i + k, b = a + across;
      world.addQuad(a, b, b + 1, a + 1, Surface::road);
    }
  }
}

/// One pavement box between two road samples, on `side` (+1 left, -1 right), if clear of roads.
void addPavementPiece(World& world, const RouteIndex& index, const RouteSample& a,
                      const RouteSample& b, double side, const WorldStyle& style) {
  const Eigen::Vector2d d = b.street - a.street;
  const double length = d.norm();
  if (length < 1e-6) return;
  const Eigen::Vector2d left = Eigen::Vector2d(-d.y(), d.x()) / length;
  const double offset = style.road_half_width + style.pavement_width / 2;
  const Eigen::Vector2d centre = (a.street + b.street) / 2 + side * offset * left;
  // One heading per street, whichever way the route runs (the box is symmetric).
  const bool backwards = d.x() < 0 || (d.x() == 0 && d.y() < 0);
  const Eigen::Vector2d along = (backwards ? -1.0 : 1.0) / length * d;
  const Eigen::Vector2d ha = (length / 2 + 0.05) * along, hb = style.pavement_width / 2 * left;
  const std::array<Eigen::Vector2d, 4> footprint = {centre - ha - hb, centre + ha - hb,
                                                    centre + ha + hb, centre - ha + hb};
  if (!index.clear(footprint, style.road_half_width - 0.5)) return;
  const double z = std::min(a.z_road, b.z_road) - 0.2;
  const Eigen::Isometry3d T_world_box =
      Eigen::Translation3d(centre.x(), centre.y(), z) *
      Eigen::AngleAxisd(std::atan2(along.y(), along.x()), Eigen::Vector3d::UnitZ());
  const double top = std::max(a.z_road, b.z_road) + style.kerb_height;
  world.addBox(T_world_box, {length + 0.1, style.pavement_width, top - z}, Surface::kerb);
}

void addPavements(World& world, const RouteIndex& index, const std::vector<RouteSample>& samples,
                  const WorldStyle& style) {
  std::size_t start = 0;
  for (std::size_t i = 1; i < samples.size(); ++i) {
    const bool last = i + 1 == samples.size();
    if (samples[i].s - samples[start].s < kPavementPiece && !last) continue;
    if (samples[start].fresh && samples[i].fresh) {
      for (double side : {1.0, -1.0})
        addPavementPiece(world, index, samples[start], samples[i], side, style);
    }
    start = i;
  }
}

}  // namespace

void addRoads(World& world, const RouteIndex& index, const WorldStyle& style) {
  for (std::size_t r = 0; r < index.routeCount(); ++r) {
    const auto& samples = index.samples(r);
    // One strip per paved run; revisits in between drive on the first pass's road.
    for (std::size_t first = 0; first < samples.size();) {
      std::size_t end = first;
      while (end < samples.size() && samples[end].paved) ++end;
      if (end > first) {
        const std::vector<RouteSample> run(samples.begin() + first, samples.begin() + end);
        addRoadStrip(world, withOverhang(run), style.road_half_width);
      }
      first = end + 1;
    }
    addPavements(world, index, samples, style);
  }
}

}  // namespace dcl::sim::detail
