// Infill: buildings, hedges, low walls, bike racks, lamp posts, trees and car
// parks on the land the lots along the routes leave free.

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <optional>

#include "world_detail.hpp"

namespace dcl::sim::detail {

namespace {

/// Building sizes tried at a site, as shares of the drawn one, largest first.
constexpr std::array<double, 3> kShrink = {1.0, 0.75, 0.55};
/// Site shifts tried along a and b (away from the street), as shares of the pitch.
constexpr std::array<double, 5> kShift = {0.0, 0.25, -0.25, 0.5, -0.5};

/// Resultant length (0-1) of the routes' headings modulo 90 degrees from
/// which they count as following a street grid.
constexpr double kGridStrength = 0.6;

/// The heading of the street grid the routes follow, if they follow one: the
/// length-weighted circular mean of the segment headings modulo 90 degrees,
/// when most of the routes' length runs along its two axes (bends and corners
/// arcs weaken it).
std::optional<double> streetGrid(const RouteIndex& index) {
  std::complex<double> sum = 0.0;
  double total = 0.0;
  for (std::size_t r = 0; r < index.routeCount(); ++r) {
    const auto& samples = index.samples(r);
    for (std::size_t i = 1; i < samples.size(); ++i) {
      const Eigen::Vector2d d = samples[i].xy - samples[i - 1].xy;
      sum += d.norm() * std::polar(1.0, 4.0 * std::atan2(d.y(), d.x()));
      total += d.norm();
    }
  }
  if (total <= 0.0 || std::abs(sum) < kGridStrength * total) return std::nullopt;
  return std::arg(sum) / 4.0;
}

/// The frame of a site: origin at the site, a along the nearest street (along
/// the grid's axis nearest to it when there is a grid), b away from the street.
LotFrame facingStreet(const Eigen::Vector2d& xy, const RouteNearest& near,
                      std::optional<double> grid) {
  Eigen::Vector2d along = near.along;
  if (grid) {
    const Eigen::Vector2d u(std::cos(*grid), std::sin(*grid)), v(-u.y(), u.x());
    along = std::abs(u.dot(near.along)) >= std::abs(v.dot(near.along)) ? u : v;
  }
  Eigen::Vector2d out(-along.y(), along.x());
  if (out.dot(xy - near.point) < 0) out = -out;
  return {xy, along, out};
}

class InfillFiller {
 public:
  InfillFiller(PropAdder& adder, const RouteIndex& index, const WorldStyle& style,
               std::uint64_t seed)
      : adder_(adder),
        index_(index),
        style_(style),
        seed_(seed),
        reach_(std::min(style.infill_reach, style.extent - style.frontage_max)),
        grid_(streetGrid(index)) {}

  /// Every site of the grid over the routes' bounds widened by the reach, row by row.
  void fill() {
    Eigen::AlignedBox2d bounds;
    for (std::size_t r = 0; r < index_.routeCount(); ++r)
      for (const RouteSample& sample : index_.samples(r)) bounds.extend(sample.xy);
    if (bounds.isEmpty()) return;
    const double pitch = style_.infill_spacing;
    const auto cell = [&](double v) { return static_cast<int>(std::floor(v / pitch)); };
    const Eigen::Vector2d lo = bounds.min().array() - reach_;
    const Eigen::Vector2d hi = bounds.max().array() + reach_;
    for (int iy = cell(lo.y()); iy <= cell(hi.y()); ++iy)
      for (int ix = cell(lo.x()); ix <= cell(hi.x()); ++ix) fillSite(ix, iy);
  }

 private:
  void fillSite(int ix, int iy) {
    Rng rng(mix(mix(seed_, static_cast<std::uint64_t>(ix)), static_cast<std::uint64_t>(iy)));
    const double pitch = style_.infill_spacing;
    const Eigen::Vector2d jitter(rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2));
    const Eigen::Vector2d xy = pitch * (Eigen::Vector2d(ix + 0.5, iy + 0.5) + jitter);
    const auto near = index_.nearest(xy, reach_);
    if (!near) return;
    LotFrame frame = facingStreet(xy, *near, grid_);
    Rng content(rng.next());
    if (const auto spec = addFittingBuilding(frame, content))
      return addSurroundings(frame, *spec, content);
    addLawn(frame, content);
  }

  /// The largest of the drawn building's shrunk versions that fits near the
  /// site; the frame moves to where it stands.
  std::optional<BuildingSpec> addFittingBuilding(LotFrame& frame, Rng& rng) {
    const double frontage = rng.uniform(style_.frontage_min, style_.frontage_max);
    BuildingSpec spec = randomBuilding(style_, 0.0, frontage, rng);
    spec.clearance = style_.infill_setback;
    const double depth = spec.depth;
    const Eigen::Vector2d site = frame.origin;
    for (const double k : kShrink) {
      spec.frontage = k * frontage;
      spec.depth = std::max(style_.depth_min * 0.8, k * depth);
      spec.front = -spec.depth / 2;
      for (const double db : kShift) {
        for (const double da : kShift) {
          frame.origin = site + style_.infill_spacing * (da * frame.along + db * frame.out);
          if (addBuilding(adder_, frame, spec, rng)) return spec;
        }
      }
    }
    frame.origin = site;
    return std::nullopt;
  }

  /// A hedge or low wall and a bike rack before the street facade, a lamp
  /// post at a corner, trees around.
  void addSurroundings(const LotFrame& frame, const BuildingSpec& spec, Rng& rng) {
    const double edge = style_.road_half_width + style_.pavement_width;
    if (rng.chance(style_.front_share)) {
      const bool hedge = rng.chance(0.6);
      const LotBox box{rng.uniform(-2.0, 2.0),
                       spec.front - rng.uniform(2.5, 4.0),
                       spec.frontage * rng.uniform(0.5, 0.9),
                       hedge ? 0.8 : 0.3,
                       0,
                       rng.uniform(1.0, 1.6)};
      adder_.addStructure(frame, std::span(&box, 1), hedge ? Surface::vegetation : Surface::wall,
                          edge, 0.5);
    }
    if (rng.chance(style_.bike_rack_share)) {
      const double a = rng.uniform(-0.4, 0.2) * spec.frontage;
      adder_.addBikeRack(frame, a, spec.front - 1.6, rng.integer(5, 10));
    }
    const double corner = (rng.chance(0.5) ? 1.0 : -1.0) * (spec.frontage / 2 + 2.0);
    if (rng.chance(0.6))
      adder_.addPole(frame.toWorld(corner, spec.front - 3.0), -1.2 * frame.out, true);
    if (rng.chance(style_.parking_share)) addParkingRow(frame, spec, rng);
    const int trees = rng.integer(1, 4);
    for (int i = 0; i < trees; ++i) {
      const double a = rng.uniform(-0.5, 0.5) * (spec.frontage + 14.0);
      const double b = rng.uniform(spec.front - 7.0, spec.front + spec.depth + 7.0);
      addLawnTree(frame.toWorld(a, b), rng);
    }
  }

  /// Trees, sometimes a hedge row, a lamp post or a car park, on a site no building fits.
  void addLawn(const LotFrame& frame, Rng& rng) {
    const double half = style_.infill_spacing / 2;
    if (rng.chance(style_.parking_share)) addCarPark(frame, rng);
    if (rng.chance(0.3)) {
      const LotBox hedge{
          rng.uniform(-half, half) / 2, rng.uniform(-half, half), rng.uniform(8, 16), 0.8, 0,
          rng.uniform(1.1, 1.6)};
      adder_.addStructure(frame, std::span(&hedge, 1), Surface::vegetation,
                          style_.road_half_width + style_.pavement_width, 0.5);
    }
    if (rng.chance(0.5))
      adder_.addPole(frame.toWorld(rng.uniform(-half, half), rng.uniform(-half, half)),
                     1.2 * frame.along, true);
    const double area = 4 * half * half;
    const int trees = static_cast<int>(style_.lawn_tree_density * area / 100.0 + rng.uniform());
    for (int i = 0; i < trees; ++i)
      addLawnTree(frame.toWorld(rng.uniform(-half, half), rng.uniform(-half, half)), rng);
  }

  /// Two rows of cars nose to nose along the street, some bays empty.
  void addCarPark(const LotFrame& frame, Rng& rng) {
    const int bays = rng.integer(4, 9);
    for (int i = 0; i < bays; ++i) {
      for (int row = 0; row < 2; ++row) {
        const bool car = rng.chance(0.7);
        Rng car_rng(rng.next());
        const Eigen::Vector2d bay = frame.toWorld((i - bays / 2.0) * 2.7, row == 0 ? -2.6 : 2.6);
        if (car) adder_.addCar(bay, row == 0 ? frame.out : -frame.out, car_rng);
      }
    }
  }

  /// A row of bays along one side wall, cars nose to the wall, some bays empty.
  void addParkingRow(const LotFrame& frame, const BuildingSpec& spec, Rng& rng) {
    const double side = rng.chance(0.5) ? 1.0 : -1.0;
    const double a = side * (spec.frontage / 2 + 3.5);
    for (double b = spec.front + 1.5; b < spec.front + spec.depth - 1.0; b += 2.7) {
      const bool car = rng.chance(0.75);
      Rng car_rng(rng.next());
      if (car) adder_.addCar(frame.toWorld(a, b), -side * frame.along, car_rng);
    }
  }

  /// A tree off the road and pavement.
  void addLawnTree(const Eigen::Vector2d& xy, Rng& rng) {
    Rng tree_rng(rng.next());
    const double off_pavement = style_.road_half_width + style_.pavement_width + 1.5;
    if (!index_.nearest(xy, off_pavement)) adder_.addTree(xy, tree_rng);
  }

  PropAdder& adder_;
  const RouteIndex& index_;
  const WorldStyle& style_;
  std::uint64_t seed_;
  double reach_;  ///< m, farthest site from every route (buildings stay in the extent)
  std::optional<double> grid_;  ///< heading of the routes' street grid, if any
};

}  // namespace

void addInfill(PropAdder& adder, const RouteIndex& index, const WorldStyle& style,
               std::uint64_t seed) {
  if (style.infill_spacing <= 0.0 || !adder.spaced()) return;
  InfillFiller(adder, index, style, seed).fill();
}

}  // namespace dcl::sim::detail
