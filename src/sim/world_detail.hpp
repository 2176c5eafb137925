#pragma once

// Private building blocks of the world generators: deterministic random
// numbers, route samples with a grid for distance queries, the terrain height
// field, and the adders of ground, roads and props.

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <span>
#include <unordered_map>
#include <vector>

#include <dcl/core/trajectory.hpp>
#include <dcl/sim/world.hpp>
#include <dcl/sim/world_gen.hpp>

namespace dcl::sim::detail {

/// SplitMix64's output for counter `z`: z plus the golden gamma, finalised.
/// Counter-based numbers, the same on every platform.
inline std::uint64_t splitmix(std::uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

/// Mixes `value` into the hash `h` (SplitMix64 finaliser): seeds for every lot and vertex.
std::uint64_t mix(std::uint64_t h, std::uint64_t value);

/// A SplitMix64 generator with its own mapping to doubles, so that worlds are
/// identical on every standard library.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next();
  /// Uniform in [0, 1).
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  /// Uniform in [lo, hi).
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  /// Uniform integer in [lo, hi].
  int integer(int lo, int hi);
  /// True with probability p.
  bool chance(double p) { return uniform() < p; }
  /// A standard normal (Box-Muller on two uniforms in (0, 1]).
  double gaussian() {
    const auto open_unit = [&] { return (static_cast<double>(next() >> 11) + 1.0) * 0x1.0p-53; };
    const double radius = std::sqrt(-2.0 * std::log(open_unit()));
    return radius * std::cos(2.0 * M_PI * open_unit());
  }

 private:
  std::uint64_t state_;
};

/// A sample of a route: where the sensor passes and the road surface under it.
struct RouteSample {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();  ///< horizontal position, m
  double z_road = 0.0;                           ///< road surface under the sensor, m
  double s = 0.0;                                ///< arc length from the route's start, m
  bool fresh = true;        ///< no earlier route (or earlier pass of this one) runs here
  bool paved = true;        ///< no earlier pass's road lies under it: it carries its own road
  std::uint32_t route = 0;  ///< index of the route
  Eigen::Vector2d street = Eigen::Vector2d::Zero();  ///< street centreline beside xy (see below)
};

/// The nearest point of any route to a query point.
struct RouteNearest {
  double distance = 0.0;                             ///< m, horizontal
  double z_road = 0.0;                               ///< road height at the nearest point
  Eigen::Vector2d point = Eigen::Vector2d::Zero();   ///< the nearest point, m
  Eigen::Vector2d along = Eigen::Vector2d::UnitX();  ///< unit direction of its segment
};

/// Least horizontal distance between two convex polygons (0 when they overlap).
double polygonDistance(std::span<const Eigen::Vector2d> a, std::span<const Eigen::Vector2d> b);

/// A place along one route: position, road height, unit tangent and left normal.
struct RouteFrame {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();      ///< m
  double z_road = 0.0;                               ///< m
  Eigen::Vector2d along = Eigen::Vector2d::UnitX();  ///< unit direction of travel
  Eigen::Vector2d left = Eigen::Vector2d::UnitY();   ///< unit normal to the left
  bool fresh = true;                                 ///< see RouteSample::fresh
};

/// The routes resampled every 0.5-2 m, with a uniform grid over all samples for
/// horizontal distance queries against every route segment. Where several
/// lanes run side by side (robots passing both ways, a revisit a lane over),
/// each sample's street centreline is the middle of all of them, so that kerbs
/// and buildings line the street, not one lane.
class RouteIndex {
 public:
  RouteIndex(std::span<const core::Trajectory> routes, double mount_height);

  [[nodiscard]] std::size_t routeCount() const { return routes_.size(); }
  [[nodiscard]] const std::vector<RouteSample>& samples(std::size_t route) const {
    return routes_[route];
  }
  /// Path length of a route, m.
  [[nodiscard]] double length(std::size_t route) const;

  /// The nearest route point within `radius`, none if every route is farther.
  /// With `paved_only`, only stretches with a road of their own count: the
  /// ground follows the first pass where ground truth disagrees on a revisit.
  [[nodiscard]] std::optional<RouteNearest> nearest(const Eigen::Vector2d& p, double radius,
                                                    bool paved_only = false) const;

  /// True when the convex polygon keeps at least `clearance` from every route segment.
  [[nodiscard]] bool clear(std::span<const Eigen::Vector2d> polygon, double clearance) const;

  /// The route's frame at arc length `s` (clamped to the route).
  [[nodiscard]] RouteFrame frameAt(std::size_t route, double s) const;

  /// A smooth blend of nearby road heights (inverse-distance weighted, up to
  /// `radius`), for terrain far from the roads; the nearest sample's height if none.
  [[nodiscard]] double smoothRoadHeight(const Eigen::Vector2d& p, double radius) const;

 private:
  using Key = std::int64_t;
  struct SegmentRef {
    std::uint32_t route;
    std::uint32_t index;  ///< segment from sample index to index + 1
  };
  [[nodiscard]] Key key(int cx, int cy) const;
  [[nodiscard]] Eigen::Vector2i cellOf(const Eigen::Vector2d& p, double cell) const;
  void buildGrids();
  void markFresh();
  void findStreets();
  template <class F>
  void forSegmentsNear(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, F&& f,
                       bool paved_only = false) const;

  std::vector<std::vector<RouteSample>> routes_;
  std::unordered_map<Key, std::vector<SegmentRef>> grid_;       ///< segments by cell
  std::unordered_map<Key, std::vector<std::uint32_t>> coarse_;  ///< coarse samples by cell
  std::vector<Eigen::Vector3d> coarse_samples_;                 ///< x, y, z_road every ~10 m
};

/// The height of the ground: the roads' own heights near the routes, blending
/// into low-frequency relief away from them.
class Terrain {
 public:
  Terrain(const RouteIndex& index, const WorldStyle& style, std::uint64_t seed);

  /// Surface height at `p` (the road's height on and beside the road).
  [[nodiscard]] double height(const Eigen::Vector2d& p) const;

  /// Height of the ground mesh vertex at `p`: `height` lowered under roads and
  /// pavements (so those lie on top) and roughened off them.
  [[nodiscard]] double groundVertexHeight(const Eigen::Vector2d& p) const;

  /// Distance to the nearest route (capped at the style's extent).
  [[nodiscard]] double routeDistance(const Eigen::Vector2d& p) const;

 private:
  [[nodiscard]] double relief(const Eigen::Vector2d& p) const;
  [[nodiscard]] double valueNoise(const Eigen::Vector2d& p, std::uint64_t octave) const;

  const RouteIndex& index_;
  WorldStyle style_;
  std::uint64_t seed_;
};

/// The ground mesh: 16 m tiles within the extent, 2 m cells near routes, 8 m beyond.
void addGround(World& world, const Terrain& terrain, const RouteIndex& index,
               const WorldStyle& style);

/// The road strips of the routes' paved stretches (revisits drive on the
/// first pass's road) and the pavements (kerb surface) along fresh stretches.
void addRoads(World& world, const RouteIndex& index, const WorldStyle& style);

/// A rigid local frame on the ground: a = along the road, b = away from it.
struct LotFrame {
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  ///< world xy of (a, b) = (0, 0)
  Eigen::Vector2d along = Eigen::Vector2d::UnitX();  ///< unit a axis
  Eigen::Vector2d out = Eigen::Vector2d::UnitY();    ///< unit b axis

  /// World xy of local (a, b).
  [[nodiscard]] Eigen::Vector2d toWorld(double a, double b) const {
    return origin + a * along + b * out;
  }
  /// Heading (yaw) of the a axis.
  [[nodiscard]] double yaw() const;
};

/// A box in a lot frame: centre of its footprint, extents along a and b, height range.
struct LotBox {
  double a = 0.0;       ///< m, footprint centre along the road
  double b = 0.0;       ///< m, footprint centre away from the road
  double size_a = 1.0;  ///< m
  double size_b = 1.0;  ///< m
  double z0 = 0.0;      ///< m, bottom above the lot's base height
  double z1 = 1.0;      ///< m, top above the lot's base height
};

/// A footprint on the ground: four corners counter-clockwise (a box seen from above).
using Footprint = std::array<Eigen::Vector2d, 4>;

/// The footprints of what stands on the ground, in a grid, so that new
/// structures can keep apart from earlier ones. Tree trunks are plants: they
/// keep others only kPlantGap away, whatever gap a structure asks for.
class Occupancy {
 public:
  static constexpr double kPlantGap = 1.0;  ///< m, least distance of anything from a trunk

  void add(const Footprint& footprint, bool plant);
  /// True when `footprint` keeps `gap` from every solid footprint (kPlantGap from plants).
  [[nodiscard]] bool free(const Footprint& footprint, double gap) const;

 private:
  struct Entry {
    Footprint footprint;
    bool plant;
  };
  using Key = std::int64_t;
  template <class F>
  void forCells(const Footprint& footprint, double margin, F&& f) const;

  std::vector<Entry> entries_;
  std::unordered_map<Key, std::vector<std::uint32_t>> grid_;  ///< entries by cell
};

/// Adds props after checking they keep clear of every route: each adder
/// returns false (and adds nothing) when the prop would stand too close. With
/// a positive `spacing` (the campus) props also keep apart from the ones
/// added before them; with 0 (the city) they are not checked against each other.
class PropAdder {
 public:
  PropAdder(World& world, const RouteIndex& index, const Terrain& terrain, double clearance,
            double spacing = 0.0)
      : world_(world), index_(index), terrain_(terrain), clearance_(clearance), spacing_(spacing) {}

  /// Boxes of one structure (all or none), on the lowest ground under them,
  /// keeping `gap` from earlier props when props are checked against each other.
  bool addStructure(const LotFrame& frame, std::span<const LotBox> boxes, Surface surface,
                    double clearance, double gap = 0.5);
  /// A tree: trunk cylinder and ellipsoid crown.
  bool addTree(const Eigen::Vector2d& xy, Rng& rng);
  /// A shrub: one to three overlapping ellipsoids of foliage on the ground,
  /// lumpy as a real bush is, at most `radius` m across from `xy`.
  bool addShrub(const Eigen::Vector2d& xy, double radius, Rng& rng);
  /// A lamp post with an arm reaching `arm` (world xy offset), or a sign pole.
  bool addPole(const Eigen::Vector2d& xy, const Eigen::Vector2d& arm, bool lamp);
  /// A parked car heading along `along` on the road at `xy`.
  bool addCar(const Eigen::Vector2d& xy, const Eigen::Vector2d& along, Rng& rng);
  /// A bike rack: a row of `stands` inverted-U stands (two thin posts and a
  /// bar each, 0.8 m apart along a) starting at (a, b) of `frame`.
  bool addBikeRack(const LotFrame& frame, double a, double b, int stands);

  [[nodiscard]] double clearance() const { return clearance_; }
  /// True when props are checked against each other (see the constructor).
  [[nodiscard]] bool spaced() const { return spacing_ > 0.0; }
  /// True when the square of half-side `radius` around `xy` keeps `gap` from earlier props.
  [[nodiscard]] bool freeAround(const Eigen::Vector2d& xy, double radius, double gap) const;

 private:
  [[nodiscard]] Footprint corners(const LotFrame& frame, const LotBox& box) const;
  [[nodiscard]] bool fits(const Footprint& footprint, double gap) const;
  void addLotBox(const LotFrame& frame, const LotBox& box, double base, Surface surface);
  [[nodiscard]] bool clearDisc(const Eigen::Vector2d& xy, double radius) const;

  World& world_;
  const RouteIndex& index_;
  const Terrain& terrain_;
  double clearance_;
  double spacing_;
  Occupancy occupied_;
};

/// The size of a building on a lot, in the lot frame.
struct BuildingSpec {
  double front = 10.0;     ///< m, street facade's distance b from the frame origin (on the route)
  double frontage = 20.0;  ///< m, width along a, centred on a = 0
  double depth = 15.0;     ///< m, extent in b behind the facade
  double height = 12.0;    ///< m, main part's height
  double floor_height = 3.0;  ///< m a storey (balcony levels)
  bool relief = true;         ///< pillars, balconies and a cornice on the street facades
  double clearance = 8.0;     ///< m, least distance of the footprint from every route
  double gap = 0.5;           ///< m from earlier props (when the adder checks that)
};

/// One building: a footprint of several boxes (rectangle, L, notched or
/// courtyard), with facade relief on the parts facing the street. False when
/// it would stand too near a route (nothing is added then).
bool addBuilding(PropAdder& adder, const LotFrame& frame, const BuildingSpec& spec, Rng& rng);

/// The building of `style` for a lot: random depth, storeys, relief; front and frontage given.
BuildingSpec randomBuilding(const WorldStyle& style, double front, double frontage, Rng& rng);

/// Fills the land the lots along the routes leave free (block interiors, the
/// land beyond the outer streets) within the style's infill reach: buildings
/// facing the nearest street on a jittered grid, with hedges, low walls,
/// bike racks and trees around them, lawns with trees and car parks where
/// none fits. Nothing when the style's infill spacing is 0.
void addInfill(PropAdder& adder, const RouteIndex& index, const WorldStyle& style,
               std::uint64_t seed);

}  // namespace dcl::sim::detail
