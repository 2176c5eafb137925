// The world generators: ground, roads, then lot after lot along both sides of every route.

#include <algorithm>
#include <cmath>

#include <dcl/sim/world_gen.hpp>

#include "world_detail.hpp"

namespace dcl::sim {

namespace {

using detail::BuildingSpec;
using detail::LotBox;
using detail::LotFrame;
using detail::Rng;

/// Nothing but road, kerb and ground comes nearer a route than this (m); the
/// tests check the 3 m.
constexpr double kRouteClearance = 3.3;
/// m behind the pavement: where a lot's hedge or garden wall starts, and
/// where the garden behind it (a hedge is 0.8 m deep) starts.
constexpr double kFrontBehindPavement = 0.8;
constexpr double kGardenBehindFront = 1.8;
/// m behind the pavement where the garden of a lot without a hedge starts.
constexpr double kGardenBehindPavement = 0.3;

/// Fills the lots along the routes with buildings, trees, poles, cars and hedges.
class LotFiller {
 public:
  LotFiller(const WorldStyle& style, const detail::RouteIndex& index, detail::PropAdder& adder,
            std::uint64_t seed)
      : style_(style), index_(index), adder_(adder), seed_(seed) {}

  void fillRoute(std::size_t route) {
    const double length = index_.length(route);
    if (index_.samples(route).empty()) return;
    for (const double side : {1.0, -1.0}) {
      Lot lot{route, side, 0.0, 0.0, false};
      if (style_.repeat_period > 0) alignToWorld(lot);
      Rng offset_rng(detail::mix(detail::mix(seed_, route), side > 0));
      if (style_.repeat_period <= 0) lot.s0 = offset_rng.uniform(0.0, 10.0);
      for (std::uint64_t k = 0; lot.s0 < length; ++k) lot.s0 += fillLot(lot, k);
    }
  }

 private:
  /// A stretch of one side of a route; a flipped lot is laid out against the
  /// route's direction (aliasing: every lot faces the same world direction).
  struct Lot {
    std::size_t route;
    double side;    ///< +1 left of the route, -1 right
    double s0;      ///< arc length where the lot starts
    double length;  ///< along the route
    bool flipped;
    /// Arc length of lot coordinate a (0 at the lot's start in its own direction).
    [[nodiscard]] double s(double a) const { return flipped ? s0 + length - a : s0 + a; }
    /// The side in the lot's own direction (what its seed depends on).
    [[nodiscard]] double ownSide() const { return flipped ? -side : side; }
  };

  /// Aliasing: lot boundaries where the world position along the route's
  /// heading is a multiple of the period, and one heading for every lot.
  void alignToWorld(Lot& lot) const {
    const detail::RouteFrame first = index_.frameAt(lot.route, 0.0);
    lot.flipped = first.along.x() < 0 || (first.along.x() == 0 && first.along.y() < 0);
    const Eigen::Vector2d heading = lot.flipped ? -first.along : first.along;
    const double position = first.xy.dot(heading) * (lot.flipped ? -1.0 : 1.0);
    const double phase =
        position - style_.repeat_period * std::floor(position / style_.repeat_period);
    lot.s0 = -phase;
  }

  /// One lot starting at lot.s0; returns its length along the route.
  double fillLot(Lot lot, std::uint64_t k) {
    Rng rng(lotSeed(lot, k));
    const double gap = rng.uniform(style_.gap_min, style_.gap_max);
    double frontage = rng.uniform(style_.frontage_min, style_.frontage_max);
    lot.length = style_.repeat_period > 0 ? style_.repeat_period : frontage + gap;
    frontage = std::min(frontage, lot.length - 1.0);
    addStreetProps(lot, rng);
    const detail::RouteFrame mid = index_.frameAt(lot.route, lot.s(frontage / 2));
    const LotFrame frame{mid.xy, lot.flipped ? -mid.along : mid.along, lot.side * mid.left};
    const bool open = rng.chance(style_.open_share);
    const bool front = rng.chance(style_.front_share);
    Rng content(rng.next());
    if (!mid.fresh) return lot.length;
    const bool bend = adder_.spaced() && onBend(lot, frontage);
    // The lot's garden, from behind the pavement (and its hedge) to the facade,
    // planted along it; or the whole open lot, its shrubs a quarter as dense.
    // They draw from a stream of their own.
    const double pavement_back = style_.road_half_width + style_.pavement_width;
    double garden_end = style_.setback_max + style_.depth_max;
    double shrub_density = style_.shrub_density / 4;
    if (open || bend) addOpenLot(frame, frontage, content, !bend);
    if (!open && !bend) {
      garden_end = addBuildings(frame, frontage, content) - 0.3;
      shrub_density = style_.shrub_density;
    }
    if (front) addFront(frame, frontage, content);
    Rng shrubs(detail::mix(lotSeed(lot, k), 0x5b2));
    addShrubs(frame, frontage, pavement_back + (front ? kGardenBehindFront : kGardenBehindPavement),
              garden_end, shrub_density, shrubs);
    return lot.length;
  }

  [[nodiscard]] std::uint64_t lotSeed(const Lot& lot, std::uint64_t k) const {
    const std::uint64_t h = detail::mix(seed_, lot.ownSide() > 0 ? 0x1e7 : 0x21);
    if (style_.repeat_period > 0) return h;  // every lot the same: perceptual aliasing
    return detail::mix(detail::mix(h, lot.route), k);
  }

  /// Trees and poles on the pavement, cars parked along the kerb.
  void addStreetProps(const Lot& lot, Rng& rng) {
    const double w = style_.road_half_width;
    for (double a = style_.tree_spacing / 2; a < lot.length; a += style_.tree_spacing) {
      const double jitter = rng.uniform(-1.0, 1.0);
      const bool tree = rng.chance(style_.tree_share);
      Rng tree_rng(rng.next());
      const auto f = index_.frameAt(lot.route, lot.s(a + jitter));
      if (tree && f.fresh)
        adder_.addTree(f.xy + lot.side * (w + 0.55 * style_.pavement_width) * f.left, tree_rng);
    }
    const int poles = static_cast<int>(lot.length / style_.pole_spacing + rng.uniform());
    for (int i = 0; i < poles; ++i) {
      const double a = rng.uniform(0.0, lot.length);
      const bool lamp = rng.chance(0.6);
      const auto f = index_.frameAt(lot.route, lot.s(a));
      const Eigen::Vector2d out = lot.side * f.left;
      if (f.fresh) adder_.addPole(f.xy + (w + 0.4) * out, -1.6 * out, lamp);
    }
    if (w < 5.0) return;  // no parking lane
    for (double a = 3.25; a < lot.length; a += 6.5) {
      const bool car = rng.chance(style_.car_share);
      Rng car_rng(rng.next());
      const auto f = index_.frameAt(lot.route, lot.s(a));
      const Eigen::Vector2d heading = lot.ownSide() > 0 ? -f.along : f.along;
      if (car && f.fresh)
        adder_.addCar(f.xy + lot.side * (w - 1.1) * f.left, lot.flipped ? -heading : heading,
                      car_rng);
    }
  }

  /// True when the road turns by more than 25 degrees along the lot's frontage
  /// (a corner): no building there, where a straight one would stand askew.
  [[nodiscard]] bool onBend(const Lot& lot, double frontage) const {
    const auto first = index_.frameAt(lot.route, lot.s(0.0));
    const auto last = index_.frameAt(lot.route, lot.s(frontage));
    return first.along.dot(last.along) < std::cos(25.0 * M_PI / 180.0);
  }

  /// The building and, on some lots, one behind it; returns the front
  /// facade's distance from the route.
  double addBuildings(const LotFrame& frame, double frontage, Rng& rng) {
    const double front = rng.uniform(style_.setback_min, style_.setback_max);
    const BuildingSpec spec = detail::randomBuilding(style_, front, frontage, rng);
    addFitting(frame, spec, rng);
    if (!rng.chance(style_.back_row_share)) return front;
    const double back = front + spec.depth + rng.uniform(4.0, 12.0);
    BuildingSpec behind =
        detail::randomBuilding(style_, back, frontage * rng.uniform(0.6, 1.0), rng);
    const double tallest = style_.floors_max * style_.floor_height + 1.5;
    behind.height = std::min(behind.height + rng.integer(1, 4) * style_.floor_height, tallest);
    addFitting(frame, behind, rng);
    return front;
  }

  /// Shrubs, `density` per 100 m^2, over the band b in [b0, b1] of the lot's frontage.
  void addShrubs(const LotFrame& frame, double frontage, double b0, double b1, double density,
                 Rng& rng) {
    constexpr double kLargest = 1.2;  // m, a shrub's half-width at most
    if (density <= 0.0 || b1 - b0 < 0.9) return;
    const double area = frontage * (b1 - b0);
    const int count = static_cast<int>(density * area / 100.0 + rng.uniform());
    for (int i = 0; i < count; ++i) {
      const double radius = std::min(rng.uniform(0.5, kLargest), (b1 - b0) / 2);
      const double a = rng.uniform(-frontage / 2 + radius, frontage / 2 - radius);
      const double b = rng.uniform(b0 + radius, b1 - radius);
      Rng shrub_rng(rng.next());
      adder_.addShrub(frame.toWorld(a, b), radius, shrub_rng);
    }
  }

  /// The building or, when props are spaced (the campus) and it does not fit,
  /// a narrower and shallower one.
  void addFitting(const LotFrame& frame, BuildingSpec spec, Rng& rng) {
    if (detail::addBuilding(adder_, frame, spec, rng) || !adder_.spaced()) return;
    for (const double shrink : {0.7, 0.45}) {
      spec.frontage *= shrink;
      spec.depth = std::max(style_.depth_min, spec.depth * shrink);
      if (detail::addBuilding(adder_, frame, spec, rng)) return;
    }
  }

  /// A square or lawn with trees, or (where `parking`) a car park.
  void addOpenLot(const LotFrame& frame, double frontage, Rng& rng, bool parking = true) {
    const double b0 = style_.road_half_width + style_.pavement_width + 2.0;
    const double b1 = style_.setback_max + style_.depth_max;
    if (rng.chance(style_.parking_share) && parking)
      return addCarPark(frame, frontage, b0 + 2.0, rng);
    const double area = frontage * (b1 - b0);
    const int trees = static_cast<int>(style_.lawn_tree_density * area / 100.0 + rng.uniform());
    for (int i = 0; i < trees; ++i) {
      const double a = rng.uniform(-frontage / 2, frontage / 2), b = rng.uniform(b0, b1);
      Rng tree_rng(rng.next());
      adder_.addTree(frame.toWorld(a, b), tree_rng);
    }
  }

  /// Two rows of cars parked nose to nose, across the lot.
  void addCarPark(const LotFrame& frame, double frontage, double b0, Rng& rng) {
    for (double a = -frontage / 2 + 1.5; a < frontage / 2 - 1.5; a += 2.7) {
      for (int row = 0; row < 2; ++row) {
        const bool car = rng.chance(0.7);
        Rng car_rng(rng.next());
        const double b = b0 + 2.5 + row * 5.5;
        if (car) adder_.addCar(frame.toWorld(a, b), row == 0 ? frame.out : -frame.out, car_rng);
      }
    }
  }

  /// A hedge or a garden wall at the back of the pavement.
  void addFront(const LotFrame& frame, double frontage, Rng& rng) {
    const double b = style_.road_half_width + style_.pavement_width + kFrontBehindPavement;
    const bool hedge = rng.chance(0.6);
    const LotBox box{0, b, frontage - 1.0, hedge ? 0.8 : 0.3, 0, rng.uniform(1.0, 1.8)};
    const Surface surface = hedge ? Surface::vegetation : Surface::wall;
    adder_.addStructure(frame, std::span(&box, 1), surface, style_.road_half_width + 0.5);
  }

  const WorldStyle& style_;
  const detail::RouteIndex& index_;
  detail::PropAdder& adder_;
  std::uint64_t seed_;
};

}  // namespace

WorldStyle cityStyle() {
  return {};
}

WorldStyle campusStyle() {
  WorldStyle s;
  s.road_half_width = 4.5;
  s.pavement_width = 2.5;
  s.setback_min = 9.5;  // 5-8.5 m from the road's edge
  s.setback_max = 13.0;
  s.frontage_min = 14.0;
  s.frontage_max = 36.0;
  s.depth_min = 8.0;
  s.depth_max = 16.0;
  s.gap_min = 5.0;
  s.gap_max = 14.0;
  s.floors_min = 1;
  s.floors_max = 4;
  s.open_share = 0.2;
  s.back_row_share = 0.3;
  s.relief_share = 0.4;
  s.front_share = 0.35;
  s.tree_spacing = 8.0;
  s.tree_share = 0.8;
  s.lawn_tree_density = 0.5;
  s.shrub_density = 3.0;
  s.parking_share = 0.35;
  s.pole_spacing = 20.0;
  s.terrain_amplitude = 1.0;
  s.min_building_gap = 4.0;
  s.infill_spacing = 32.0;
  s.infill_reach = 85.0;
  s.infill_setback = 9.0;
  s.bike_rack_share = 0.4;
  return s;
}

WorldStyle aliasingStyle() {
  WorldStyle s;
  s.repeat_period = 48.0;
  s.open_share = 0.0;
  s.shrub_density = 0.0;  // bare blocks, as on its flat and even ground
  s.terrain_amplitude = 0.0;
  s.ground_roughness = 0.0;
  return s;
}

World generateWorld(const WorldRequest& request, const WorldStyle& style) {
  const detail::RouteIndex index(request.routes, request.mount_height);
  const detail::Terrain terrain(index, style, request.seed);
  World world;
  detail::addGround(world, terrain, index, style);
  detail::addRoads(world, index, style);
  detail::PropAdder adder(world, index, terrain, kRouteClearance, style.min_building_gap);
  LotFiller filler(style, index, adder, detail::mix(request.seed, 0x10f5));
  for (std::size_t r = 0; r < index.routeCount(); ++r) filler.fillRoute(r);
  detail::addInfill(adder, index, style, detail::mix(request.seed, 0x1f11));
  return world;
}

World generateCityWorld(const WorldRequest& request) {
  return generateWorld(request, cityStyle());
}

World generateCampusWorld(const WorldRequest& request) {
  return generateWorld(request, campusStyle());
}

World generateAliasingWorld(const WorldRequest& request) {
  return generateWorld(request, aliasingStyle());
}

}  // namespace dcl::sim
