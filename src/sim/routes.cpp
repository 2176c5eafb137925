#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <unordered_map>

#include <dcl/core/error.hpp>
#include <dcl/core/ids.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/sim/routes.hpp>

namespace dcl::sim {

// ---------------------------------------------------------------- Route

Eigen::Isometry3d Route::T_world_odom() const {
  if (T_world_sensor.empty()) return Eigen::Isometry3d::Identity();
  return T_world_sensor.pose(0);
}

core::Trajectory Route::inOdomFrame() const {
  core::Trajectory T_odom_sensor = T_world_sensor;
  T_odom_sensor.transformWorld(T_world_odom().inverse());
  return T_odom_sensor;
}

double Route::duration() const {
  if (T_world_sensor.size() < 2) return 0.0;
  return T_world_sensor.stamps().back() - T_world_sensor.stamps().front();
}

// ---------------------------------------------------------------- KITTI

namespace {

/// `T` with its rotation projected onto SO(3), translation unchanged.
Eigen::Isometry3d rigid(const Eigen::Isometry3d& T) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = core::projectToSO3(T.linear());
  out.translation() = T.translation();
  return out;
}

}  // namespace

core::Trajectory kittiToLidar(const core::Trajectory& T_world_cam,
                              const Eigen::Isometry3d& T_cam_velo) {
  const Eigen::Isometry3d T_velo_cam = T_cam_velo.inverse();
  core::Trajectory out;
  out.reserve(T_world_cam.size());
  for (std::size_t i = 0; i < T_world_cam.size(); ++i)
    out.push_back(T_world_cam.stamp(i), rigid(T_velo_cam * T_world_cam.pose(i) * T_cam_velo));
  // KITTI's first pose is the identity to 7 digits; re-anchor so the world is
  // exactly the LiDAR frame at the first pose.
  if (!out.empty()) out.transformWorld(out.pose(0).inverse());
  for (std::size_t i = 0; i < out.size(); ++i) out.pose(i) = rigid(out.pose(i));
  return out;
}

core::Trajectory loadKittiLidarTrajectory(const std::string& poses_path,
                                          const std::string& calib_path,
                                          const std::optional<std::string>& times_path,
                                          double frame_period) {
  core::Trajectory T_world_cam = io::readKittiPoses(poses_path, times_path);
  if (!times_path) {
    std::vector<double> stamps(T_world_cam.size());
    for (std::size_t i = 0; i < stamps.size(); ++i) stamps[i] = frame_period * double(i);
    T_world_cam = core::Trajectory(std::move(stamps), T_world_cam.poses());
  }
  return kittiToLidar(T_world_cam, io::readKittiCalib(calib_path).T_cam_velo);
}

core::Trajectory limitGrade(const core::Trajectory& T_world_sensor, double max_grade) {
  core::Trajectory out = T_world_sensor;
  double lowered = 0.0;  // how far the profile has been lowered so far (negative: raised)
  for (std::size_t i = 1; i < out.size(); ++i) {
    const Eigen::Vector3d step =
        T_world_sensor.pose(i).translation() - T_world_sensor.pose(i - 1).translation();
    const double limit = max_grade * step.head<2>().norm();
    lowered += step.z() - std::clamp(step.z(), -limit, limit);
    out.pose(i).translation().z() -= lowered;
  }
  return out;
}

core::Trajectory levelRevisits(const core::Trajectory& T_world_sensor, const LevelConfig& config) {
  const std::size_t n = T_world_sensor.size();
  if (n < 2) return T_world_sensor;
  if (!(config.radius > 0.0) || !(config.min_travel > 0.0) || !(config.revisit_weight > 0.0))
    throw core::Error("levelRevisits: radius, min_travel and revisit_weight must be positive");
  const std::vector<double> travel = T_world_sensor.distances();
  const auto xy = [&](std::size_t i) -> Eigen::Vector2d {
    return T_world_sensor.pose(i).translation().head<2>();
  };
  const auto z = [&](std::size_t i) { return T_world_sensor.pose(i).translation().z(); };

  // Horizontal grid of cell `radius` for the nearest pose of another pass.
  using Cell = std::int64_t;
  const auto cellOf = [&](const Eigen::Vector2d& p, int dx = 0, int dy = 0) -> Cell {
    const auto cx = static_cast<std::int64_t>(std::floor(p.x() / config.radius)) + dx;
    const auto cy = static_cast<std::int64_t>(std::floor(p.y() / config.radius)) + dy;
    return (cx << 32) ^ (cy & 0xffffffff);
  };
  std::unordered_map<Cell, std::vector<std::size_t>> grid;
  for (std::size_t i = 0; i < n; ++i) grid[cellOf(xy(i))].push_back(i);

  // Rows: z'_0 = z_0 (the gauge), z'_i - z'_(i-1) = z_i - z_(i-1), and
  // w (z'_i - z'_j) = 0 for j the nearest earlier pass within the radius.
  std::vector<Eigen::Triplet<double>> a;
  std::vector<double> b;
  const auto row = [&](std::size_t i, double ci, std::size_t j, double cj, double rhs) {
    const auto r = static_cast<int>(b.size());
    a.emplace_back(r, static_cast<int>(i), ci);
    if (cj != 0.0) a.emplace_back(r, static_cast<int>(j), cj);
    b.push_back(rhs);
  };
  row(0, 1.0, 0, 0.0, z(0));
  for (std::size_t i = 1; i < n; ++i) row(i, 1.0, i - 1, -1.0, z(i) - z(i - 1));
  for (std::size_t i = 0; i < n; ++i) {
    std::size_t best = n;
    double best_d = config.radius;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy) {
        const auto it = grid.find(cellOf(xy(i), dx, dy));
        if (it == grid.end()) continue;
        for (const std::size_t j : it->second) {
          if (j >= i || travel[i] - travel[j] < config.min_travel) continue;
          const double d = (xy(i) - xy(j)).norm();
          if (d < best_d) best_d = d, best = j;
        }
      }
    if (best < n) row(i, config.revisit_weight, best, -config.revisit_weight, 0.0);
  }
  Eigen::SparseMatrix<double> A(static_cast<Eigen::Index>(b.size()), static_cast<Eigen::Index>(n));
  A.setFromTriplets(a.begin(), a.end());
  const Eigen::SparseMatrix<double> AtA = A.transpose() * A;
  const Eigen::VectorXd Atb = A.transpose() * Eigen::Map<const Eigen::VectorXd>(
                                                  b.data(), static_cast<Eigen::Index>(b.size()));
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(AtA);
  if (solver.info() != Eigen::Success) throw core::Error("levelRevisits: factorisation failed");
  const Eigen::VectorXd levelled = solver.solve(Atb);
  core::Trajectory out = T_world_sensor;
  for (std::size_t i = 0; i < n; ++i)
    out.pose(i).translation().z() = levelled(static_cast<Eigen::Index>(i));
  return out;
}

namespace {

/// Poses [first, last] of `trajectory`, re-timed to start at 0.
core::Trajectory piece(const core::Trajectory& trajectory, std::size_t first, std::size_t last) {
  core::Trajectory out;
  out.reserve(last - first + 1);
  for (std::size_t i = first; i <= last; ++i)
    out.push_back(trajectory.stamp(i) - trajectory.stamp(first), trajectory.pose(i));
  return out;
}

/// The index in [first, d.size()) whose distance is nearest to `target`.
std::size_t nearestDistanceIndex(const std::vector<double>& d, std::size_t first, double target) {
  auto it = std::lower_bound(d.begin() + std::ptrdiff_t(first), d.end(), target);
  if (it == d.end()) return d.size() - 1;
  const auto i = std::size_t(it - d.begin());
  if (i > first && target - d[i - 1] < d[i] - target) return i - 1;
  return i;
}

Route namedRoute(std::size_t index, core::Trajectory T_world_sensor) {
  return {core::robotName(core::RobotId(static_cast<std::uint8_t>(index))),
          std::move(T_world_sensor)};
}

}  // namespace

std::vector<Route> splitByLength(const core::Trajectory& trajectory,
                                 std::span<const double> lengths) {
  const std::vector<double> d = trajectory.distances();
  std::vector<Route> routes;
  std::size_t first = 0;
  for (const double length : lengths) {
    if (!(length > 0.0)) throw core::Error("splitByLength: piece lengths must be positive");
    const std::size_t last = nearestDistanceIndex(d, first, d[first] + length);
    if (last + 2 > d.size())
      throw core::Error("splitByLength: the trajectory (" + std::to_string(trajectory.length()) +
                        " m) is too short for the requested pieces");
    routes.push_back(namedRoute(routes.size(), piece(trajectory, first, last)));
    first = last + 1;
  }
  if (first >= d.size()) throw core::Error("splitByLength: nothing left for the last piece");
  routes.push_back(namedRoute(routes.size(), piece(trajectory, first, d.size() - 1)));
  return routes;
}

KittiSplit kittiSplit(const std::string& sequence) {
  // 05 and 08: the paper's Table I (robot alpha, beta; gamma takes the rest).
  if (sequence == "05") return {sequence, {424.9, 599.9}};
  if (sequence == "08") return {sequence, {1252.8}};
  // 00 has no paper figure; see the header for why these lengths.
  if (sequence == "00") return {sequence, {1250.0, 1250.0}};
  throw core::Error("no KITTI split for sequence '" + sequence + "' (known: 00, 05, 08)");
}

KittiFiles kittiFiles(const std::string& data_dir, const std::string& sequence) {
  const std::filesystem::path root(data_dir);
  const std::string calib = (root / "lidar_scans" / "kitti_00" / "calib.txt").string();
  const std::filesystem::path trajectories = root / "trajectories";
  if (sequence == "00")
    return {(trajectories / "evo" / "KITTI_00_gt.txt").string(),
            (trajectories / "evo" / "KITTI_00_gt_times.txt").string(), calib};
  if (sequence == "05" || sequence == "08")
    return {(trajectories / "kitti_gt_poses" / (sequence + ".txt")).string(), std::nullopt, calib};
  throw core::Error("no KITTI ground truth for sequence '" + sequence + "' (known: 00, 05, 08)");
}

std::vector<Route> kittiRoutes(const std::string& data_dir, const std::string& sequence) {
  const KittiSplit split = kittiSplit(sequence);
  const KittiFiles files = kittiFiles(data_dir, sequence);
  const core::Trajectory T_world_velo =
      loadKittiLidarTrajectory(files.poses, files.calib, files.times);
  return splitByLength(levelRevisits(limitGrade(T_world_velo, kKittiMaxGrade)), split.lengths);
}

// ---------------------------------------------------------------- overlaps

std::string toString(OverlapKind kind) {
  switch (kind) {
    case OverlapKind::same_direction:
      return "same";
    case OverlapKind::opposite_direction:
      return "opposite";
    case OverlapKind::crossing:
      return "crossing";
  }
  return "crossing";
}

namespace {

/// One examined pose of a route: its index, horizontal position, heading and travel.
struct Sample {
  std::size_t index = 0;
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  Eigen::Vector2d heading =
      Eigen::Vector2d::UnitX();  ///< unit vector of the sensor's x axis in the xy plane
  double distance = 0.0;         ///< metres travelled to this pose
};

Eigen::Vector2d headingOf(const Eigen::Isometry3d& T) {
  const Eigen::Vector2d x = T.linear().col(0).head<2>();
  return x.norm() > 1e-9 ? Eigen::Vector2d(x.normalized()) : Eigen::Vector2d(1, 0);
}

/// The poses of `trajectory` every `step` metres of travel, plus the last one.
std::vector<Sample> sampleRoute(const core::Trajectory& trajectory, double step) {
  const std::vector<double> d = trajectory.distances();
  std::vector<Sample> samples;
  double next = 0.0;
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    if (d[i] < next && i + 1 != trajectory.size()) continue;
    const Eigen::Isometry3d& T = trajectory.pose(i);
    samples.push_back({i, T.translation().head<2>(), headingOf(T), d[i]});
    next = d[i] + step;
  }
  return samples;
}

OverlapKind classify(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const double c = a.dot(b);
  if (c > std::cos(core::deg2rad(45.0))) return OverlapKind::same_direction;
  if (c < std::cos(core::deg2rad(135.0))) return OverlapKind::opposite_direction;
  return OverlapKind::crossing;
}

/// For one sample of route a and one kind: the range of route b's pose
/// indices within the radius with that kind, if any.
struct Match {
  bool near = false;
  std::size_t first_b = 0;
  std::size_t last_b = 0;
};

std::array<Match, 3> matchSample(const Sample& a, std::span<const Sample> b, double radius) {
  std::array<Match, 3> matches{};
  for (const Sample& s : b) {
    if ((s.xy - a.xy).squaredNorm() > radius * radius) continue;
    Match& m = matches[std::size_t(classify(a.heading, s.heading))];
    if (!m.near) m = {true, s.index, s.index};
    m.first_b = std::min(m.first_b, s.index);
    m.last_b = std::max(m.last_b, s.index);
  }
  return matches;
}

/// Accumulates the stretches of one kind along route a.
class StretchBuilder {
 public:
  StretchBuilder(const Route& a, OverlapKind kind, const OverlapConfig& config)
      : a_(a), kind_(kind), config_(config) {}

  void add(const Sample& s, const Match& m) {
    if (!m.near) {
      if (open_ && s.distance - last_near_ > config_.max_gap) close();
      return;
    }
    if (!open_) begin(s, m);
    current_.last_a = s.index;
    current_.first_b = std::min(current_.first_b, m.first_b);
    current_.last_b = std::max(current_.last_b, m.last_b);
    last_near_ = s.distance;
  }

  std::vector<Overlap> finish() {
    if (open_) close();
    return std::move(done_);
  }

 private:
  void begin(const Sample& s, const Match& m) {
    open_ = true;
    current_ = Overlap{};
    current_.first_a = s.index;
    current_.first_b = m.first_b;
    current_.last_b = m.last_b;
    current_.kind = kind_;
    first_distance_ = s.distance;
  }

  void close() {
    open_ = false;
    current_.length = last_near_ - first_distance_;
    if (current_.length < config_.min_length) return;
    const auto d = a_.T_world_sensor.distances();
    const std::size_t mid =
        nearestDistanceIndex(d, current_.first_a, (first_distance_ + last_near_) / 2);
    current_.position = a_.T_world_sensor.pose(mid).translation();
    done_.push_back(current_);
  }

  const Route& a_;
  OverlapKind kind_;
  const OverlapConfig& config_;
  bool open_ = false;
  Overlap current_{};
  double first_distance_ = 0.0;
  double last_near_ = 0.0;
  std::vector<Overlap> done_;
};

/// True when `o` is only the seam of a consecutive split: a's route ends right
/// where b's starts, and the stretch is no longer than that seam can be.
bool isHandover(const Overlap& o, const Route& a, const Route& b, const OverlapConfig& config) {
  const core::Trajectory& ta = a.T_world_sensor;
  const core::Trajectory& tb = b.T_world_sensor;
  const double seam = (ta.poses().back().translation() - tb.pose(0).translation()).norm();
  return o.kind == OverlapKind::same_direction && seam < config.step + 2.0 &&
         o.last_a + 1 == ta.size() && o.first_b == 0 &&
         o.length <= config.radius + config.max_gap + 2 * config.step;
}

std::vector<Overlap> pairOverlaps(const Route& a, const Route& b, std::size_t ia, std::size_t ib,
                                  const OverlapConfig& config) {
  const std::vector<Sample> sa = sampleRoute(a.T_world_sensor, config.step);
  const std::vector<Sample> sb = sampleRoute(b.T_world_sensor, config.step);
  std::array<StretchBuilder, 3> builders{StretchBuilder(a, OverlapKind::same_direction, config),
                                         StretchBuilder(a, OverlapKind::opposite_direction, config),
                                         StretchBuilder(a, OverlapKind::crossing, config)};
  for (const Sample& s : sa) {
    const auto matches = matchSample(s, sb, config.radius);
    for (std::size_t k = 0; k < 3; ++k) builders[k].add(s, matches[k]);
  }
  std::vector<Overlap> out;
  for (auto& builder : builders) {
    for (Overlap& o : builder.finish()) {
      o.robot_a = ia;
      o.robot_b = ib;
      o.handover = isHandover(o, a, b, config);
      out.push_back(o);
    }
  }
  std::sort(out.begin(), out.end(),
            [](const Overlap& x, const Overlap& y) { return x.first_a < y.first_a; });
  return out;
}

}  // namespace

std::vector<Overlap> findOverlaps(std::span<const Route> routes, const OverlapConfig& config) {
  std::vector<Overlap> out;
  for (std::size_t i = 0; i < routes.size(); ++i) {
    for (std::size_t j = i + 1; j < routes.size(); ++j) {
      if (routes[i].T_world_sensor.empty() || routes[j].T_world_sensor.empty()) continue;
      const auto pair = pairOverlaps(routes[i], routes[j], i, j, config);
      out.insert(out.end(), pair.begin(), pair.end());
    }
  }
  return out;
}

bool overlapGraphConnected(std::size_t robots, std::span<const Overlap> overlaps) {
  std::vector<std::size_t> parent(robots);
  std::iota(parent.begin(), parent.end(), std::size_t{0});
  const auto root = [&](std::size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  std::size_t components = robots;
  for (const Overlap& o : overlaps) {
    if (o.handover || o.robot_a >= robots || o.robot_b >= robots) continue;
    const std::size_t ra = root(o.robot_a);
    const std::size_t rb = root(o.robot_b);
    if (ra != rb) parent[ra] = rb, --components;
  }
  return components <= 1;
}

}  // namespace dcl::sim
