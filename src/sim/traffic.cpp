// Moving actors: lanes and pavements along the routes' streets, and a small
// time-stepped simulation of who moves where (see traffic.hpp).

#include <algorithm>
#include <cmath>
#include <limits>

#include <dcl/core/error.hpp>
#include <dcl/sim/traffic.hpp>

#include "world_detail.hpp"

namespace dcl::sim {
namespace {

constexpr double kStep = 0.1;            // s between an actor's poses
constexpr double kPathStep = 1.0;        // m between a path's vertices
constexpr double kMinStreet = 30.0;      // m, shorter fresh stretches carry no traffic
constexpr double kAbsentMargin = 0.5;    // m, an actor nearer a robot's sensor is not there
constexpr double kBrake = 3.0;           // m/s^2, comfortable deceleration
constexpr double kAccelerate = 1.5;      // m/s^2
constexpr double kRobotLookahead = 2.0;  // s, robots this far ahead in time are waited for

/// A polyline on the ground with its arc length.
class ActorPath {
 public:
  void add(const Eigen::Vector3d& p) {
    if (!points_.empty()) {
      const double d = (p.head<2>() - points_.back().head<2>()).norm();
      if (d < 1e-3) return;
      arc_.push_back(arc_.back() + d);
    } else {
      arc_.push_back(0.0);
    }
    points_.push_back(p);
  }
  [[nodiscard]] double length() const { return arc_.empty() ? 0.0 : arc_.back(); }
  [[nodiscard]] bool valid() const { return points_.size() >= 2; }

  /// The point at arc length `s` (clamped).
  [[nodiscard]] Eigen::Vector3d at(double s) const {
    if (s <= 0.0) return points_.front();
    if (s >= length()) return points_.back();
    const auto it = std::upper_bound(arc_.begin(), arc_.end(), s);
    const auto i = static_cast<std::size_t>(it - arc_.begin());
    const double f = (s - arc_[i - 1]) / (arc_[i] - arc_[i - 1]);
    return points_[i - 1] + f * (points_[i] - points_[i - 1]);
  }
  /// Heading of the path around `s`.
  [[nodiscard]] double yaw(double s) const {
    const Eigen::Vector3d d = at(s + 1.0) - at(s - 1.0);
    return std::atan2(d.y(), d.x());
  }
  [[nodiscard]] ActorPath reversed() const {
    ActorPath out;
    for (auto it = points_.rbegin(); it != points_.rend(); ++it) out.add(*it);
    return out;
  }
  /// The stretch [s0, s1] (s1 < s0 runs backwards) resampled every kPathStep.
  [[nodiscard]] ActorPath between(double s0, double s1) const {
    ActorPath out;
    const int n = std::max(1, static_cast<int>(std::abs(s1 - s0) / kPathStep));
    for (int i = 0; i <= n; ++i) out.add(at(s0 + (s1 - s0) * i / n));
    return out;
  }
  void append(const ActorPath& other) {
    for (const auto& p : other.points_) add(p);
  }

 private:
  std::vector<Eigen::Vector3d> points_;
  std::vector<double> arc_;
};

/// A fresh stretch of one route: a street carrying its own traffic.
struct Street {
  std::size_t route = 0;
  double s0 = 0.0, s1 = 0.0;  ///< arc length on the route
};

/// The street's line at `offset` m to the left of its centreline (negative:
/// right), `rise` m above the road, in the route's direction. Vertices where a
/// tight bend would fold the offset line back are left out.
ActorPath offsetLine(const detail::RouteIndex& index, const Street& street, double offset,
                     double rise) {
  ActorPath path;
  Eigen::Vector2d last = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  for (double s = street.s0; s <= street.s1 + 1e-9; s += kPathStep) {
    const auto f = index.frameAt(street.route, s);
    const Eigen::Vector2d p = f.xy + offset * f.left;
    if (!std::isnan(last.x()) && (p - last).dot(f.along) < 0.1) continue;
    path.add({p.x(), p.y(), f.z_road + rise});
    last = p;
  }
  return path;
}

/// The fresh stretches of every route at least kMinStreet long.
std::vector<Street> streetsOf(const detail::RouteIndex& index) {
  std::vector<Street> streets;
  for (std::size_t r = 0; r < index.routeCount(); ++r) {
    const double length = index.length(r);
    double begin = -1.0;
    for (double s = 0.0;; s += kPathStep) {
      const bool end = s > length;
      const bool fresh = !end && index.frameAt(r, s).fresh;
      if (fresh && begin < 0.0) begin = s;
      if (!fresh && begin >= 0.0) {
        if (s - kPathStep - begin >= kMinStreet) streets.push_back({r, begin, s - kPathStep});
        begin = -1.0;
      }
      if (end) break;
    }
  }
  return streets;
}

/// Where every robot is on the time grid of the simulation (NaN outside its route's span).
class RobotClock {
 public:
  RobotClock(std::span<const core::Trajectory> routes, double t0, std::size_t steps) {
    positions_.resize(routes.size());
    for (std::size_t r = 0; r < routes.size(); ++r) {
      positions_[r].resize(steps);
      for (std::size_t k = 0; k < steps; ++k) {
        const auto pose = routes[r].at(t0 + kStep * static_cast<double>(k));
        positions_[r][k] =
            pose ? Eigen::Vector2d(pose->translation().head<2>()) : Eigen::Vector2d::Constant(kFar);
      }
    }
  }
  /// Each robot's position at step `k` (far away when it is not driving then).
  template <class F>
  void forEach(std::size_t k, F&& f) const {
    for (const auto& robot : positions_) {
      if (k < robot.size()) f(robot[k]);
    }
  }

 private:
  static constexpr double kFar = 1e9;
  std::vector<std::vector<Eigen::Vector2d>> positions_;
};

/// Distance from `p` to the footprint of a box of half extents `half` around
/// `centre` turned by `yaw`.
double footprintDistance(const Eigen::Vector2d& p, const Eigen::Vector2d& centre, double yaw,
                         const Eigen::Vector2d& half) {
  const Eigen::Vector2d d = p - centre;
  const double c = std::cos(yaw), s = std::sin(yaw);
  const Eigen::Vector2d local(c * d.x() + s * d.y(), -s * d.x() + c * d.y());
  const Eigen::Vector2d outside = (local.cwiseAbs() - half).cwiseMax(0.0);
  return outside.norm();
}

/// The body of an actor of `kind`, sized at random within its kind.
Actor makeBody(ActorKind kind, detail::Rng& rng) {
  Actor a;
  a.kind = kind;
  const auto box = [&](double x, double y, double z0, double z1, double hx, double hy) {
    a.boxes.push_back({Eigen::Vector3f(static_cast<float>(x), static_cast<float>(y),
                                       static_cast<float>((z0 + z1) / 2)),
                       Eigen::Vector3f(static_cast<float>(hx), static_cast<float>(hy),
                                       static_cast<float>((z1 - z0) / 2))});
  };
  switch (kind) {
    case ActorKind::car:
    case ActorKind::parked_car: {
      const double length = rng.uniform(3.9, 4.9), width = rng.uniform(1.7, 1.9);
      const double roof = rng.uniform(1.4, 1.6);
      a.surface = Surface::vehicle;
      box(0.0, 0.0, 0.3, 1.0, length / 2, width / 2);                        // body
      box(-0.05 * length, 0.0, 1.0, roof, 0.28 * length, width / 2 - 0.08);  // cabin
      box(0.33 * length, 0.0, 0.0, 0.3, 0.3, width / 2 - 0.05);              // front wheels
      box(-0.33 * length, 0.0, 0.0, 0.3, 0.3, width / 2 - 0.05);             // rear wheels
      break;
    }
    case ActorKind::cyclist:
      a.surface = Surface::person;
      box(0.0, 0.0, 0.05, 0.95, 0.85, 0.08);  // bicycle
      box(-0.1, 0.0, 0.95, 1.8, 0.25, 0.22);  // rider
      break;
    case ActorKind::pedestrian: {
      const double height = rng.uniform(1.55, 1.9);
      a.surface = Surface::person;
      box(0.0, 0.0, 0.0, 0.47 * height, 0.12, 0.17);     // legs
      box(0.0, 0.0, 0.47 * height, height, 0.14, 0.24);  // torso and head
      break;
    }
  }
  for (const auto& b : a.boxes) {
    a.radius = std::max(a.radius, (b.centre.head<2>().cwiseAbs() + b.half.head<2>()).norm());
  }
  return a;
}

/// What a mover does on its path.
struct Behaviour {
  double speed_min = 1.0, speed_max = 1.5;  ///< m/s, cruising
  double gap = 1.0;                         ///< m kept to the one ahead
  double stop_spacing = 0.0;                ///< m between stops on average; 0: never stops
  double lookahead = 3.0;                   ///< m of path ahead kept free of robots
  double robot_clearance = 1.5;             ///< m, a robot nearer the path ahead is waited for
};

/// One actor moving along one path.
struct Mover {
  Actor actor;
  Eigen::Vector2d half;
  double s = 0.0, v = 0.0, cruise = 0.0;
  double next_stop = std::numeric_limits<double>::infinity();
  double waiting = 0.0;  ///< s left standing at a stop
  bool done = false;
  detail::Rng rng{0};  ///< its own: where it stops and for how long
};

/// The actors of one path (a lane or a pavement in one direction), from the
/// ones there at `t0` and the ones arriving at its start later, moved step by
/// step: cruising, following, stopping now and then, waiting for robots.
class Lane {
 public:
  Lane(ActorPath path, ActorKind kind, Behaviour behaviour, const RobotClock& robots)
      : path_(std::move(path)), kind_(kind), behaviour_(behaviour), robots_(robots) {}

  /// `present` actors spread over the path at `t0`, and arrivals at a mean
  /// rate of `rate` per s until `t1`.
  void populate(double present, double rate, double t0, double t1, detail::Rng& rng) {
    const int n = static_cast<int>(present + rng.uniform());
    std::vector<double> at;
    for (int i = 0; i < n; ++i) at.push_back(rng.uniform(0.0, path_.length()));
    std::sort(at.begin(), at.end(), std::greater<>());
    for (double s : at) movers_.push_back(spawn(s, t0, rng));
    if (rate > 0.0) {
      for (double t = t0 - std::log(1.0 - rng.uniform()) / rate; t < t1;
           t -= std::log(1.0 - rng.uniform()) / rate) {
        arrivals_.push_back(t);
      }
    }
    rng_seed_ = rng.next();
  }

  /// One actor entering the path's start at `t`.
  void arrive(double t, detail::Rng& rng) {
    arrivals_.push_back(t);
    rng_seed_ = rng.next();
  }

  /// Runs the lane from `t0` for `steps` steps and appends its actors to `out`.
  void run(double t0, std::size_t steps, std::vector<Actor>& out) {
    detail::Rng rng(rng_seed_);
    std::size_t next_arrival = 0;
    std::vector<Mover> active = std::move(movers_);
    for (std::size_t k = 0; k < steps; ++k) {
      const double t = t0 + kStep * static_cast<double>(k);
      // Arrivals enter at the path's start when the last one has moved on.
      while (next_arrival < arrivals_.size() && arrivals_[next_arrival] <= t) {
        const bool free = active.empty() || active.back().s - active.back().half.x() >
                                                behaviour_.gap + 2.0 * active.back().half.x();
        if (!free) break;
        active.push_back(spawn(0.0, t, rng));
        ++next_arrival;
      }
      for (std::size_t i = 0; i < active.size(); ++i) {
        Mover& m = active[i];
        if (m.done) continue;
        move(m, i == 0 ? nullptr : &active[i - 1], k);
        record(m, k);
        if (m.s >= path_.length()) m.done = true;
      }
      // Finished movers leave the front of the queue.
      while (!active.empty() && active.front().done) {
        out.push_back(std::move(active.front().actor));
        active.erase(active.begin());
      }
    }
    for (auto& m : active) out.push_back(std::move(m.actor));
  }

 private:
  Mover spawn(double s, double t, detail::Rng& rng) {
    Mover m;
    m.actor = makeBody(kind_, rng);
    m.actor.start = t;
    m.actor.step = kStep;
    m.half = m.actor.footprint().cast<double>();
    m.s = s;
    m.cruise = rng.uniform(behaviour_.speed_min, behaviour_.speed_max);
    m.v = m.cruise;
    m.rng = detail::Rng(rng.next());
    if (behaviour_.stop_spacing > 0.0) m.next_stop = s + nextStop(m);
    return m;
  }

  /// How far a mover drives to its next stop (exponential, the behaviour's mean).
  [[nodiscard]] double nextStop(Mover& m) const {
    return -behaviour_.stop_spacing * std::log(1.0 - m.rng.uniform());
  }

  /// The distance ahead along the path (from the mover's front) to the first
  /// point a robot is near now or within kRobotLookahead; infinite if none.
  [[nodiscard]] double robotAhead(const Mover& m, std::size_t k) const {
    const auto lookahead_steps = static_cast<std::size_t>(kRobotLookahead / kStep);
    for (double d = 0.0; d <= behaviour_.lookahead; d += 1.0) {
      const Eigen::Vector2d q = path_.at(m.s + m.half.x() + d).head<2>();
      bool near = false;
      for (std::size_t dk = 0; dk <= lookahead_steps && !near; dk += lookahead_steps / 2) {
        robots_.forEach(k + dk, [&](const Eigen::Vector2d& robot) {
          if ((robot - q).norm() < behaviour_.robot_clearance + m.half.y()) near = true;
        });
      }
      if (near) return d;
    }
    return std::numeric_limits<double>::infinity();
  }

  void move(Mover& m, const Mover* leader, std::size_t k) {
    double target = m.cruise;
    if (leader != nullptr && !leader->done) {
      const double gap = leader->s - leader->half.x() - (m.s + m.half.x()) - behaviour_.gap;
      target = std::min(target, std::sqrt(2.0 * kBrake * std::max(0.0, gap)));
    }
    if (m.waiting > 0.0) {
      m.waiting -= kStep;
      target = 0.0;
      if (m.waiting <= 0.0) m.next_stop = m.s + nextStop(m);
    } else if (std::isfinite(m.next_stop)) {
      const double d = m.next_stop - m.s;
      target = std::min(target, std::sqrt(2.0 * kBrake * std::max(0.0, d)));
      if (d < 0.5 && m.v < 0.5) {
        m.waiting = m.rng.uniform(2.0, 10.0);
        m.next_stop = std::numeric_limits<double>::infinity();
      }
    }
    const double robot = robotAhead(m, k);
    if (std::isfinite(robot))
      target = std::min(target, std::sqrt(2.0 * kBrake * std::max(0.0, robot - 1.0)));
    m.v = std::min(target, m.v + kAccelerate * kStep);
    m.s += m.v * kStep;
  }

  void record(Mover& m, std::size_t k) const {
    const Eigen::Vector3d p = path_.at(m.s);
    const double yaw = path_.yaw(m.s);
    // Robots between this step and its neighbours count too: at() interpolates.
    bool absent = false;
    for (std::size_t j = k == 0 ? 0 : k - 1; j <= k + 1; ++j) {
      robots_.forEach(j, [&](const Eigen::Vector2d& robot) {
        if (footprintDistance(robot, p.head<2>(), yaw, m.half) < kAbsentMargin) absent = true;
      });
    }
    m.actor.poses.push_back({static_cast<float>(p.x()), static_cast<float>(p.y()),
                             static_cast<float>(p.z()), static_cast<float>(yaw)});
    m.actor.absent.push_back(absent ? 1 : 0);
  }

  ActorPath path_;
  ActorKind kind_;
  Behaviour behaviour_;
  const RobotClock& robots_;
  std::vector<Mover> movers_;
  std::vector<double> arrivals_;
  std::uint64_t rng_seed_ = 0;
};

/// A path that walks `a` m along one pavement, crosses the street at the
/// end, and walks on along the other pavement for `b` m.
ActorPath crossingPath(const detail::RouteIndex& index, const Street& street, double s_cross,
                       double side, double a, double b, double pavement, double rise) {
  const ActorPath from = offsetLine(index, street, side * pavement, rise);
  const ActorPath to = offsetLine(index, street, -side * pavement, rise);
  const double s = s_cross - street.s0;
  ActorPath path = from.between(std::max(0.0, s - a), s);
  path.append(to.between(s, std::min(to.length(), s + b)));
  return path;
}

}  // namespace

const char* toString(ActorKind kind) {
  switch (kind) {
    case ActorKind::car:
      return "car";
    case ActorKind::cyclist:
      return "cyclist";
    case ActorKind::pedestrian:
      return "pedestrian";
    case ActorKind::parked_car:
      return "parked car";
  }
  return "actor";
}

std::optional<ActorPose> Actor::at(double t) const {
  if (poses.empty() || t < start || t > end()) return std::nullopt;
  if (poses.size() == 1) return absent[0] ? std::nullopt : std::optional(poses[0]);
  const double u = (t - start) / step;
  const auto i = std::min(static_cast<std::size_t>(u), poses.size() - 2);
  if (absent[i] || absent[i + 1]) return std::nullopt;
  const auto f = static_cast<float>(u - static_cast<double>(i));
  const ActorPose& a = poses[i];
  const ActorPose& b = poses[i + 1];
  float turn = b.yaw - a.yaw;
  if (turn > static_cast<float>(M_PI)) turn -= 2.0f * static_cast<float>(M_PI);
  if (turn < -static_cast<float>(M_PI)) turn += 2.0f * static_cast<float>(M_PI);
  return ActorPose{a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), a.z + f * (b.z - a.z),
                   a.yaw + f * turn};
}

Eigen::Vector2f Actor::footprint() const {
  Eigen::Vector2f half = Eigen::Vector2f::Zero();
  for (const ActorBox& b : boxes)
    half = half.cwiseMax(b.centre.head<2>().cwiseAbs() + b.half.head<2>());
  return half;
}

std::size_t Traffic::count(ActorKind kind) const {
  return static_cast<std::size_t>(
      std::count_if(actors.begin(), actors.end(), [&](const Actor& a) { return a.kind == kind; }));
}

TrafficStyle cityTraffic() {
  TrafficStyle t;
  t.cars_per_km = 20.0;
  t.cyclists_per_km = 6.0;
  t.pedestrians_per_km = 40.0;
  t.parked_per_km = 10.0;
  return t;
}

TrafficStyle campusTraffic() {
  TrafficStyle t;
  t.cars_per_km = 6.0;
  t.cyclists_per_km = 12.0;
  t.pedestrians_per_km = 60.0;
  t.parked_per_km = 0.0;
  t.lane_offset = 2.6;
  t.car_speed_min = 4.0;
  t.car_speed_max = 8.0;
  t.car_stop_spacing = 150.0;
  return t;
}

Traffic generateTraffic(const WorldRequest& request, const WorldStyle& style,
                        const TrafficStyle& traffic, double density) {
  if (!(density >= 0.0)) throw core::Error("traffic density must be 0 or more");
  Traffic out;
  if (density == 0.0 || request.routes.empty()) return out;
  double t0 = std::numeric_limits<double>::infinity(), t1 = -t0;
  for (const auto& route : request.routes) {
    if (route.empty()) continue;
    t0 = std::min(t0, route.stamps().front());
    t1 = std::max(t1, route.stamps().back() + 0.2);  // the last sweep
  }
  if (!(t1 > t0)) return out;
  const auto steps = static_cast<std::size_t>((t1 - t0) / kStep) + 2;
  const detail::RouteIndex index(request.routes, request.mount_height);
  const RobotClock robots(request.routes, t0,
                          steps + static_cast<std::size_t>(kRobotLookahead / kStep) + 1);
  detail::Rng rng(detail::mix(request.seed, 0x7aff1c));

  const double w = style.road_half_width;
  const bool parking = w >= 5.0;  // as the world generator: a parking lane on wide roads
  const double cycle_offset = parking ? w - 2.5 : w - 0.9;
  const double pavement = w + 0.5 * style.pavement_width;
  const Behaviour car{
      traffic.car_speed_min, traffic.car_speed_max, 6.0, traffic.car_stop_spacing, 12.0, 1.2};
  const Behaviour cyclist{3.5, 6.0, 3.0, 0.0, 6.0, 1.2};
  const Behaviour walker{1.0, 1.6, 1.0, 0.0, 2.0, 1.5};

  std::vector<Lane> lanes;
  // Per km of street -> per m of one path (a lane or pavement in one direction).
  const auto perPath = [&](double per_km, int paths) { return density * per_km / 1000.0 / paths; };
  /// A path of `kind` carrying `per_m` actors a metre, arriving at its start
  /// as they leave at `speed`.
  const auto addPath = [&](const ActorPath& path, ActorKind kind, const Behaviour& b, double per_m,
                           double speed) {
    if (!path.valid()) return;
    lanes.emplace_back(path, kind, b, robots);
    lanes.back().populate(per_m * path.length(), per_m * speed, t0, t1, rng);
  };
  const double car_speed = (traffic.car_speed_min + traffic.car_speed_max) / 2;
  for (const Street& street : streetsOf(index)) {
    // Right-hand traffic: the lanes right of the route run with it, the left ones against it.
    const auto line = [&](double offset, double rise = 0.0) {
      return offsetLine(index, street, offset, rise);
    };
    for (double side : {-1.0, 1.0}) {
      const auto way = [side](const ActorPath& path) { return side < 0 ? path : path.reversed(); };
      addPath(way(line(side * traffic.lane_offset)), ActorKind::car, car,
              perPath(traffic.cars_per_km, 2), car_speed);
      addPath(way(line(side * cycle_offset)), ActorKind::cyclist, cyclist,
              perPath(traffic.cyclists_per_km, 2), 4.75);
      // Pedestrians walk both ways on both pavements.
      const ActorPath pavement_line = line(side * pavement, style.kerb_height);
      const double walking =
          perPath(traffic.pedestrians_per_km * (1.0 - traffic.crossing_share), 4);
      addPath(pavement_line, ActorKind::pedestrian, walker, walking, 1.3);
      addPath(pavement_line.reversed(), ActorKind::pedestrian, walker, walking, 1.3);
    }
    // Crossing pedestrians: each walks a stretch, crosses and walks on; about
    // a minute on their path, so the street's share is renewed every minute.
    const double length = street.s1 - street.s0;
    const double crossings = density * traffic.pedestrians_per_km * traffic.crossing_share *
                             length / 1000.0 * (t1 - t0) / 60.0;
    const int n_cross = static_cast<int>(crossings + rng.uniform());
    for (int i = 0; i < n_cross; ++i) {
      const double s = rng.uniform(street.s0 + 10.0, street.s1 - 10.0);
      const double side = rng.chance(0.5) ? 1.0 : -1.0;
      ActorPath path = crossingPath(index, street, s, side, rng.uniform(5.0, 40.0),
                                    rng.uniform(5.0, 40.0), pavement, style.kerb_height);
      if (!path.valid()) continue;
      lanes.emplace_back(std::move(path), ActorKind::pedestrian, walker, robots);
      // One walker, setting off at a random moment (at once when that is before t0).
      lanes.back().arrive(std::max(t0, rng.uniform(t0 - 30.0, t1)), rng);
    }
    // Cars parked for a while.
    if (parking && traffic.parked_per_km > 0.0) {
      const double expected = density * traffic.parked_per_km * length / 1000.0;
      const int n = static_cast<int>(expected + rng.uniform());
      for (int i = 0; i < n; ++i) {
        const double s = rng.uniform(street.s0, street.s1);
        const double side = rng.chance(0.5) ? 1.0 : -1.0;
        const auto f = index.frameAt(street.route, s);
        const Eigen::Vector2d xy = f.xy + side * (w - 1.1) * f.left;
        const double yaw = std::atan2(f.along.y(), f.along.x()) + (side > 0 ? M_PI : 0.0);
        Actor a = makeBody(ActorKind::parked_car, rng);
        const double span = t1 - t0;
        const double begin = rng.uniform(t0 - 0.5 * span, t1);
        const double end = std::min(t1, begin + rng.uniform(0.1, 0.6) * span);
        a.start = std::max(t0, begin);
        if (end < a.start + 1.0) continue;  // gone before the robots came
        a.step = end - a.start;
        const ActorPose pose{static_cast<float>(xy.x()), static_cast<float>(xy.y()),
                             static_cast<float>(f.z_road), static_cast<float>(yaw)};
        a.poses = {pose, pose};
        a.absent = {0, 0};
        out.actors.push_back(std::move(a));
      }
    }
  }
  for (Lane& lane : lanes) lane.run(t0, steps, out.actors);
  return out;
}

}  // namespace dcl::sim
