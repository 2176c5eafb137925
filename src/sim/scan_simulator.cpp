#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <tbb/parallel_for.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/sim/scan_simulator.hpp>

#include "raycaster.hpp"

namespace dcl::sim {
namespace {

/// Columns cast together: the unit of parallel work and of packet forming.
/// Fixed, so that the packets (and hence every result) are the same whether
/// the blocks run on one thread or many.
constexpr int kColumnsPerBlock = 16;

/// How the returned intensity follows from the surface. Chosen so that a
/// KITTI-like street scene averages near KITTI's mean intensity of about 0.28:
///   I = gain * reflectivity * (floor + (1 - floor) * cos(incidence)) / (1 + r / falloff) + noise.
struct IntensityModel {
  float gain = 2.7f;             ///< overall scale of the sensor's reflectance calibration
  float shading_floor = 0.75f;   ///< share of the return that does not follow cos(incidence)
  float falloff_range = 150.0f;  ///< m, range at which the return has halved
  float noise_sigma = 0.02f;     ///< Gaussian noise on the reported intensity
  /// Real surfaces are not one colour: paint, dirt, wet and dry patches. A
  /// surface's reflectivity varies by a log-normal factor of this sigma from
  /// one cell of the world to the next (cells of albedo_cell metres), the same
  /// in every sweep.
  float albedo_sigma = 0.8f;
  float albedo_cell = 0.5f;
  /// The receiver compresses strong echoes: above `knee` the reported
  /// intensity (noise included) grows `compression` times as fast as the
  /// echo. KITTI's HDL-64E reports half its returns within 40 m above 0.3,
  /// crowded just above it (median 0.37, mean 0.40), and a mean of all its
  /// returns of 0.27-0.30; the spread over the bins below and above 0.3 is
  /// the same with and without it.
  float knee = 0.3f;
  float compression = 0.2f;
};
constexpr IntensityModel kIntensity{};

/// splitmix64's output function: a bijective 64-bit mixer.
std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

/// Counter-based random numbers for one beam of one sweep: a splitmix64
/// stream keyed by (seed, stamp, ring, column), so no two beams share state
/// and the result does not depend on which thread casts the beam.
class BeamRandom {
 public:
  BeamRandom(std::uint64_t seed, double stamp, int ring, int column) {
    std::uint64_t stamp_bits = 0;
    std::memcpy(&stamp_bits, &stamp, sizeof stamp);
    const auto beam = (static_cast<std::uint64_t>(ring) << 32) | static_cast<std::uint32_t>(column);
    state_ = mix64(seed + mix64(stamp_bits + mix64(beam)));
  }

  /// Uniform in [0, 1).
  float uniform() { return static_cast<float>(next() >> 40) * 0x1.0p-24f; }

  /// Two independent standard normals (Box-Muller, both outputs: one log and
  /// one sincos a beam, which mattered: they were a quarter of a sweep's time).
  std::pair<float, float> gaussianPair() {
    const float radius = std::sqrt(-2.0f * std::log(1.0f - uniform()));  // 1 - u in (0, 1]
    const float angle = 2.0f * static_cast<float>(M_PI) * uniform();
    return {radius * std::cos(angle), radius * std::sin(angle)};
  }

 private:
  std::uint64_t next() { return mix64(state_ += 0x9e3779b97f4a7c15ULL); }
  std::uint64_t state_;
};

/// The pose at `t`, clamped to the trajectory's ends.
Eigen::Isometry3d poseAt(const core::Trajectory& trajectory, double t) {
  const double clamped = std::clamp(t, trajectory.stamps().front(), trajectory.stamps().back());
  return *trajectory.at(clamped);
}

/// What a beam reports: a range and an intensity, or nothing (NaN range).
struct BeamReturn {
  float range = std::numeric_limits<float>::quiet_NaN();  ///< m, NaN when no return
  float intensity = 0.0f;                                 ///< in [0, 1]
  float azimuth_jitter = 0.0f;  ///< rad, how far from its column's azimuth the beam fired
};

/// Keys of the random streams a beam draws from besides its measurement's.
constexpr std::uint64_t kJitterStream = 0x6a09e667f3bcc909ULL;
constexpr std::uint64_t kMixStream = 0xbb67ae8584caa73bULL;

/// `v` turned by `angle` (rad) about the sensor's z axis.
Eigen::Vector3f turnedAboutZ(const Eigen::Vector3f& v, float angle) {
  const float c = std::cos(angle), s = std::sin(angle);
  return {c * v.x() - s * v.y(), s * v.x() + c * v.y(), v.z()};
}

/// The factor by which the reflectivity of the world's cell at `at` departs
/// from its surface's (IntensityModel::albedo_sigma), mean 1.
float albedoAt(const Eigen::Vector3f& at) {
  std::uint64_t key = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const auto cell = static_cast<std::int64_t>(std::floor(at[axis] / kIntensity.albedo_cell));
    key = mix64(key + static_cast<std::uint64_t>(cell));
  }
  const float u1 = static_cast<float>((key >> 40) + 1) * 0x1.0p-24f;  // (0, 1]
  const float u2 = static_cast<float>(mix64(key) >> 40) * 0x1.0p-24f;
  const float normal =
      std::sqrt(-2.0f * std::log(u1)) * std::cos(2.0f * static_cast<float>(M_PI) * u2);
  const float sigma = kIntensity.albedo_sigma;
  return std::exp(sigma * normal - 0.5f * sigma * sigma);
}

/// The noiseless intensity of a hit (IntensityModel) on a cell of albedo
/// factor `albedo`, before clamping.
float intensityOf(const RayHit& hit, float albedo) {
  const float shading =
      kIntensity.shading_floor + (1.0f - kIntensity.shading_floor) * hit.cos_incidence;
  const float falloff = 1.0f / (1.0f + hit.range / kIntensity.falloff_range);
  return kIntensity.gain * reflectivity(hit.surface) * albedo * shading * falloff;
}

/// What the receiver reports for an echo of intensity `echo`, clamped to [0, 1].
float reported(float echo) {
  const float out = echo <= kIntensity.knee
                        ? echo
                        : kIntensity.knee + kIntensity.compression * (echo - kIntensity.knee);
  return std::clamp(out, 0.0f, 1.0f);
}

/// The sweep's fixed geometry: beam directions in the sensor frame and firing times.
struct BeamTable {
  int rings = 0;
  int columns = 0;
  std::vector<Eigen::Vector3f> directions;  ///< unit, index column * rings + ring
  std::vector<std::uint8_t> blocked;        ///< 1 where the vehicle's body hides the beam
  std::vector<double> column_times;         ///< s since the sweep's start

  [[nodiscard]] const Eigen::Vector3f& direction(int ring, int column) const {
    return directions[static_cast<std::size_t>(column * rings + ring)];
  }
};

/// Where one unit's lasers really point and how far off their ranges read
/// (BeamCalibration): the rays are cast along the true elevations, while the
/// returns are reported along the tabled ones, as a driver converts them.
class UnitBeams {
 public:
  UnitBeams(const LidarModel& model, const BeamCalibration& unit) {
    if (unit.empty()) return;
    if (unit.elevation_error_deg.size() != model.elevations_deg.size() ||
        unit.range_offset.size() != model.elevations_deg.size()) {
      throw core::Error("a beam calibration of " + std::to_string(unit.elevation_error_deg.size()) +
                        " elevation errors and " + std::to_string(unit.range_offset.size()) +
                        " range offsets does not fit LiDAR model '" + model.name + "' of " +
                        std::to_string(model.elevations_deg.size()) + " lasers");
    }
    for (std::size_t r = 0; r < model.elevations_deg.size(); ++r) {
      const double tabled = core::deg2rad(model.elevations_deg[r]);
      const double real = core::deg2rad(model.elevations_deg[r] + unit.elevation_error_deg[r] +
                                        unit.elevation_bias_deg);
      horizontal_scale_.push_back(static_cast<float>(std::cos(real) / std::cos(tabled)));
      vertical_.push_back(static_cast<float>(std::sin(real)));
      range_offset_.push_back(static_cast<float>(unit.range_offset[r]));
    }
  }

  /// The true direction of ring `ring`'s beam whose tabled direction is `tabled`.
  [[nodiscard]] Eigen::Vector3f direction(const Eigen::Vector3f& tabled, int ring) const {
    if (vertical_.empty()) return tabled;
    const auto r = static_cast<std::size_t>(ring);
    return {tabled.x() * horizontal_scale_[r], tabled.y() * horizontal_scale_[r], vertical_[r]};
  }
  [[nodiscard]] float rangeOffset(int ring) const {
    return range_offset_.empty() ? 0.0f : range_offset_[static_cast<std::size_t>(ring)];
  }

 private:
  std::vector<float> horizontal_scale_;  ///< cos(true elevation) / cos(tabled elevation)
  std::vector<float> vertical_;          ///< sin(true elevation)
  std::vector<float> range_offset_;
};

/// True when the beam from the sensor's origin along `direction` meets `box`
/// within `max_range` (slab test).
bool meetsBox(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& direction, double max_range) {
  double near = 0.0, far = max_range;
  for (int axis = 0; axis < 3; ++axis) {
    const double d = direction[axis];
    if (std::abs(d) < 1e-12) {
      if (box.min()[axis] > 0.0 || box.max()[axis] < 0.0) return false;
      continue;
    }
    const double t1 = box.min()[axis] / d, t2 = box.max()[axis] / d;
    near = std::max(near, std::min(t1, t2));
    far = std::min(far, std::max(t1, t2));
  }
  return near <= far;
}

/// A moving actor where it is while one block of columns fires.
struct PlacedActor {
  const Actor* actor = nullptr;
  Eigen::Vector3f position = Eigen::Vector3f::Zero();  ///< origin, world frame
  float cos_yaw = 1.0f, sin_yaw = 0.0f;
};

/// Meets `ray` with the actors' boxes: shortens `hit` to the nearest box face
/// the beam enters before it, with the actor's surface. A beam starting
/// inside a box does not see that box.
void meetActors(std::span<const PlacedActor> actors, const Ray& ray, float max_range, RayHit& hit) {
  const Eigen::Vector2f dxy = ray.direction.head<2>();
  const float dxy2 = dxy.squaredNorm();
  for (const PlacedActor& placed : actors) {
    const Eigen::Vector3f w = placed.position - ray.origin;
    const float r = placed.actor->radius;
    // Cull on the ground plane: the beam's line must pass within the actor's radius.
    const float along = w.x() * dxy.x() + w.y() * dxy.y();
    if (dxy2 < 1e-8f) {
      if (w.head<2>().squaredNorm() > r * r) continue;
    } else {
      const float across = w.x() * dxy.y() - w.y() * dxy.x();
      if (across * across > r * r * dxy2 || along < -r * std::sqrt(dxy2)) continue;
    }
    // The beam in the actor's frame.
    const float c = placed.cos_yaw, s = placed.sin_yaw;
    const Eigen::Vector3f o(-(c * w.x() + s * w.y()), -(-s * w.x() + c * w.y()), -w.z());
    const Eigen::Vector3f d(c * ray.direction.x() + s * ray.direction.y(),
                            -s * ray.direction.x() + c * ray.direction.y(), ray.direction.z());
    for (const ActorBox& box : placed.actor->boxes) {
      float near = 0.0f, far = hit.hit() ? hit.range : max_range;
      int axis_in = -1;
      bool miss = false;
      for (int axis = 0; axis < 3 && !miss; ++axis) {
        const float lo = box.centre[axis] - box.half[axis] - o[axis];
        const float hi = box.centre[axis] + box.half[axis] - o[axis];
        if (std::abs(d[axis]) < 1e-9f) {
          miss = lo > 0.0f || hi < 0.0f;
          continue;
        }
        float t1 = lo / d[axis], t2 = hi / d[axis];
        if (t1 > t2) std::swap(t1, t2);
        if (t1 > near) {
          near = t1;
          axis_in = axis;
        }
        far = std::min(far, t2);
        miss = near > far;
      }
      if (miss || axis_in < 0) continue;  // missed, or starts inside the box
      hit.range = near;
      hit.cos_incidence = std::abs(d[axis_in]);
      hit.surface = placed.actor->surface;
    }
  }
}

/// Marks the beams the vehicle's body hides (none without a body).
std::vector<std::uint8_t> blockedBeams(const LidarModel& model,
                                       std::span<const Eigen::Vector3f> directions) {
  std::vector<std::uint8_t> blocked(directions.size(), 0);
  if (!model.ego_body) return blocked;
  for (std::size_t i = 0; i < directions.size(); ++i)
    blocked[i] = meetsBox(*model.ego_body, directions[i].cast<double>(), model.max_range) ? 1 : 0;
  return blocked;
}

/// The Velodyne spins clockwise seen from above. Column 0 looks backwards, so
/// the sweep's seam lies behind the vehicle and the front is seen mid-sweep,
/// as on KITTI, whose cameras trigger when the LiDAR faces forward.
BeamTable makeBeamTable(const LidarModel& model) {
  BeamTable table;
  table.rings = static_cast<int>(model.elevations_deg.size());
  table.columns = model.columns;
  table.directions.reserve(model.raysPerScan());
  for (int c = 0; c < model.columns; ++c) {
    const double phase = model.columnPhase(c);
    const double azimuth = M_PI - 2.0 * M_PI * phase;
    table.column_times.push_back(model.sweepDuration() * phase);
    for (double elevation_deg : model.elevations_deg) {
      const double elevation = core::deg2rad(elevation_deg);
      table.directions.emplace_back(Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                                                    std::cos(elevation) * std::sin(azimuth),
                                                    std::sin(elevation))
                                        .cast<float>());
    }
  }
  table.blocked = blockedBeams(model, table.directions);
  return table;
}

/// Refuses models the sweep cannot be cast with.
void checkModel(const LidarModel& model) {
  if (model.elevations_deg.empty() || model.columns <= 0 || !(model.rate_hz > 0.0))
    throw core::Error("LiDAR model '" + model.name +
                      "' needs at least one beam, one column and a positive rate");
  if (!(model.min_range >= 0.0 && model.max_range > model.min_range))
    throw core::Error("LiDAR model '" + model.name + "' needs 0 <= min_range < max_range");
  if (!(model.dropout >= 0.0 && model.dropout < 1.0) || !(model.range_noise_sigma >= 0.0) ||
      !(model.range_noise_per_m >= 0.0) || !(model.range_noise_max >= 0.0))
    throw core::Error("LiDAR model '" + model.name +
                      "' needs dropout in [0, 1) and a non-negative noise sigma");
  if (!(model.dark_dropout >= 0.0 && model.dark_dropout <= 1.0) || !(model.dark_intensity > 0.0) ||
      !(model.mixed_pixel_rate >= 0.0 && model.mixed_pixel_rate <= 1.0) ||
      !(model.foliage_depth >= 0.0) || !(model.azimuth_jitter_deg >= 0.0))
    throw core::Error("LiDAR model '" + model.name +
                      "' needs dark dropout and mixed-pixel rate in [0, 1], a positive dark "
                      "intensity, and non-negative foliage depth and azimuth jitter");
  if (!(model.half_step_period == 0.0 || model.half_step_period >= 2.0))
    throw core::Error("LiDAR model '" + model.name +
                      "' needs a half-step period of 0 (none) or at least 2 firings");
}

}  // namespace

struct ScanSimulator::Impl {
  RayCaster caster;
  LidarModel model;
  ScanOptions options;
  BeamTable beams;
  Traffic traffic;

  Impl(const World& world, LidarModel m, ScanOptions o, Traffic t)
      : caster(world),
        model(std::move(m)),
        options(o),
        beams(makeBeamTable(model)),
        traffic(std::move(t)) {}

  /// The actors alive during the sweep from `stamp` that may come within
  /// the sensor's range.
  [[nodiscard]] std::vector<const Actor*> actorsNear(const Eigen::Vector3f& sensor,
                                                     double stamp) const;
  /// Those of `near` that are there at time `t`, placed, within range of `sensor`.
  [[nodiscard]] std::vector<PlacedActor> placeActors(std::span<const Actor* const> near,
                                                     const Eigen::Vector3f& sensor, double t) const;

  /// T_world_sensor of every column: at its firing time, or all at `stamp` without distortion.
  [[nodiscard]] std::vector<Eigen::Isometry3f> columnPoses(const core::Trajectory& trajectory,
                                                           double stamp) const;
  /// Casts the columns of block `block` and writes their beams' returns.
  void castBlock(int block, std::span<const Eigen::Isometry3f> poses, double stamp,
                 std::uint64_t seed, const UnitBeams& unit, std::span<const Actor* const> actors,
                 std::span<BeamReturn> returns) const;
  /// What the sensor reports for a hit: the laser's range offset, noise,
  /// dropout and range limits applied.
  [[nodiscard]] BeamReturn measure(const RayHit& hit, float range_offset, float albedo,
                                   BeamRandom& random) const;
  /// Mixed pixels: where two neighbouring beams of a ring meet surfaces far
  /// apart, one of them now and then reports a range between the two.
  void mixDepthEdges(std::span<BeamReturn> returns, double stamp, std::uint64_t seed) const;
  /// The returns as a cloud, column by column, rings in order within a column.
  [[nodiscard]] core::PointCloud collect(std::span<const BeamReturn> returns) const;
};

std::vector<Eigen::Isometry3f> ScanSimulator::Impl::columnPoses(const core::Trajectory& trajectory,
                                                                double stamp) const {
  const Eigen::Isometry3f T_world_start = poseAt(trajectory, stamp).cast<float>();
  std::vector<Eigen::Isometry3f> poses(beams.column_times.size(), T_world_start);
  if (!options.motion_distortion) return poses;
  for (std::size_t c = 0; c < poses.size(); ++c)
    poses[c] = poseAt(trajectory, stamp + beams.column_times[c]).cast<float>();
  return poses;
}

std::vector<const Actor*> ScanSimulator::Impl::actorsNear(const Eigen::Vector3f& sensor,
                                                          double stamp) const {
  std::vector<const Actor*> near;
  const double sweep = model.sweepDuration();
  for (const Actor& actor : traffic.actors) {
    if (actor.poses.empty() || actor.end() < stamp || actor.start > stamp + sweep) continue;
    // Where it is during the sweep (its first pose there), and how far it can go in one.
    const auto pose = actor.at(std::clamp(stamp, actor.start, actor.end()));
    const ActorPose& p = pose ? *pose : actor.poses.front();
    const double reach = model.max_range + actor.radius + 30.0 * sweep + 1.0;
    if ((Eigen::Vector2f(p.x, p.y) - sensor.head<2>()).squaredNorm() <= reach * reach)
      near.push_back(&actor);
  }
  return near;
}

std::vector<PlacedActor> ScanSimulator::Impl::placeActors(std::span<const Actor* const> near,
                                                          const Eigen::Vector3f& sensor,
                                                          double t) const {
  std::vector<PlacedActor> placed;
  for (const Actor* actor : near) {
    const auto pose = actor->at(t);
    if (!pose) continue;
    const Eigen::Vector3f position(pose->x, pose->y, pose->z);
    const float reach = static_cast<float>(model.max_range) + actor->radius;
    if ((position - sensor).head<2>().squaredNorm() > reach * reach) continue;
    placed.push_back({actor, position, std::cos(pose->yaw), std::sin(pose->yaw)});
  }
  return placed;
}

BeamReturn ScanSimulator::Impl::measure(const RayHit& hit, float range_offset, float albedo,
                                        BeamRandom& random) const {
  if (!hit.hit()) return {};
  if (!options.noise) {
    const float range = hit.range + range_offset;
    if (range < model.min_range) return {};
    return {range, reported(intensityOf(hit, albedo))};
  }
  if (random.uniform() < model.dropout) return {};
  const auto [range_noise, intensity_noise] = random.gaussianPair();
  const float clean_intensity = intensityOf(hit, albedo);
  if (model.dark_dropout > 0.0 && clean_intensity < model.dark_intensity &&
      random.uniform() < model.dark_dropout * (1.0 - clean_intensity / model.dark_intensity))
    return {};
  float depth = hit.range;
  if (hit.surface == Surface::vegetation && model.foliage_depth > 0.0) {
    // Exponential, cut at three means: a crown's returns come from its outer layer.
    const float into = -std::log(1.0f - random.uniform());
    depth += static_cast<float>(model.foliage_depth) * std::min(into, 3.0f);
  }
  const auto sigma = static_cast<float>(
      std::min(model.range_noise_sigma + model.range_noise_per_m * depth, model.range_noise_max));
  const float range = depth + range_offset + sigma * range_noise;
  if (range < model.min_range || range > model.max_range) return {};
  return {range, reported(clean_intensity + kIntensity.noise_sigma * intensity_noise)};
}

void ScanSimulator::Impl::castBlock(int block, std::span<const Eigen::Isometry3f> poses,
                                    double stamp, std::uint64_t seed, const UnitBeams& unit,
                                    std::span<const Actor* const> actors,
                                    std::span<BeamReturn> returns) const {
  const int first = block * kColumnsPerBlock;
  const int last = std::min(first + kColumnsPerBlock, beams.columns);
  const auto offset = static_cast<std::size_t>(first * beams.rings);
  const auto count = static_cast<std::size_t>((last - first) * beams.rings);
  std::vector<Ray> rays(count);
  std::vector<float> jitter(count, 0.0f);
  const bool jittered = options.noise && model.azimuth_jitter_deg > 0.0;
  const auto jitter_sigma = static_cast<float>(core::deg2rad(model.azimuth_jitter_deg));
  for (int c = first; c < last; ++c) {
    const auto& T_world_sensor = poses[static_cast<std::size_t>(c)];
    for (int r = 0; r < beams.rings; ++r) {
      const auto i = static_cast<std::size_t>(c * beams.rings + r) - offset;
      Eigen::Vector3f tabled = beams.direction(r, c);
      if (jittered) {
        BeamRandom random(seed ^ kJitterStream, stamp, r, c);
        jitter[i] = jitter_sigma * random.gaussianPair().first;
        tabled = turnedAboutZ(tabled, jitter[i]);
      }
      rays[i].origin = T_world_sensor.translation();
      rays[i].direction = T_world_sensor.linear() * unit.direction(tabled, r);
    }
  }
  std::vector<RayHit> hits(count);
  caster.cast(rays, static_cast<float>(model.max_range), hits);
  if (!actors.empty()) {
    // The actors where they are at the block's middle column (a block fires
    // within a millisecond: a car moves a centimetre).
    const int middle = (first + last) / 2;
    const auto placed = placeActors(actors, poses[static_cast<std::size_t>(middle)].translation(),
                                    stamp + beams.column_times[static_cast<std::size_t>(middle)]);
    if (!placed.empty()) {
      for (std::size_t i = 0; i < count; ++i)
        meetActors(placed, rays[i], static_cast<float>(model.max_range), hits[i]);
    }
  }
  std::size_t i = 0;
  for (int c = first; c < last; ++c) {
    for (int r = 0; r < beams.rings; ++r, ++i) {
      if (beams.blocked[offset + i]) continue;  // stays "no return"
      BeamRandom random(seed, stamp, r, c);
      const float albedo =
          hits[i].hit() ? albedoAt(rays[i].origin + rays[i].direction * hits[i].range) : 1.0f;
      returns[offset + i] = measure(hits[i], unit.rangeOffset(r), albedo, random);
      returns[offset + i].azimuth_jitter = jitter[i];
    }
  }
}

void ScanSimulator::Impl::mixDepthEdges(std::span<BeamReturn> returns, double stamp,
                                        std::uint64_t seed) const {
  if (!options.noise || model.mixed_pixel_rate <= 0.0) return;
  // Decided on the ranges as cast, so that one mixed beam does not make another.
  std::vector<float> cast(returns.size());
  std::transform(returns.begin(), returns.end(), cast.begin(),
                 [](const BeamReturn& b) { return b.range; });
  const auto rings = static_cast<std::size_t>(beams.rings);
  for (std::size_t c = 0; c + 1 < static_cast<std::size_t>(beams.columns); ++c) {
    for (std::size_t r = 0; r < rings; ++r) {
      const std::size_t a = c * rings + r, b = a + rings;
      if (std::isnan(cast[a]) || std::isnan(cast[b])) continue;
      const float near = std::min(cast[a], cast[b]), far = std::max(cast[a], cast[b]);
      if (far - near < std::max(1.0f, 0.2f * near)) continue;
      BeamRandom random(seed ^ kMixStream, stamp, static_cast<int>(r), static_cast<int>(c));
      if (random.uniform() >= model.mixed_pixel_rate) continue;
      BeamReturn& merged = random.uniform() < 0.5f ? returns[a] : returns[b];
      merged.range = near + (0.15f + 0.7f * random.uniform()) * (far - near);
    }
  }
}

core::PointCloud ScanSimulator::Impl::collect(std::span<const BeamReturn> returns) const {
  const auto n = static_cast<std::size_t>(std::count_if(
      returns.begin(), returns.end(), [](const BeamReturn& b) { return !std::isnan(b.range); }));
  core::PointCloud cloud;
  cloud.reserve(n);
  std::size_t beam = 0;
  for (int column = 0; column < beams.columns; ++column) {
    const auto time = static_cast<float>(beams.column_times[static_cast<std::size_t>(column)]);
    for (int ring = 0; ring < beams.rings; ++ring, ++beam) {
      const BeamReturn& b = returns[beam];
      if (std::isnan(b.range)) continue;
      cloud.points.push_back((b.azimuth_jitter == 0.0f
                                  ? beams.directions[beam]
                                  : turnedAboutZ(beams.directions[beam], b.azimuth_jitter)) *
                             b.range);
      cloud.intensity.push_back(b.intensity);
      cloud.time.push_back(time);
      cloud.ring.push_back(static_cast<std::uint16_t>(ring));
    }
  }
  return cloud;
}

ScanSimulator::ScanSimulator(const World& world, LidarModel model, ScanOptions options,
                             Traffic traffic) {
  checkModel(model);
  impl_ = std::make_unique<Impl>(world, std::move(model), options, std::move(traffic));
}

ScanSimulator::~ScanSimulator() = default;
ScanSimulator::ScanSimulator(ScanSimulator&&) noexcept = default;
ScanSimulator& ScanSimulator::operator=(ScanSimulator&&) noexcept = default;

const LidarModel& ScanSimulator::model() const {
  return impl_->model;
}

const Traffic& ScanSimulator::traffic() const {
  return impl_->traffic;
}

core::PointCloud ScanSimulator::scan(const core::Trajectory& T_world_sensor, double stamp,
                                     std::uint64_t seed, const BeamCalibration& unit) const {
  if (T_world_sensor.empty()) throw core::Error("cannot simulate a scan on an empty trajectory");
  const UnitBeams unit_beams(impl_->model, unit);
  const auto poses = impl_->columnPoses(T_world_sensor, stamp);
  std::vector<BeamReturn> returns(impl_->model.raysPerScan());
  const auto actors = impl_->actorsNear(poses.front().translation(), stamp);
  const int blocks = (impl_->beams.columns + kColumnsPerBlock - 1) / kColumnsPerBlock;
  const auto cast_block = [&](int block) {
    impl_->castBlock(block, poses, stamp, seed, unit_beams, actors, returns);
  };
  if (impl_->options.parallel) {
    tbb::parallel_for(0, blocks, cast_block);
  } else {
    for (int block = 0; block < blocks; ++block) cast_block(block);
  }
  impl_->mixDepthEdges(returns, stamp, seed);
  return impl_->collect(returns);
}

}  // namespace dcl::sim
