#pragma once

/// Procedural worlds generated along given routes, deterministically from a seed.

#include <cstdint>
#include <span>

#include <dcl/core/trajectory.hpp>
#include <dcl/sim/world.hpp>

namespace dcl::sim {

/// What a world is generated around: the sensors' routes (ground-truth
/// T_world_sensor of every robot) and how high the sensor rides above the ground.
struct WorldRequest {
  std::span<const core::Trajectory> routes;  ///< sensor poses in the world frame
  double mount_height = 1.73;                ///< m, sensor above the ground
  std::uint64_t seed = 1;                    ///< everything random derives from it
};

/// How a generated world looks. Distances are horizontal, from the route
/// centreline unless said otherwise. The defaults are the city's.
struct WorldStyle {
  // Roads.
  double road_half_width = 7.5;  ///< m, asphalt either side of the centreline, parking included
  double pavement_width = 2.5;   ///< m, raised pavement beyond the road edge
  double kerb_height = 0.12;     ///< m, pavement top above the road
  // Buildings: one lot after another along each side of every route.
  double setback_min = 11.0;    ///< m, centreline to front facade, least
  double setback_max = 16.0;    ///< m, centreline to front facade, most
  double frontage_min = 12.0;   ///< m, building width along the road, least
  double frontage_max = 30.0;   ///< m, building width along the road, most
  double depth_min = 10.0;      ///< m, building depth away from the road, least
  double depth_max = 20.0;      ///< m, building depth away from the road, most
  double gap_min = 1.0;         ///< m, between neighbouring buildings, least
  double gap_max = 5.0;         ///< m, between neighbouring buildings, most
  int floors_min = 2;           ///< storeys, least
  int floors_max = 7;           ///< storeys, most
  double floor_height = 3.0;    ///< m a storey
  double open_share = 0.08;     ///< share of lots left open (squares, lawns with trees)
  double back_row_share = 0.6;  ///< share of lots with a second, taller building behind
  double relief_share = 0.8;    ///< share of buildings with pillars, balconies and a cornice
  double front_share = 0.4;     ///< share of lots with a hedge or garden wall at the pavement
  // Street furniture and vegetation.
  double tree_spacing = 10.0;      ///< m between tree slots along the pavement
  double tree_share = 0.5;         ///< share of tree slots holding a tree
  double lawn_tree_density = 0.2;  ///< trees per 100 m^2 of open lot
  double parking_share = 0.0;      ///< share of open lots that are car parks
  /// Shrubs per 100 m^2 of front garden (between the pavement, or its hedge,
  /// and a facade set back far enough); an open lawn has a quarter as many.
  double shrub_density = 20.0;
  double pole_spacing = 30.0;  ///< m between lamp posts and sign poles along each side
  double car_share = 0.7;      ///< share of parking slots (6.5 m) holding a car
  // Terrain.
  double extent = 120.0;           ///< m, no geometry farther than this from every route
  double ground_cell = 2.0;        ///< m, ground mesh spacing within 50 m of a route (8 m beyond)
  double terrain_amplitude = 1.5;  ///< m, low-frequency relief away from the roads
  double ground_roughness = 0.03;  ///< m, per-vertex ground noise off the road
  double terrain_blend = 40.0;     ///< m, from the pavement's edge to free terrain
  // Dense layouts (the campus): props spaced apart, the land between the streets filled.
  /// m; > 0: every building keeps this far from the props placed before it (other props
  /// 0.3-0.5 m), shrinks to fit, and lots on bends stay open; 0: props are not checked
  /// against each other (the city's lots never meet).
  double min_building_gap = 0.0;
  /// m; > 0 (with min_building_gap > 0): a jittered grid of this pitch fills the land
  /// the lots leave (block interiors, beyond the outer streets) with buildings facing
  /// the nearest street, lawns and car parks; 0: no infill.
  double infill_spacing = 0.0;
  double infill_reach = 75.0;    ///< m, no infill site farther than this from every route (nor
                                 ///< than extent - frontage_max)
  double infill_setback = 9.0;   ///< m, least distance of an infill building from every route
  double bike_rack_share = 0.0;  ///< share of infill buildings with a bike rack in front
  // Perceptual aliasing.
  double repeat_period = 0.0;  ///< m; > 0: every lot identical, one every period along each route
};

/// The city: 15 m streets lined with parked cars, 2-7 storey blocks 11-16 m from the centreline,
/// their front gardens planted with shrubs.
WorldStyle cityStyle();
/// The campus: narrow roads, 1-4 storey buildings of varied size 5-8 m back from the road
/// and filling the blocks and the land beyond the outer streets, many trees, hedges,
/// low walls, lamp posts, bike racks, car parks and lawns.
WorldStyle campusStyle();
/// Perceptual aliasing: one 40 m block (same buildings, trees, cars) repeated on flat ground.
WorldStyle aliasingStyle();

/// A world of `style` around the request's routes. Distances from "the
/// centreline" are from the street's middle: where lanes run side by side (robots
/// passing both ways), from the middle of all of them. Nothing but road, kerb and
/// ground comes within 3.3 m of a route pose; the road under every pose lies
/// exactly `mount_height` below it, except where routes disagree: a revisit
/// within 4 m of an earlier pass drives on that pass's road (ground truth's
/// heights differ between passes), and near a junction of two grades the
/// higher road covers the lower. Deterministic in the request and style.
World generateWorld(const WorldRequest& request, const WorldStyle& style);

/// A city: roads along the routes, building blocks set back from them with
/// varied footprints, heights and facade relief, trees, poles, parked cars,
/// kerbs, on a gently sloped noisy ground that meets every route at mount height.
World generateCityWorld(const WorldRequest& request);

/// A campus: lower, more spread buildings than the city, inside the blocks and beyond
/// the streets too, with trees, hedges, lamp posts, bike racks and car parks.
World generateCampusWorld(const WorldRequest& request);

/// Perceptual aliasing: identical blocks repeated along the routes, so that
/// different places look alike.
World generateAliasingWorld(const WorldRequest& request);

}  // namespace dcl::sim
