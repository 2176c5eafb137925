/// Generated routes: campus loops and U routes with planned rendezvous, and the
/// perceptual-aliasing corridor. Paths are polylines with arc-rounded corners,
/// driven with a trapezoidal speed profile and lifted onto a gentle terrain.

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include <dcl/core/error.hpp>
#include <dcl/core/ids.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/sim/routes.hpp>

#include "world_detail.hpp"

namespace dcl::sim {
namespace {

// ---------------------------------------------------------------- randomness

using detail::Rng;

/// An independent stream for `stream` (a robot, the terrain) under `seed`.
Rng streamRng(std::uint64_t seed, std::uint64_t stream) {
  Rng mix(seed * 0x2545F4914F6CDD1Dull + stream);
  return Rng(mix.next());
}

// ---------------------------------------------------------------- terrain

/// A gentle ground undulation z(x, y): two sine waves across the plane.
struct Terrain {
  double amplitude = 0.0;
  double wavenumber = 0.0;  ///< rad/m
  double phase_x = 0.0;
  double phase_y = 0.0;

  [[nodiscard]] double height(const Eigen::Vector2d& p) const {
    return amplitude * (0.6 * std::sin(wavenumber * p.x() + phase_x) +
                        0.4 * std::sin(wavenumber * p.y() + phase_y));
  }

  [[nodiscard]] Eigen::Vector2d gradient(const Eigen::Vector2d& p) const {
    const double g = amplitude * wavenumber;
    return {0.6 * g * std::cos(wavenumber * p.x() + phase_x),
            0.4 * g * std::cos(wavenumber * p.y() + phase_y)};
  }
};

Terrain makeTerrain(std::uint64_t seed, double amplitude, double wavelength) {
  Rng rng = streamRng(seed, 0xE44A1Full);
  return {amplitude, 2.0 * M_PI / wavelength, rng.uniform(0, 2 * M_PI), rng.uniform(0, 2 * M_PI)};
}

/// The sensor pose at `xy` heading `yaw`, standing on the terrain: z up the
/// ground normal, x along the path tilted with the slope.
Eigen::Isometry3d poseOnTerrain(const Terrain& terrain, const Eigen::Vector2d& xy, double yaw) {
  const Eigen::Vector2d g = terrain.gradient(xy);
  const Eigen::Vector2d dir(std::cos(yaw), std::sin(yaw));
  const Eigen::Vector3d normal = Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
  const Eigen::Vector3d x = Eigen::Vector3d(dir.x(), dir.y(), g.dot(dir)).normalized();
  const Eigen::Vector3d y = normal.cross(x).normalized();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() << x, y, x.cross(y);
  T.translation() << xy, terrain.height(xy);
  return T;
}

// ---------------------------------------------------------------- paths

/// A straight line (curvature 0) or a circular arc of a planar path.
struct Piece {
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
  double heading = 0.0;    ///< rad at the start
  double length = 0.0;     ///< m
  double curvature = 0.0;  ///< 1/m, positive turns left
};

/// A point of a path with its heading.
struct PathPoint {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  double heading = 0.0;
};

PathPoint pointInPiece(const Piece& p, double s) {
  const double h = p.heading + p.curvature * s;
  if (std::abs(p.curvature) < 1e-12)
    return {p.start + s * Eigen::Vector2d(std::cos(p.heading), std::sin(p.heading)), h};
  const Eigen::Vector2d d(std::sin(h) - std::sin(p.heading), std::cos(p.heading) - std::cos(h));
  return {p.start + d / p.curvature, h};
}

/// A planar path of lines and arcs, continuous in position and heading.
class Path {
 public:
  void add(const Piece& piece) {
    if (piece.length <= 1e-9) return;
    starts_.push_back(length_);
    pieces_.push_back(piece);
    length_ += piece.length;
  }

  [[nodiscard]] double length() const { return length_; }

  /// The point `s` metres along the path, clamped to its ends.
  [[nodiscard]] PathPoint at(double s) const {
    s = std::clamp(s, 0.0, length_);
    auto it = std::upper_bound(starts_.begin(), starts_.end(), s);
    const auto i = std::size_t(std::max<std::ptrdiff_t>(it - starts_.begin() - 1, 0));
    return pointInPiece(pieces_[i], std::min(s - starts_[i], pieces_[i].length));
  }

 private:
  std::vector<Piece> pieces_;
  std::vector<double> starts_;
  double length_ = 0.0;
};

using Polyline = std::vector<Eigen::Vector2d>;

double headingOf(const Eigen::Vector2d& d) {
  return std::atan2(d.y(), d.x());
}

double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

/// Lines between the points of `pts`, every interior corner replaced by an arc of `radius`.
Path filletPolyline(const Polyline& pts, double radius) {
  Path path;
  Eigen::Vector2d cursor = pts.front();
  for (std::size_t k = 1; k + 1 < pts.size(); ++k) {
    const Eigen::Vector2d d1 = (pts[k] - pts[k - 1]).normalized();
    const Eigen::Vector2d d2 = (pts[k + 1] - pts[k]).normalized();
    const double turn = std::atan2(cross2(d1, d2), d1.dot(d2));
    const double tangent = radius * std::tan(std::abs(turn) / 2);
    const Eigen::Vector2d arc_start = pts[k] - d1 * tangent;
    path.add({cursor, headingOf(d1), (arc_start - cursor).norm(), 0.0});
    path.add({arc_start, headingOf(d1), radius * std::abs(turn), (turn > 0 ? 1.0 : -1.0) / radius});
    cursor = pts[k] + d2 * tangent;
  }
  path.add({cursor, headingOf(pts.back() - cursor), (pts.back() - cursor).norm(), 0.0});
  return path;
}

/// The right-hand normal of the edge a -> b.
Eigen::Vector2d rightNormal(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d d = (b - a).normalized();
  return {d.y(), -d.x()};
}

/// `pts` moved `offset` metres to the right of the driving direction (a lane),
/// corners kept on the bisector so every edge stays parallel to its original.
Polyline offsetPolyline(const Polyline& pts, double offset, bool closed) {
  const std::size_t n = pts.size();
  Polyline out(n);
  for (std::size_t k = 0; k < n; ++k) {
    const bool has_prev = closed || k > 0;
    const bool has_next = closed || k + 1 < n;
    const Eigen::Vector2d n_in = has_prev ? rightNormal(pts[(k + n - 1) % n], pts[k])
                                          : rightNormal(pts[k], pts[(k + 1) % n]);
    const Eigen::Vector2d n_out = has_next ? rightNormal(pts[k], pts[(k + 1) % n]) : n_in;
    out[k] = pts[k] + offset * (n_in + n_out) / (1.0 + n_in.dot(n_out));
  }
  return out;
}

/// A closed loop through `corners` (in driving order), rounded, starting halfway along the first
/// edge.
Path loopPath(const Polyline& corners, double radius) {
  const Eigen::Vector2d mid = (corners[0] + corners[1]) / 2;
  Polyline pts{mid};
  for (std::size_t k = 1; k <= corners.size(); ++k) pts.push_back(corners[k % corners.size()]);
  pts.push_back(mid);
  return filletPolyline(pts, radius);
}

// ---------------------------------------------------------------- speed

/// Trapezoidal speed: wait, accelerate, cruise, brake to a stop at the end.
struct SpeedProfile {
  double length = 0.0;        ///< m to drive
  double speed = 1.0;         ///< m/s cruise
  double acceleration = 0.5;  ///< m/s^2
  double wait = 0.0;          ///< s standing still at the start

  [[nodiscard]] double rampTime() const { return speed / acceleration; }
  [[nodiscard]] double rampLength() const { return speed * speed / (2 * acceleration); }
  [[nodiscard]] double driveTime() const {
    return 2 * rampTime() + (length - 2 * rampLength()) / speed;
  }
  [[nodiscard]] double duration() const { return wait + driveTime(); }

  /// Metres driven at time t.
  [[nodiscard]] double arcAt(double t) const {
    const double tau = t - wait;
    const double drive = driveTime();
    if (tau <= 0) return 0.0;
    if (tau >= drive) return length;
    if (tau < rampTime()) return 0.5 * acceleration * tau * tau;
    if (tau > drive - rampTime()) return length - 0.5 * acceleration * std::pow(drive - tau, 2);
    return rampLength() + speed * (tau - rampTime());
  }

  /// The time at which `s` metres are driven.
  [[nodiscard]] double timeAt(double s) const {
    s = std::clamp(s, 0.0, length);
    if (s <= rampLength()) return wait + std::sqrt(2 * s / acceleration);
    if (s >= length - rampLength())
      return wait + driveTime() - std::sqrt(2 * (length - s) / acceleration);
    return wait + rampTime() + (s - rampLength()) / speed;
  }
};

SpeedProfile makeProfile(double length, double speed, double acceleration, double wait = 0.0) {
  // A route too short to reach cruise speed brakes as soon as it has accelerated.
  speed = std::min(speed, std::sqrt(acceleration * length));
  return {length, speed, acceleration, wait};
}

// ---------------------------------------------------------------- plans

/// One robot's path, where on it the robot starts and how it drives it.
struct RoutePlan {
  Path path{};
  bool closed = false;  ///< a loop: the route starts `phase` metres along and wraps around
  double phase = 0.0;   ///< m
  SpeedProfile profile{};

  /// The path point `s` metres along the route.
  [[nodiscard]] PathPoint point(double s) const {
    if (!closed) return path.at(s);
    return path.at(std::fmod(phase + s, path.length()));
  }

  /// The route distance of the route point nearest `p` (searched every 0.25 m).
  [[nodiscard]] double arcNear(const Eigen::Vector2d& p) const {
    double best = 0.0;
    double best_d2 = INFINITY;
    for (double s = 0.0; s <= profile.length; s += 0.25) {
      const double d2 = (point(s).xy - p).squaredNorm();
      if (d2 < best_d2) best_d2 = d2, best = s;
    }
    return best;
  }

  /// When the robot passes nearest to `p`.
  [[nodiscard]] double timeNear(const Eigen::Vector2d& p) const {
    return profile.timeAt(arcNear(p));
  }
};

/// The poses of `plan` at `rate` Hz from time 0 to the end, on `terrain`.
core::Trajectory samplePlan(const RoutePlan& plan, const Terrain& terrain, double rate) {
  const double duration = plan.profile.duration();
  const auto n = static_cast<std::size_t>(std::floor(duration * rate + 1e-9)) + 1;
  core::Trajectory out;
  out.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double t = double(k) / rate;
    const PathPoint p = plan.point(plan.profile.arcAt(t));
    out.push_back(t, poseOnTerrain(terrain, p.xy, p.heading));
  }
  return out;
}

Route makeRoute(std::size_t index, core::Trajectory T_world_sensor) {
  return {core::robotName(core::RobotId(static_cast<std::uint8_t>(index))),
          std::move(T_world_sensor)};
}

void checkRobotCount(int robots, const char* what) {
  if (robots < 1 || robots > 255)
    throw core::Error(std::string(what) + ": robots must be 1 to 255, not " +
                      std::to_string(robots));
}

// ---------------------------------------------------------------- campus

/// The sides of a campus block.
enum class Side { south, east, north, west };

/// One robot's block of the campus grid and how it drives around it.
struct Cell {
  int col = 0;
  int row = 0;
  bool ccw = true;  ///< counter-clockwise (even rows) or clockwise (odd rows)
};

Cell cellOf(int index, int cols) {
  const int row = index / cols;
  return {index % cols, row, row % 2 == 0};
}

/// The block's corners on the street centrelines, in driving order.
Polyline blockCorners(const Cell& c, double pitch) {
  const double x0 = c.col * pitch, x1 = x0 + pitch;
  const double y0 = c.row * pitch, y1 = y0 + pitch;
  if (c.ccw) return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  return {{x0, y0}, {x0, y1}, {x1, y1}, {x1, y0}};
}

/// Index of `side` in blockCorners' edges (edge k runs from corner k to k + 1).
std::size_t sideIndex(Side side, bool ccw) {
  static constexpr std::array<std::size_t, 4> kCcw{0, 1, 2, 3};  // south east north west
  static constexpr std::array<std::size_t, 4> kCw{3, 2, 1, 0};   // west north east south
  return (ccw ? kCcw : kCw)[std::size_t(side)];
}

/// The U around three sides of the block (all but `dropped`), legs extended by `extension`.
Polyline uPolyline(const Polyline& corners, std::size_t dropped, double extension) {
  Polyline pts;
  for (std::size_t k = 1; k <= 4; ++k) pts.push_back(corners[(dropped + k) % 4]);
  pts.front() -= (pts[1] - pts[0]).normalized() * extension;
  pts.back() += (pts[3] - pts[2]).normalized() * extension;
  return pts;
}

/// The side a U may leave out without losing a street shared with a neighbour.
Side droppableSide(const Cell& c, Rng& rng) {
  if (c.col == 0) return Side::west;
  return rng.uniform(0, 1) < 0.5 ? Side::north : Side::south;
}

/// The middle of the street this cell shares with its partner (left, or below for column 0).
Eigen::Vector2d sharedStreetMiddle(const Cell& c, double pitch) {
  const double x0 = c.col * pitch, y0 = c.row * pitch;
  if (c.col > 0) return {x0, y0 + pitch / 2};
  return {x0 + pitch / 2, y0};
}

/// The partner a robot plans its rendezvous with: left neighbour, or below for column 0.
int partnerOf(const Cell& c, int cols) {
  if (c.col > 0) return c.row * cols + c.col - 1;
  return (c.row - 1) * cols;
}

RoutePlan loopPlan(const Cell& c, double speed, const CampusRouteConfig& config) {
  RoutePlan plan;
  const Polyline lane =
      offsetPolyline(blockCorners(c, config.block_pitch), config.lane_offset, true);
  plan.path = loopPath(lane, config.corner_radius);
  plan.closed = true;
  plan.profile = makeProfile(plan.path.length(), speed, config.acceleration);
  return plan;
}

RoutePlan uPlan(const Cell& c, Side dropped, double speed, const CampusRouteConfig& config) {
  const Polyline corners = blockCorners(c, config.block_pitch);
  const Polyline u = uPolyline(corners, sideIndex(dropped, c.ccw), config.block_pitch / 2);
  RoutePlan plan;
  plan.path = filletPolyline(offsetPolyline(u, config.lane_offset, false), config.corner_radius);
  plan.profile = makeProfile(plan.path.length(), speed, config.acceleration);
  return plan;
}

/// Starts the loop `back` metres before the point from which it would pass
/// `meet` at time `when` (waiting at the start if it is early).
void scheduleLoop(RoutePlan& plan, const Eigen::Vector2d& meet, double when, double back,
                  const CampusRouteConfig& config) {
  const double L = plan.path.length();
  plan.phase = 0.0;
  plan.profile.wait = 0.0;
  const double on_path = plan.arcNear(meet);
  const double s = std::min(plan.profile.arcAt(when), 0.8 * L) + back;
  plan.phase = std::fmod(on_path - s + 2 * L, L);
  plan.profile.wait = std::clamp(when - plan.profile.timeAt(s), 0.0, config.max_wait);
}

/// Waits at the start of the U so that it passes `meet` at time `when`; false if it cannot.
bool scheduleU(RoutePlan& plan, const Eigen::Vector2d& meet, double when,
               const CampusRouteConfig& config) {
  const double wait = when - plan.timeNear(meet);
  if (wait < 0.0 || wait > config.max_wait) return false;
  plan.profile.wait = wait;
  return true;
}

/// The random choices of one campus robot.
struct Draw {
  double speed = 1.5;          ///< m/s cruise
  bool want_u = false;         ///< asks for a U route
  Side dropped = Side::north;  ///< the side a U leaves out
  double phase = 0.0;          ///< in [0, 1), where the root robot starts its loop
};

Draw drawRobot(const Cell& cell, std::uint64_t seed, int index, const CampusRouteConfig& config) {
  Rng rng = streamRng(seed, std::uint64_t(index) + 1);
  Draw d;
  d.speed = rng.uniform(config.min_speed, config.max_speed);
  d.want_u = rng.uniform(0, 1) < config.u_route_share;
  d.dropped = droppableSide(cell, rng);
  d.phase = rng.uniform(0, 1);
  return d;
}

/// True when `plan` starts at least `min_distance` from every earlier robot's start.
bool startIsClear(const RoutePlan& plan, const std::vector<RoutePlan>& before,
                  double min_distance) {
  const Eigen::Vector2d start = plan.point(0).xy;
  return std::none_of(before.begin(), before.end(), [&](const RoutePlan& other) {
    return (other.point(0).xy - start).norm() < min_distance;
  });
}

/// A U that meets its partner at `when`, trying a few cruise speeds; none if no U can.
std::optional<RoutePlan> scheduledU(const Cell& cell, const Draw& draw, const Eigen::Vector2d& meet,
                                    double when, const std::vector<RoutePlan>& before,
                                    const CampusRouteConfig& config) {
  const double mid = (config.min_speed + config.max_speed) / 2;
  for (const double v : {draw.speed, config.max_speed, mid, config.min_speed}) {
    RoutePlan plan = uPlan(cell, draw.dropped, v, config);
    if (scheduleU(plan, meet, when, config) &&
        startIsClear(plan, before, config.min_start_separation))
      return plan;
  }
  return std::nullopt;
}

/// A loop that meets its partner at `when` or, if that start is taken, a little later.
RoutePlan scheduledLoop(const Cell& cell, const Draw& draw, const Eigen::Vector2d& meet,
                        double when, const std::vector<RoutePlan>& before,
                        const CampusRouteConfig& config) {
  RoutePlan plan = loopPlan(cell, draw.speed, config);
  for (int k = 0; k < 10; ++k) {  // start up to 27 m further back, 3 m at a time
    scheduleLoop(plan, meet, when, 3.0 * k, config);
    if (startIsClear(plan, before, config.min_start_separation)) break;
  }
  return plan;
}

/// Plans robot `index`, given the plans of the robots before it.
RoutePlan planCampusRobot(int index, int cols, std::uint64_t seed,
                          const std::vector<RoutePlan>& before, const CampusRouteConfig& config) {
  const Cell cell = cellOf(index, cols);
  const Draw draw = drawRobot(cell, seed, index, config);
  if (index == 0) {
    if (draw.want_u) return uPlan(cell, draw.dropped, draw.speed, config);
    RoutePlan plan = loopPlan(cell, draw.speed, config);
    plan.phase = draw.phase * plan.path.length();
    return plan;
  }
  const Eigen::Vector2d meet = sharedStreetMiddle(cell, config.block_pitch);
  const double when =
      before[std::size_t(partnerOf(cell, cols))].timeNear(meet) + config.rendezvous_gap;
  if (draw.want_u) {
    if (auto plan = scheduledU(cell, draw, meet, when, before, config)) return *plan;
  }
  return scheduledLoop(cell, draw, meet, when, before, config);
}

}  // namespace

std::vector<Route> campusRoutes(int robots, std::uint64_t seed, const CampusRouteConfig& config) {
  checkRobotCount(robots, "campusRoutes");
  if (config.columns < 0) throw core::Error("campusRoutes: columns must not be negative");
  const int cols = config.columns > 0 ? std::min(config.columns, robots)
                                      : static_cast<int>(std::ceil(std::sqrt(double(robots))));
  const Terrain terrain = makeTerrain(seed, config.terrain_amplitude, config.terrain_wavelength);
  std::vector<RoutePlan> plans;
  std::vector<Route> routes;
  for (int i = 0; i < robots; ++i) {
    plans.push_back(planCampusRobot(i, cols, seed, plans, config));
    routes.push_back(makeRoute(std::size_t(i), samplePlan(plans.back(), terrain, config.rate)));
  }
  return routes;
}

std::vector<Route> aliasingRoutes(int robots, std::uint64_t seed,
                                  const AliasingRouteConfig& config) {
  checkRobotCount(robots, "aliasingRoutes");
  if (!(config.route_length > 0.0) || config.route_length > config.corridor_length)
    throw core::Error("aliasingRoutes: route_length must be in (0, corridor_length]");
  const Terrain terrain = makeTerrain(seed, config.terrain_amplitude, config.terrain_wavelength);
  const double spare = config.corridor_length - config.route_length;
  std::vector<Route> routes;
  for (int i = 0; i < robots; ++i) {
    Rng rng = streamRng(seed, std::uint64_t(i) + 1);
    const double even = robots == 1 ? 0.0 : spare * i / (robots - 1);
    const double start = std::clamp(even + rng.uniform(-5.0, 5.0), 0.0, spare);
    const bool east = i % 2 == 0;
    const double y = east ? -config.lane_offset : config.lane_offset;
    const Eigen::Vector2d a(east ? start : start + config.route_length, y);
    const Eigen::Vector2d b(east ? start + config.route_length : start, y);
    RoutePlan plan;
    plan.path.add({a, headingOf(b - a), config.route_length, 0.0});
    plan.profile =
        makeProfile(config.route_length, config.speed * rng.uniform(0.9, 1.1), config.acceleration);
    routes.push_back(makeRoute(std::size_t(i), samplePlan(plan, terrain, config.rate)));
  }
  return routes;
}

std::vector<Route> crossingRoutes(std::uint64_t seed, const CrossingRouteConfig& config) {
  if (!(config.route_length > 0.0))
    throw core::Error("crossingRoutes: route_length must be positive");
  const Terrain terrain = makeTerrain(seed, config.terrain_amplitude, config.terrain_wavelength);
  std::vector<Route> routes;
  for (int i = 0; i < 2; ++i) {
    Rng rng = streamRng(seed, std::uint64_t(i) + 1);
    const double heading = i == 0 ? 0.0 : M_PI / 2 + core::deg2rad(rng.uniform(-10.0, 10.0));
    const Eigen::Vector2d along(std::cos(heading), std::sin(heading));
    const Eigen::Vector2d right(along.y(), -along.x());
    const Eigen::Vector2d start = -0.5 * config.route_length * along + config.lane_offset * right;
    RoutePlan plan;
    plan.path.add({start, heading, config.route_length, 0.0});
    plan.profile =
        makeProfile(config.route_length, config.speed * rng.uniform(0.9, 1.1), config.acceleration);
    routes.push_back(makeRoute(std::size_t(i), samplePlan(plan, terrain, config.rate)));
  }
  return routes;
}

}  // namespace dcl::sim
