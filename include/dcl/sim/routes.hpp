#pragma once

/// The robots' routes: ground-truth sensor trajectories in one shared world
/// frame, either from real KITTI ground truth (converted to the LiDAR frame
/// and split into robots as the paper does) or generated (campus loops and
/// U-turn routes with planned rendezvous, a perceptual-aliasing corridor).
///
/// Every route's stamps start at 0: the robots of a dataset run concurrently,
/// each from its own time zero, and each robot's odometry frame is its first
/// pose (T_world_odom = T_world_sensor(0)).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <dcl/core/trajectory.hpp>

namespace dcl::sim {

/// One robot's ground-truth route.
struct Route {
  std::string name{};                 ///< robot name: "a", "b", ... (core::robotName)
  core::Trajectory T_world_sensor{};  ///< sensor poses in the shared world frame, stamps from 0

  /// The robot's odometry frame in the world: its first pose (identity when empty).
  [[nodiscard]] Eigen::Isometry3d T_world_odom() const;

  /// The route in the robot's own odometry frame (T_odom_sensor, first pose identity).
  [[nodiscard]] core::Trajectory inOdomFrame() const;

  /// Path length in metres.
  [[nodiscard]] double length() const { return T_world_sensor.length(); }

  /// Duration in seconds (last stamp minus first; 0 when fewer than two poses).
  [[nodiscard]] double duration() const;
};

// ---------------------------------------------------------------- KITTI

/// Converts KITTI ground truth T_cam0(0)_cam0(t) to the LiDAR frame, with the
/// world being the LiDAR frame at the first pose (z up):
/// T_world_velo(t) = T_cam_velo^-1 * T_world_cam(t) * T_cam_velo. Each rotation
/// is projected onto SO(3) (KITTI prints 7 digits) so the poses are exactly
/// rigid. Stamps are kept.
core::Trajectory kittiToLidar(const core::Trajectory& T_world_cam,
                              const Eigen::Isometry3d& T_cam_velo);

/// Reads a KITTI pose file and a `calib.txt` and returns the LiDAR-frame
/// trajectory (kittiToLidar). Stamps come from `times_path` when given, else
/// `frame_period` seconds per frame starting at 0.
core::Trajectory loadKittiLidarTrajectory(const std::string& poses_path,
                                          const std::string& calib_path,
                                          const std::optional<std::string>& times_path = {},
                                          double frame_period = 0.1);

/// `T_world_sensor` with every step's climb limited to `max_grade` times its
/// horizontal travel (rotations unchanged). Ground truth has vertical glitches a
/// vehicle cannot drive: KITTI 08's rises 20 m in its first 12 s while the car
/// creeps forward level. A simulated world must put a road under every pose,
/// so such climbs are flattened; the rest of the profile is kept.
core::Trajectory limitGrade(const core::Trajectory& T_world_sensor, double max_grade);

/// Settings of levelRevisits.
struct LevelConfig {
  double radius = 5.0;         ///< m, a pose this close (horizontally) to an earlier pass is on it
  double min_travel = 100.0;   ///< m of travel between two poses before they count as passes
  double revisit_weight = 10;  ///< weight of "same height" against each step's kept climb
};

/// `T_world_sensor` with its heights made consistent where it drives a road
/// again (rotations and horizontal positions unchanged). Ground truth drifts in
/// height (KITTI 08 comes back to a street 3 m below where it left it), and
/// limitGrade's flattening shifts the rest of a profile; a simulated world has
/// one road there, so a robot on the later pass would drive under it. Solves
/// one linear least-squares problem over the heights: keep each step's climb,
/// and put poses within `radius` of each other on different passes at the same
/// height, which spreads each disagreement over the drive between the passes.
core::Trajectory levelRevisits(const core::Trajectory& T_world_sensor,
                               const LevelConfig& config = {});

/// Cuts `trajectory` into consecutive pieces by path length: piece i is
/// `lengths[i]` metres long (to the nearest pose), and a last piece takes the
/// rest, so there are lengths.size() + 1 routes. Pieces do not share poses;
/// each is re-timed to start at 0 and named "a", "b", ... Throws core::Error
/// when a length is not positive or the trajectory is too short for them.
std::vector<Route> splitByLength(const core::Trajectory& trajectory,
                                 std::span<const double> lengths);

/// How a KITTI sequence is split into robots.
struct KittiSplit {
  std::string sequence{};       ///< "00", "05" or "08"
  std::vector<double> lengths;  ///< metres of every robot but the last (the last takes the rest)
};

/// The split of a KITTI sequence. 05 into 424.9 m, 599.9 m and the rest, 08
/// into 1252.8 m and the rest: the paper's Table I (the rest is longer than the
/// paper's 1066.7 m and 1991.6 m, which stop short of the sequences' ends).
/// 00 (no paper figure) into 1250 m, 1250 m and the rest: a's streets are
/// driven again by c the same way (about 400 m) and the other way at two
/// places, b and c share about 110 m the same way, so every robot overlaps
/// another. Throws core::Error for another sequence.
KittiSplit kittiSplit(const std::string& sequence);

/// The ground-truth file paths of a KITTI sequence under the shared data folder.
struct KittiFiles {
  std::string poses{};                 ///< KITTI pose file (left camera frame)
  std::optional<std::string> times{};  ///< times file, when the data has one
  std::string calib{};                 ///< calib.txt (kitti_00's serves 05 and 08 too)
};

/// Where sequence "00", "05" or "08" lives under `data_dir`; throws core::Error otherwise.
KittiFiles kittiFiles(const std::string& data_dir, const std::string& sequence);

/// The steepest climb kittiRoutes keeps (10 %, a steep city street; 00 and 05 stay under 7 %).
inline constexpr double kKittiMaxGrade = 0.10;

/// The robots' routes of a KITTI sequence: loaded from `data_dir`, converted to
/// the LiDAR frame, limited to kKittiMaxGrade (limitGrade), levelled where it
/// drives a street again (levelRevisits) and split by kittiSplit.
std::vector<Route> kittiRoutes(const std::string& data_dir, const std::string& sequence);

// ---------------------------------------------------------------- overlaps

/// How two robots' headings compare where their routes overlap.
enum class OverlapKind {
  same_direction,      ///< heading difference under 45 degrees
  opposite_direction,  ///< heading difference over 135 degrees
  crossing,            ///< in between (a junction)
};

/// "same", "opposite" or "crossing".
std::string toString(OverlapKind kind);

/// Settings of findOverlaps.
struct OverlapConfig {
  double radius = 10.0;     ///< m, two poses closer than this overlap (horizontal distance)
  double step = 1.0;        ///< m, route poses are examined every `step` metres of travel
  double min_length = 5.0;  ///< m, shorter overlap stretches are dropped
  double max_gap = 3.0;     ///< m, a stretch continues across gaps up to this long
};

/// A stretch where robot `robot_a` passes within `radius` of robot `robot_b`'s route.
struct Overlap {
  std::size_t robot_a = 0;  ///< index of the first robot (robot_a < robot_b)
  std::size_t robot_b = 0;  ///< index of the second robot
  std::size_t first_a = 0;  ///< first pose index of the stretch on robot_a's route
  std::size_t last_a = 0;   ///< last pose index of the stretch on robot_a's route
  std::size_t first_b = 0;  ///< lowest pose index on robot_b's route near the stretch
  std::size_t last_b = 0;   ///< highest pose index on robot_b's route near the stretch
  /// World position of the stretch's middle on robot_a's route.
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double length = 0.0;                       ///< m, length of the stretch along robot_a's route
  OverlapKind kind = OverlapKind::crossing;  ///< heading relation all along the stretch
  /// Only the seam of a consecutive split: robot_a's piece ends where robot_b's starts.
  bool handover = false;
};

/// Every overlap between routes of different robots, ordered by robot pair and
/// then along robot_a's route.
std::vector<Overlap> findOverlaps(std::span<const Route> routes, const OverlapConfig& config = {});

/// True when the graph with one node per robot and an edge per overlap (of
/// any kind, handovers excluded) is connected.
bool overlapGraphConnected(std::size_t robots, std::span<const Overlap> overlaps);

// ---------------------------------------------------------------- generated

/// Settings of the generated campus routes.
struct CampusRouteConfig {
  double block_pitch = 70.0;   ///< m, distance between street centrelines of the campus grid
  double corner_radius = 8.0;  ///< m, corners are arcs of this radius
  double lane_offset = 1.5;    ///< m, robots drive this far right of the street centreline
  double min_speed = 1.5;      ///< m/s, cruise speed is drawn in [min_speed, max_speed]
  double max_speed = 2.0;      ///< m/s
  double acceleration = 0.5;   ///< m/s^2, at the start and at the end of each route
  double rate = 10.0;          ///< Hz, poses per second
  /// Probability that a robot asks for a U route; it drives a loop when no U can meet its partner.
  double u_route_share = 0.7;
  /// Blocks in a row of the grid; 0: ceil(sqrt(robots)), a square. One column
  /// puts every robot's block above the last, so that neighbours all drive
  /// their shared street the same way.
  int columns = 0;
  double max_wait = 40.0;       ///< s, longest wait at the start to make a planned rendezvous
  double rendezvous_gap = 3.0;  ///< s, a robot reaches a rendezvous this long after its partner
  double min_start_separation = 10.0;  ///< m, no robot starts closer than this to another
  double terrain_amplitude = 1.0;      ///< m, amplitude of the gentle ground undulation
  double terrain_wavelength = 250.0;   ///< m, its wavelength
};

/// `robots` robots (1 to 255) on a campus street grid, one block each, laid
/// out row by row (`columns` blocks to a row, a square grid by default): each
/// drives a loop around its block or a U around three of its sides (legs
/// extended half a block), smooth (rounded corners, speed ramps), yaw along
/// the path, z and tilt following a gentle terrain. Every
/// robot shares a street with the robot to its left (or, first in a row, the
/// one below), so the overlap graph is connected; rows alternate the driving
/// sense, so that neighbours in a row meet head-on and neighbours across rows
/// drive the same way. Each robot's start is planned so that it passes the
/// middle of that shared street `rendezvous_gap` seconds after its partner (a
/// rendezvous; a loop starts a little further back when its start would be
/// within `min_start_separation` of another robot's). Deterministic in `seed`.
/// Throws core::Error for a robot count outside 1..255 or negative columns.
std::vector<Route> campusRoutes(int robots, std::uint64_t seed,
                                const CampusRouteConfig& config = {});

/// Settings of the perceptual-aliasing routes.
struct AliasingRouteConfig {
  double corridor_length = 420.0;     ///< m, the straight street along +x the robots share
  double route_length = 260.0;        ///< m, each robot's stretch of it
  double lane_offset = 1.5;           ///< m, right of the centreline in the driving direction
  double speed = 2.0;                 ///< m/s cruise speed
  double acceleration = 0.5;          ///< m/s^2 at the start and the end
  double rate = 10.0;                 ///< Hz, poses per second
  double terrain_amplitude = 0.5;     ///< m, amplitude of the gentle ground undulation
  double terrain_wavelength = 300.0;  ///< m, its wavelength
};

/// `robots` robots (1 to 255) along one long straight corridor (the aliasing
/// world repeats identical blocks along it): robot i starts at an evenly spaced
/// offset, even robots drive +x, odd robots -x, so same- and opposite-direction
/// overlaps exist and identical-looking places are passed at different true
/// positions. The seed jitters the starts and speeds a little. Throws
/// core::Error for a robot count outside 1..255 or a route longer than the corridor.
std::vector<Route> aliasingRoutes(int robots, std::uint64_t seed,
                                  const AliasingRouteConfig& config = {});

/// Settings of the crossing routes.
struct CrossingRouteConfig {
  double route_length = 160.0;        ///< m, each robot's straight street
  double lane_offset = 1.5;           ///< m, right of the centreline in the driving direction
  double speed = 2.0;                 ///< m/s cruise speed
  double acceleration = 0.5;          ///< m/s^2 at the start and the end
  double rate = 10.0;                 ///< Hz, poses per second
  double terrain_amplitude = 1.0;     ///< m, amplitude of the gentle ground undulation
  double terrain_wavelength = 250.0;  ///< m, its wavelength
};

/// Two robots on straight streets that cross at their middles, at right
/// angles give or take a few degrees (the seed's): they see each other's
/// place for a few keyframes, where they pass the crossing, and nowhere else
/// (robots that meet once, briefly, as they mostly do in the field). The
/// seed also jitters the speeds.
std::vector<Route> crossingRoutes(std::uint64_t seed, const CrossingRouteConfig& config = {});

// ---------------------------------------------------------------- the body

/// How a vehicle's body rocks on its suspension, the sensor with it: it
/// pitches nose down when it brakes (up when it accelerates), rolls out of a
/// turn, and the road's roughness shakes it in pitch and roll while it moves.
/// Each axis is a damped spring: the body follows its equilibrium (the
/// accelerations' tilt) with the overshoot of a real one, and the road drives
/// it with noise. The defaults give a car's fast pitch and roll (less their
/// 2 s mean) of about 0.2 deg, as KITTI's ground truth has (`bench sensor`).
struct BodyMotion {
  double pitch_per_accel_deg = 0.25;  ///< deg of pitch per m/s^2 along the path
  double roll_per_accel_deg = 0.5;    ///< deg of roll per m/s^2 across it
  double road_sigma_deg = 0.3;        ///< deg, 1 sigma of the road's pitch and roll at speed
  double full_speed = 2.0;            ///< m/s from which the road shakes fully (none standing)
  double bump_spacing = 25.0;         ///< m of road between two bumps on average (joints, potholes)
  double bump_deg = 1.0;              ///< deg, 1 sigma of the swing a bump starts in pitch and roll
  double frequency_hz = 1.4;          ///< the body's natural frequency on its springs
  double damping = 0.35;              ///< its damping ratio
};

/// `T_world_sensor` (x forward, z up) with its body's motion added: the pitch
/// and roll of `motion` about the body's axes, pivoting on the ground
/// `mount_height` below the sensor (so that the sensor also sways a little).
/// The accelerations come from the trajectory itself. A generated route
/// drives a rigid plank over its terrain; real cars rock. Deterministic in
/// `seed`. Trajectories of fewer than three poses come back unchanged.
core::Trajectory rockBody(const core::Trajectory& T_world_sensor, double mount_height,
                          std::uint64_t seed, const BodyMotion& motion = {});

}  // namespace dcl::sim
