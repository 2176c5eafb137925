// Props: buildings with varied footprints and facade relief, trees, poles, cars.

#include <algorithm>
#include <cmath>
#include <limits>

#include "world_detail.hpp"

namespace dcl::sim::detail {

double LotFrame::yaw() const {
  return std::atan2(along.y(), along.x());
}

namespace {

constexpr double kOccupancyCell = 8.0;  // m, grid cell of the occupancy

Footprint square(const Eigen::Vector2d& xy, double half) {
  return {xy + Eigen::Vector2d(-half, -half), xy + Eigen::Vector2d(half, -half),
          xy + Eigen::Vector2d(half, half), xy + Eigen::Vector2d(-half, half)};
}

}  // namespace

template <class F>
void Occupancy::forCells(const Footprint& footprint, double margin, F&& f) const {
  Eigen::Vector2d lo = footprint[0], hi = footprint[0];
  for (const auto& p : footprint) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const auto cell = [](double v) { return static_cast<int>(std::floor(v / kOccupancyCell)); };
  for (int x = cell(lo.x() - margin); x <= cell(hi.x() + margin); ++x)
    for (int y = cell(lo.y() - margin); y <= cell(hi.y() + margin); ++y)
      f((static_cast<Key>(x) << 32) ^ static_cast<Key>(static_cast<std::uint32_t>(y)));
}

void Occupancy::add(const Footprint& footprint, bool plant) {
  const auto id = static_cast<std::uint32_t>(entries_.size());
  entries_.push_back({footprint, plant});
  forCells(footprint, 0.0, [&](Key key) { grid_[key].push_back(id); });
}

bool Occupancy::free(const Footprint& footprint, double gap) const {
  bool ok = true;
  forCells(footprint, std::max(gap, kPlantGap), [&](Key key) {
    const auto it = grid_.find(key);
    if (!ok || it == grid_.end()) return;
    for (const std::uint32_t id : it->second) {
      const Entry& e = entries_[id];
      if (polygonDistance(footprint, e.footprint) < (e.plant ? kPlantGap : gap)) ok = false;
    }
  });
  return ok;
}

Footprint PropAdder::corners(const LotFrame& frame, const LotBox& box) const {
  const double ha = box.size_a / 2, hb = box.size_b / 2;
  return {frame.toWorld(box.a - ha, box.b - hb), frame.toWorld(box.a + ha, box.b - hb),
          frame.toWorld(box.a + ha, box.b + hb), frame.toWorld(box.a - ha, box.b + hb)};
}

void PropAdder::addLotBox(const LotFrame& frame, const LotBox& box, double base, Surface surface) {
  occupied_.add(corners(frame, box), false);
  const Eigen::Vector2d c = frame.toWorld(box.a, box.b);
  const Eigen::Isometry3d T_world_box = Eigen::Translation3d(c.x(), c.y(), base + box.z0) *
                                        Eigen::AngleAxisd(frame.yaw(), Eigen::Vector3d::UnitZ());
  world_.addBox(T_world_box, {box.size_a, box.size_b, box.z1 - box.z0}, surface);
}

bool PropAdder::fits(const Footprint& footprint, double gap) const {
  return !spaced() || occupied_.free(footprint, gap);
}

bool PropAdder::freeAround(const Eigen::Vector2d& xy, double radius, double gap) const {
  return fits(square(xy, radius), gap);
}

bool PropAdder::addStructure(const LotFrame& frame, std::span<const LotBox> boxes, Surface surface,
                             double clearance, double gap) {
  if (boxes.empty()) return false;
  const double needed = std::max(clearance, clearance_);
  double base = std::numeric_limits<double>::infinity();
  for (const LotBox& box : boxes) {
    const auto footprint = corners(frame, box);
    if (!index_.clear(footprint, needed) || !fits(footprint, gap)) return false;
    if (&box == &boxes.front())
      for (const auto& p : footprint) base = std::min(base, terrain_.height(p));
  }
  for (const LotBox& box : boxes) addLotBox(frame, box, base - 0.3, surface);
  return true;
}

bool PropAdder::clearDisc(const Eigen::Vector2d& xy, double radius) const {
  return !index_.nearest(xy, radius + clearance_);
}

bool PropAdder::addTree(const Eigen::Vector2d& xy, Rng& rng) {
  const double trunk_r = rng.uniform(0.12, 0.3), trunk_h = rng.uniform(1.8, 3.5);
  Eigen::Vector3d radii(rng.uniform(1.5, 3.5), 0.0, rng.uniform(1.8, 4.0));
  if (const auto near = index_.nearest(xy, radii.x() + clearance_)) {
    radii.x() = near->distance - clearance_;  // a smaller crown beside the road
    if (radii.x() < 1.0) return false;
  }
  if (!fits(square(xy, 0.7 * radii.x()), 0.3)) return false;  // the crown may overhang a little
  occupied_.add(square(xy, trunk_r), true);
  const double base = terrain_.height(xy) - 0.2;
  world_.addCylinder({xy.x(), xy.y(), base}, trunk_r, trunk_h + 0.5 * radii.z() + 0.2, 7,
                     Surface::trunk);
  const Eigen::Vector3d centre(xy.x(), xy.y(), base + 0.2 + trunk_h + radii.z());
  world_.addEllipsoid(centre, {radii.x(), radii.x() * 0.9, radii.z()}, 5, Surface::vegetation);
  return true;
}

bool PropAdder::addShrub(const Eigen::Vector2d& xy, double radius, Rng& rng) {
  if (!clearDisc(xy, radius) || !fits(square(xy, radius), 0.3)) return false;
  occupied_.add(square(xy, radius), false);
  const double base = terrain_.height(xy);
  const int lobes = rng.integer(1, 3);
  for (int i = 0; i < lobes; ++i) {
    const double across = rng.uniform(0.45, 1.0) * (lobes == 1 ? radius : 0.7 * radius);
    const double tall = rng.uniform(0.35, 1.2);
    const double reach = std::max(radius - across, 0.0);
    const Eigen::Vector2d at =
        xy + Eigen::Vector2d(rng.uniform(-reach, reach) * 0.7, rng.uniform(-reach, reach) * 0.7);
    world_.addEllipsoid({at.x(), at.y(), base + 0.7 * tall}, {across, across * 0.85, tall}, 4,
                        Surface::vegetation);
  }
  return true;
}

bool PropAdder::addPole(const Eigen::Vector2d& xy, const Eigen::Vector2d& arm, bool lamp) {
  if (!clearDisc(xy, 0.15) || (lamp && !clearDisc(xy + arm, 0.15))) return false;
  if (!fits(square(xy, 0.15), 0.3)) return false;
  occupied_.add(square(xy, 0.15), false);
  const double base = terrain_.height(xy) - 0.2;
  const double height = lamp ? 8.0 : 2.8;
  world_.addCylinder({xy.x(), xy.y(), base}, lamp ? 0.12 : 0.05, height, 6, Surface::pole);
  const Eigen::Vector2d mid = xy + arm / 2;
  const double yaw = std::atan2(arm.y(), arm.x());
  const Eigen::Isometry3d T_world_top =
      Eigen::Translation3d(mid.x(), mid.y(), base + height - (lamp ? 0.15 : 0.8)) *
      Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ());
  if (lamp) world_.addBox(T_world_top, {arm.norm(), 0.2, 0.15}, Surface::pole);
  if (!lamp) world_.addBox(T_world_top, {0.06, 0.7, 0.7}, Surface::pole);  // a sign plate
  return true;
}

bool PropAdder::addCar(const Eigen::Vector2d& xy, const Eigen::Vector2d& along, Rng& rng) {
  const double length = rng.uniform(3.9, 4.9), width = rng.uniform(1.7, 1.9);
  const double roof = rng.uniform(1.4, 1.7), cabin_shift = rng.uniform(-0.4, 0.0);
  const LotFrame frame{xy, along, Eigen::Vector2d(-along.y(), along.x())};
  const LotBox body{0, 0, length, width, 0.3, 1.0};
  const LotBox cabin{cabin_shift * length / 4, 0, length * 0.5, width - 0.1, 1.0, roof};
  const LotBox front_axle{length * 0.32, 0, 0.6, width - 0.2, 0.0, 0.3};
  const LotBox rear_axle{-length * 0.32, 0, 0.6, width - 0.2, 0.0, 0.3};
  const std::array<LotBox, 4> boxes = {body, cabin, front_axle, rear_axle};
  const auto footprint = corners(frame, body);
  if (!index_.clear(footprint, clearance_) || !fits(footprint, 0.5)) return false;
  const double base = terrain_.height(xy);
  for (const LotBox& box : boxes) addLotBox(frame, box, base, Surface::vehicle);
  return true;
}

bool PropAdder::addBikeRack(const LotFrame& frame, double a, double b, int stands) {
  // Structures stand 0.3 m deep in the ground: 0.85 m stands.
  constexpr double kPitch = 0.8, kWidth = 0.7, kHeight = 1.15, kPost = 0.05;
  std::vector<LotBox> boxes;
  for (int i = 0; i < stands; ++i) {
    const double at = a + i * kPitch;
    boxes.push_back({at, b - kWidth / 2, kPost, kPost, 0.0, kHeight});
    boxes.push_back({at, b + kWidth / 2, kPost, kPost, 0.0, kHeight});
    boxes.push_back({at, b, kPost, kWidth, kHeight - kPost, kHeight});
  }
  return addStructure(frame, boxes, Surface::pole, clearance_, 0.5);
}

namespace {

/// The footprint of a building as boxes in its lot frame, by a random shape.
std::vector<LotBox> footprint(double front, double frontage, double depth, double height,
                              Rng& rng) {
  const double a0 = -frontage / 2, a1 = frontage / 2, b0 = front, b1 = front + depth;
  const double step = rng.uniform(0.0, 1.0) * 3.0;  // other wings up to a storey lower
  const double h2 = std::max(4.0, height - step);
  switch (rng.integer(0, 5)) {
    case 0:  // L: a front bar and a wing on one side reaching back
    {
      const double wing = frontage * rng.uniform(0.3, 0.5), bar = depth * rng.uniform(0.4, 0.6);
      const double wa = rng.chance(0.5) ? a0 + wing / 2 : a1 - wing / 2;
      return {{0, b0 + bar / 2, frontage, bar, 0, height},
              {wa, b0 + depth / 2, wing, depth, 0, h2}};
    }
    case 1:  // notched: the middle set back from the street
    {
      const double side = frontage * rng.uniform(0.25, 0.35), notch = rng.uniform(2.0, 4.0);
      return {{a0 + side / 2, b0 + depth / 2, side, depth, 0, height},
              {a1 - side / 2, b0 + depth / 2, side, depth, 0, height},
              {0, b0 + (notch + depth) / 2, frontage - 2 * side, depth - notch, 0, h2}};
    }
    case 2:  // courtyard: four wings around an open yard
      if (depth >= 14.0 && frontage >= 16.0) {
        const double w = 5.0;
        return {{0, b0 + w / 2, frontage, w, 0, height},
                {0, b1 - w / 2, frontage, w, 0, h2},
                {a0 + w / 2, (b0 + b1) / 2, w, depth - 2 * w, 0, height},
                {a1 - w / 2, (b0 + b1) / 2, w, depth - 2 * w, 0, height}};
      }
      [[fallthrough]];
    default:  // rectangle, sometimes with a lower annex behind
      if (rng.chance(0.4))
        return {{0, b0 + depth * 0.35, frontage, depth * 0.7, 0, height},
                {0, b0 + depth * 0.85, frontage * 0.6, depth * 0.3, 0, std::max(4.0, height - 6)}};
      return {{0, b0 + depth / 2, frontage, depth, 0, height}};
  }
}

/// Pillars, balconies and a cornice on the street facade (b = front) over a in [a0, a1].
std::vector<LotBox> facadeRelief(double a0, double a1, double front, double height, double floor,
                                 Rng& rng) {
  std::vector<LotBox> boxes;
  const double spacing = rng.uniform(3.0, 5.0);
  const double pillar = rng.uniform(0.25, 0.45), balcony = rng.uniform(0.9, 1.3);
  const double balcony_share = rng.uniform(0.2, 0.7);
  const int bays = std::max(1, static_cast<int>((a1 - a0) / spacing));
  const double bay = (a1 - a0) / bays;
  for (int i = 0; i <= bays; ++i)
    boxes.push_back({a0 + i * bay, front - pillar / 2, 0.5, pillar, 0, height});
  const int floors = static_cast<int>(height / floor);
  for (int f = 1; f < floors; ++f) {
    for (int i = 0; i < bays; ++i) {
      if (!rng.chance(balcony_share)) continue;
      const double a = a0 + (i + 0.5) * bay;
      boxes.push_back({a, front - balcony / 2, bay - 1.0, balcony, f * floor, f * floor + 1.0});
    }
  }
  boxes.push_back({(a0 + a1) / 2, front - 0.25, a1 - a0 + 0.6, 0.5, height - 0.5, height + 0.3});
  return boxes;
}

}  // namespace

bool addBuilding(PropAdder& adder, const LotFrame& frame, const BuildingSpec& spec, Rng& rng) {
  std::vector<LotBox> boxes = footprint(spec.front, spec.frontage, spec.depth, spec.height, rng);
  const std::size_t parts = boxes.size();
  for (std::size_t i = 0; i < parts && spec.relief; ++i) {
    const LotBox part = boxes[i];
    if (std::abs(part.b - part.size_b / 2 - spec.front) > 1e-9) continue;  // not on the street
    const double a0 = part.a - part.size_a / 2, a1 = part.a + part.size_a / 2;
    const auto extra = facadeRelief(a0, a1, spec.front, part.z1, spec.floor_height, rng);
    boxes.insert(boxes.end(), extra.begin(), extra.end());
  }
  return adder.addStructure(frame, boxes, Surface::building, spec.clearance, spec.gap);
}

BuildingSpec randomBuilding(const WorldStyle& style, double front, double frontage, Rng& rng) {
  BuildingSpec spec;
  spec.front = front;
  spec.frontage = frontage;
  spec.depth = rng.uniform(style.depth_min, style.depth_max);
  spec.floor_height = style.floor_height;
  const int floors = rng.integer(style.floors_min, style.floors_max);
  spec.height = floors * style.floor_height + rng.uniform(0.3, 1.5);
  spec.relief = rng.chance(style.relief_share);
  spec.clearance = style.road_half_width + 0.5;  // off every lane's road, balconies too
  spec.gap = style.min_building_gap;
  return spec;
}

}  // namespace dcl::sim::detail
