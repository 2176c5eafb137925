#pragma once

/// Moving actors of a simulated world: cars driving the streets both ways and
/// stopping now and then, cyclists, pedestrians walking the pavements and
/// crossing the street, cars parked for part of the time. Each actor is a few
/// boxes moving along its own path; the scan simulator casts the beams against
/// them at each column's time, so an actor moves during a sweep as it would
/// in the world. Actors are never part of the ground truth: they are what a
/// front-end and a place recogniser must see past.
///
/// Deterministic in the routes, the style, the density and the seed. Actors
/// keep out of the robots' way (their routes are the ground truth and do not
/// yield): an actor with a robot on its path ahead waits, and an actor that
/// a robot would still come within half a metre of is not there at that moment.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include <dcl/sim/world.hpp>
#include <dcl/sim/world_gen.hpp>

namespace dcl::sim {

/// What an actor is.
enum class ActorKind : std::uint8_t {
  car,         ///< a moving car in a lane
  cyclist,     ///< a bicycle and its rider near the road's edge
  pedestrian,  ///< a person on the pavement, some crossing the street
  parked_car,  ///< a car in the parking lane for part of the time
};

/// "car", "cyclist", "pedestrian" or "parked car".
const char* toString(ActorKind kind);

/// One box of an actor's body, in the actor's frame (x forward, y left, z up
/// from the ground under the actor's origin).
struct ActorBox {
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();  ///< m
  Eigen::Vector3f half = Eigen::Vector3f::Ones();    ///< m, half extents along x, y, z
};

/// Where an actor is: its origin on the ground and its heading.
struct ActorPose {
  float x = 0.0f, y = 0.0f, z = 0.0f;  ///< m, world frame
  float yaw = 0.0f;                    ///< rad, heading of the actor's x axis
};

/// One actor: its body and its poses sampled at a fixed step from `start`
/// to the end of its life.
struct Actor {
  ActorKind kind = ActorKind::car;
  Surface surface = Surface::vehicle;  ///< what the beams that meet it see
  std::vector<ActorBox> boxes{};
  float radius = 0.0f;  ///< m, horizontal radius around the origin containing every box
  double start = 0.0;   ///< s, time of the first pose
  double step = 0.1;    ///< s between poses
  std::vector<ActorPose> poses{};
  std::vector<std::uint8_t> absent{};  ///< 1 where the actor is not there (a robot too close)

  /// Half extents (along x, y) of the rectangle around every box's footprint.
  [[nodiscard]] Eigen::Vector2f footprint() const;
  /// Time of the last pose.
  [[nodiscard]] double end() const { return start + step * static_cast<double>(poses.size() - 1); }
  /// The pose at time `t`, interpolated; none outside the actor's life or
  /// when it is absent at either neighbouring pose.
  [[nodiscard]] std::optional<ActorPose> at(double t) const;
};

/// How much moves in a world at a density scale of 1. Counts are the mean
/// number present per km of street at any moment (both directions, both sides).
struct TrafficStyle {
  double cars_per_km = 0.0;
  double cyclists_per_km = 0.0;
  double pedestrians_per_km = 0.0;
  double parked_per_km = 0.0;   ///< cars parked for a while, then gone (none without parking lane)
  double crossing_share = 0.3;  ///< share of pedestrians crossing the street
  double car_stop_spacing = 250.0;  ///< m, mean distance a car drives between stops
  double lane_offset = 3.5;         ///< m, street centreline to the middle of a car lane
  double car_speed_min = 6.0;       ///< m/s, least cruising speed of a car
  double car_speed_max = 13.0;      ///< m/s, most
};

/// The city's traffic: KITTI-like streets, tens of moving objects in view at times.
TrafficStyle cityTraffic();
/// The campus: few slow cars, many pedestrians and cyclists, no parking lane.
TrafficStyle campusTraffic();

/// Everything that moves in one world.
struct Traffic {
  std::vector<Actor> actors{};

  [[nodiscard]] bool empty() const { return actors.empty(); }
  /// Number of actors of `kind`.
  [[nodiscard]] std::size_t count(ActorKind kind) const;
};

/// The traffic of a world of `style` generated around `request`'s routes:
/// `density` times the style's traffic (0: none), alive over the routes' time
/// span (their stamps). Streets are the routes' own (a street driven twice
/// carries one set of lanes). Deterministic in its arguments.
Traffic generateTraffic(const WorldRequest& request, const WorldStyle& style,
                        const TrafficStyle& traffic, double density);

}  // namespace dcl::sim
