#include <functional>
#include <string>
#include <vector>

#include <dcl/core/error.hpp>
#include <dcl/sim/presets.hpp>

namespace dcl::sim {
namespace {

constexpr double kKittiMountHeight = 1.73;  ///< m, KITTI's HDL-64 above the road
constexpr double kUgvMountHeight = 1.0;     ///< m, a VLP-16 on a small ground robot

/// How a preset is made: its fixed description and a route builder.
struct Recipe {
  std::string name;
  std::string description;
  std::string world;
  std::string sensor;
  double mount_height;
  int default_robots;  ///< robots when options.robots == 0
  bool fixed_robots;   ///< the robot count cannot change (KITTI splits)
  std::function<std::vector<Route>(const PresetOptions&, int robots)> routes;
  bool calibration_error = true;  ///< the robots' lasers off the published table
  bool shared_unit = false;       ///< one LiDAR unit for every robot (one car's drive split)
  /// Every robot reads up from an IMU with each scan, as the paper's robots
  /// do (their front-ends, LIO-SAM and FAST-LIO2, need one).
  bool imu = true;
  /// The vehicle's body can rock on its suspension (rockBody, with
  /// PresetOptions::body_motion). KITTI's ground truth is a real car's,
  /// rocking already.
  bool rocks = true;
};

std::vector<Route> kitti(const PresetOptions& options, const std::string& sequence) {
  if (options.data_dir.empty())
    throw core::Error("KITTI presets need the shared data folder (--data DIR or DCL_DATA_DIR)");
  return kittiRoutes(options.data_dir, sequence);
}

Recipe kittiRecipe(const std::string& sequence, int robots) {
  Recipe recipe{"kitti" + sequence + "-" + std::to_string(robots),
                "KITTI " + sequence + " ground truth split into " + std::to_string(robots) +
                    " robots, city world, HDL-64",
                "city",
                "hdl64",
                kKittiMountHeight,
                robots,
                true,
                [sequence](const PresetOptions& o, int) { return kitti(o, sequence); }};
  // One car drove the whole sequence: its parts carry that car's one HDL-64
  // (and its one IMU, KITTI's OXTS RT3003).
  recipe.shared_unit = true;
  recipe.rocks = false;
  return recipe;
}

Recipe campusRecipe(int robots) {
  return {"campus-" + std::to_string(robots),
          std::to_string(robots) +
              " ground robots on campus loops and U routes with rendezvous, VLP-16",
          "campus",
          "vlp16",
          kUgvMountHeight,
          robots,
          false,
          [](const PresetOptions& o, int n) { return campusRoutes(n, o.seed); }};
}

/// Small and fast: three VLP-16 robots on loops around 50 m blocks, about
/// 180 m each. VLP-16 scans are a quarter of an HDL-64's rays, which keeps the
/// whole swarm quick; loops give every robot its own loop closure, and the
/// block layout gives a head-on and a same-direction inter-robot overlap.
std::vector<Route> smallRoutes(const PresetOptions& options, int robots) {
  CampusRouteConfig config;
  config.block_pitch = 50.0;
  config.u_route_share = 0.0;
  config.min_speed = 1.8;
  return campusRoutes(robots, options.seed, config);
}

/// The demo: three cars with a VLP-16 each on the roof (KITTI's height), every
/// one on a 600 m loop around a city block of its own at 7-8 m/s, the blocks
/// one above the other, so that each car drives a street with its neighbours
/// the same way (the middle one with both), a few seconds apart. At a car's
/// speed the odometry drifts a decimetre or two over the loop; each car's own
/// loop closure and the loops with its neighbours take most of it out, and
/// the loops with the neighbours put the three in one frame and one map.
std::vector<Route> demoRoutes(const PresetOptions& options, int robots) {
  CampusRouteConfig config;
  config.block_pitch = 150.0;
  config.u_route_share = 0.0;
  config.min_speed = 7.0;
  config.max_speed = 8.0;
  config.columns = 1;
  return campusRoutes(robots, options.seed, config);
}

const std::vector<Recipe>& recipes() {
  static const std::vector<Recipe> all{
      kittiRecipe("00", 3),
      kittiRecipe("05", 3),
      kittiRecipe("08", 2),
      campusRecipe(3),
      campusRecipe(9),
      // Perfect lasers: the corridor tests place recognition and PCM against
      // aliasing. With the lasers' calibration errors the odometry along its
      // bare walls drifts 4 % (0.7 % with perfect lasers), more than the
      // odometry covariance PCM checks loops against allows, and PCM keeps
      // a consistent set of aliases instead of the true loops.
      {"aliasing-3", "3 robots along a corridor of identical blocks (perceptual aliasing), VLP-16",
       "aliasing", "vlp16", kUgvMountHeight, 3, false,
       [](const PresetOptions& o, int n) { return aliasingRoutes(n, o.seed); }, false},
      {"small-3", "small and fast: 3 robots on ~180 m campus loops with overlaps, VLP-16", "campus",
       "vlp16", kUgvMountHeight, 3, false, smallRoutes},
      {"demo", "the built-in demo: 3 cars on 600 m loops around city blocks in a column, VLP-16",
       "city", "vlp16", kKittiMountHeight, 3, false, demoRoutes},
      // Two robots that meet once: their streets cross, and nothing else of
      // their routes is shared. Their maps merge on the few loops there.
      {"crossing-2", "2 robots on campus streets that cross once and share nothing else, VLP-16",
       "campus", "vlp16", kUgvMountHeight, 2, true,
       [](const PresetOptions& o, int) { return crossingRoutes(o.seed); }},
  };
  return all;
}

std::string joinedNames() {
  std::string out;
  for (const std::string& name : presetNames()) out += (out.empty() ? "" : ", ") + name;
  return out;
}

const Recipe& findRecipe(const std::string& name) {
  for (const Recipe& r : recipes())
    if (r.name == name) return r;
  throw core::Error("unknown preset '" + name + "' (known: " + joinedNames() + ")");
}

int robotCount(const Recipe& recipe, int requested) {
  if (requested < 0) throw core::Error("robots must not be negative");
  if (requested == 0) return recipe.default_robots;
  if (recipe.fixed_robots && requested != recipe.default_robots)
    throw core::Error("preset '" + recipe.name + "' has exactly " +
                      std::to_string(recipe.default_robots) + " robots, not " +
                      std::to_string(requested));
  return requested;
}

std::string sensorOf(const Recipe& recipe, const std::string& requested) {
  if (requested.empty()) return recipe.sensor;
  if (requested != "hdl64" && requested != "vlp16")
    throw core::Error("unknown sensor '" + requested + "' (known: hdl64, vlp16)");
  return requested;
}

}  // namespace

std::vector<std::string> presetNames() {
  std::vector<std::string> names;
  for (const Recipe& r : recipes()) names.push_back(r.name);
  return names;
}

Preset makePreset(const std::string& name, const PresetOptions& options) {
  const Recipe& recipe = findRecipe(name);
  Preset preset;
  preset.name = recipe.name;
  preset.description = recipe.description;
  preset.world = recipe.world;
  preset.sensor = sensorOf(recipe, options.sensor);
  preset.mount_height = recipe.mount_height;
  preset.seed = options.seed;
  preset.calibration_error = recipe.calibration_error;
  preset.shared_unit = recipe.shared_unit;
  preset.imu = recipe.imu;
  preset.routes = recipe.routes(options, robotCount(recipe, options.robots));
  if (recipe.rocks && options.body_motion)
    for (std::size_t i = 0; i < preset.routes.size(); ++i)
      preset.routes[i].T_world_sensor =
          rockBody(preset.routes[i].T_world_sensor, recipe.mount_height,
                   options.seed * 0x100000001B3ull + i);
  return preset;
}

}  // namespace dcl::sim
