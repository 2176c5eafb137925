#pragma once

// Private building blocks of the world generators: deterministic random
// numbers, route samples with a grid for distance queries, the terrain height
// field, and the adders of ground, roads and props.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <unordered_map>
#include <vector>

#include <dcl/core/trajectory.hpp>
#include <dcl/sim/world.hpp>
#include <dcl/sim/world_gen.hpp>

namespace dcl::sim::detail {

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
  double distance = 0.0;  ///< m, horizontal
  double z_road = 0.0;    ///< road height at the nearest point
};

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

/// Adds props after checking they keep clear of every route: each adder
/// returns false (and adds nothing) when the prop would stand too close.
class PropAdder {
 public:
  PropAdder(World& world, const RouteIndex& index, const Terrain& terrain, double clearance)
      : world_(world), index_(index), terrain_(terrain), clearance_(clearance) {}

  /// Boxes of one structure (all or none), on the lowest ground under them.
  bool addStructure(const LotFrame& frame, std::span<const LotBox> boxes, Surface surface,
                    double clearance);
  /// A tree: trunk cylinder and ellipsoid crown.
  bool addTree(const Eigen::Vector2d& xy, Rng& rng);
  /// A lamp post with an arm reaching `arm` (world xy offset), or a sign pole.
  bool addPole(const Eigen::Vector2d& xy, const Eigen::Vector2d& arm, bool lamp);
  /// A parked car heading along `along` on the road at `xy`.
  bool addCar(const Eigen::Vector2d& xy, const Eigen::Vector2d& along, Rng& rng);

  [[nodiscard]] double clearance() const { return clearance_; }

 private:
  [[nodiscard]] std::array<Eigen::Vector2d, 4> corners(const LotFrame& frame,
                                                       const LotBox& box) const;
  void addLotBox(const LotFrame& frame, const LotBox& box, double base, Surface surface);
  [[nodiscard]] bool clearDisc(const Eigen::Vector2d& xy, double radius) const;

  World& world_;
  const RouteIndex& index_;
  const Terrain& terrain_;
  double clearance_;
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
};

/// One building: a footprint of several boxes (rectangle, L, notched or
/// courtyard), with facade relief on the parts facing the street. False when
/// it would stand too near a route (nothing is added then).
bool addBuilding(PropAdder& adder, const LotFrame& frame, const BuildingSpec& spec, Rng& rng);

}  // namespace dcl::sim::detail
