#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/sim/scan_simulator.hpp>

// The ray caster is private to dcl::sim; its tests reach it from here.
#include "../../src/sim/raycaster.hpp"

namespace dcl::sim {
namespace {

constexpr ScanOptions kExact{.motion_distortion = false, .noise = false, .parallel = false};
constexpr ScanOptions kExactMoving{.motion_distortion = true, .noise = false, .parallel = false};
constexpr ScanOptions kNoisy{.motion_distortion = false, .noise = true, .parallel = false};

Eigen::Isometry3d poseAt(double x, double y, double z, double yaw = 0.0) {
  Eigen::Isometry3d T = core::makePose2d(x, y, yaw);
  T.translation().z() = z;
  return T;
}

/// Standing still at `T_world_sensor` for ten seconds.
core::Trajectory still(const Eigen::Isometry3d& T_world_sensor) {
  core::Trajectory trajectory;
  trajectory.push_back(0.0, T_world_sensor);
  trajectory.push_back(10.0, T_world_sensor);
  return trajectory;
}

/// Driving along +x at `speed` from the origin, at height `z`, for five seconds.
core::Trajectory straight(double speed, double z) {
  core::Trajectory trajectory;
  trajectory.push_back(0.0, poseAt(0.0, 0.0, z));
  trajectory.push_back(5.0, poseAt(5.0 * speed, 0.0, z));
  return trajectory;
}

/// A 1 m thick wall whose face is the plane x = `distance`, 200 m wide, 100 m high.
World wallWorld(double distance, Surface surface = Surface::wall) {
  World world;
  world.addBox(poseAt(distance + 0.5, 0.0, -50.0), {1.0, 200.0, 100.0}, surface);
  return world;
}

/// A closed box room around the origin: every beam hits something.
World roomWorld() {
  World world;
  world.addBox(poseAt(0.0, 0.0, -3.0), {30.0, 24.0, 9.0}, Surface::wall);
  return world;
}

/// Flat road at z = 0, `half` metres each way from the origin.
void addRoad(World& world, float half) {
  const auto a = world.addVertex({-half, -half, 0.f});
  const auto b = world.addVertex({half, -half, 0.f});
  const auto c = world.addVertex({half, half, 0.f});
  const auto d = world.addVertex({-half, half, 0.f});
  world.addQuad(a, b, c, d, Surface::road);
}

/// A few objects on a ground quad: enough shapes to test exactness on.
World smallStreetWorld() {
  World world;
  addRoad(world, 60.f);
  world.addBox(poseAt(10.0, 8.0, 0.0, 0.3), {8.0, 5.0, 6.0}, Surface::building);
  world.addBox(poseAt(-6.0, -9.0, 0.0, -0.2), {10.0, 4.0, 9.0}, Surface::building);
  world.addBox(poseAt(4.0, -4.0, 0.25, 1.0), {4.3, 1.8, 1.3},
               Surface::vehicle);  // clear of the road
  world.addCylinder({-3.0, 5.0, 0.0}, 0.25, 3.0, 8, Surface::trunk);
  world.addEllipsoid({-3.0, 5.0, 4.0}, {1.5, 1.5, 1.2}, 4, Surface::vegetation);
  return world;
}

/// Bitwise equality of every channel.
template <typename T>
bool sameBits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

bool bitIdentical(const core::PointCloud& a, const core::PointCloud& b) {
  return sameBits(a.points, b.points) && sameBits(a.intensity, b.intensity) &&
         sameBits(a.time, b.time) && sameBits(a.ring, b.ring);
}

/// The closest point to `p` on triangle abc (by Voronoi regions of the triangle).
Eigen::Vector3d closestOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                  const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a;
  const double d1 = ab.dot(p - a), d2 = ac.dot(p - a);
  if (d1 <= 0 && d2 <= 0) return a;
  const double d3 = ab.dot(p - b), d4 = ac.dot(p - b);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const double d5 = ab.dot(p - c), d6 = ac.dot(p - c);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double sum = va + vb + vc;
  return a + ab * (vb / sum) + ac * (vc / sum);
}

/// Brute-force distance from `p` to the nearest triangle of `world`.
double distanceToMesh(const World& world, const Eigen::Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : world.triangles) {
    const auto v = [&](int i) { return world.vertices[t[i]].cast<double>(); };
    best = std::min(best, (p - closestOnTriangle(p, v(0), v(1), v(2))).norm());
  }
  return best;
}

// ---------------------------------------------------------------- ray caster

TEST(RayCaster, HitsABoxFaceAtItsDistanceWithItsSurfaceAndIncidence) {
  const RayCaster caster(wallWorld(10.0, Surface::building));
  EXPECT_EQ(caster.triangleCount(), 12u);
  const RayHit ahead = caster.cast({Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX()}, 100.f);
  ASSERT_TRUE(ahead.hit());
  EXPECT_NEAR(ahead.range, 10.0, 1e-5);
  EXPECT_EQ(ahead.surface, Surface::building);
  EXPECT_NEAR(ahead.cos_incidence, 1.0, 1e-6);
  const Eigen::Vector3f diagonal = Eigen::Vector3f(1.f, 1.f, 0.f).normalized();
  const RayHit oblique = caster.cast({Eigen::Vector3f::Zero(), diagonal}, 100.f);
  ASSERT_TRUE(oblique.hit());
  EXPECT_NEAR(oblique.range, 10.0 * std::sqrt(2.0), 1e-4);
  EXPECT_NEAR(oblique.cos_incidence, std::sqrt(0.5), 1e-5);
  EXPECT_FALSE(caster.cast({Eigen::Vector3f::Zero(), -Eigen::Vector3f::UnitX()}, 100.f).hit());
  EXPECT_FALSE(caster.cast({Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX()}, 9.9f).hit());
}

TEST(RayCaster, PacketsGiveWhatSingleRaysGive) {
  World world = smallStreetWorld();
  const RayCaster caster(world);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<Ray> rays(1003);  // not a multiple of the packet width
  for (auto& ray : rays) {
    ray.origin = {5.f * u(rng), 5.f * u(rng), 1.f + u(rng) * 0.5f};
    ray.direction = Eigen::Vector3f(u(rng), u(rng), u(rng) - 0.3f).normalized();
  }
  std::vector<RayHit> hits(rays.size());
  caster.cast(rays, 80.f, hits);
  int hit_count = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const RayHit single = caster.cast(rays[i], 80.f);
    ASSERT_EQ(single.hit(), hits[i].hit()) << i;
    if (!single.hit()) continue;
    ++hit_count;
    EXPECT_NEAR(single.range, hits[i].range, 1e-5) << i;
    EXPECT_EQ(single.surface, hits[i].surface) << i;
  }
  EXPECT_GT(hit_count, 500);
}

TEST(RayCaster, RefusesAnInconsistentWorld) {
  World missing_surface = wallWorld(5.0);
  missing_surface.surfaces.pop_back();
  EXPECT_THROW(RayCaster{missing_surface}, core::Error);
  World bad_index = wallWorld(5.0);
  bad_index.triangles.push_back({0, 1, 999});
  bad_index.surfaces.push_back(Surface::wall);
  EXPECT_THROW(RayCaster{bad_index}, core::Error);
}

TEST(RayCaster, AnEmptyWorldHitsNothing) {
  const RayCaster caster(World{});
  EXPECT_FALSE(caster.cast({Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitZ()}, 100.f).hit());
}

// ---------------------------------------------------------------- ranges

TEST(ScanSimulator, ForwardBeamMeetsTheWallAtItsExactRange) {
  const ScanSimulator sim(wallWorld(10.0), LidarModel::vlp16(), kExact);
  const auto cloud = sim.scan(still(poseAt(0, 0, 0)), 0.0, 1);
  ASSERT_GT(cloud.size(), 1000u);
  bool found = false;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    EXPECT_NEAR(cloud.points[i].x(), 10.0, 1e-4) << i;   // every return lies on the wall
    if (cloud.ring[i] == 7 && cloud.time[i] == 0.05f) {  // -1 deg, facing forward
      found = true;
      EXPECT_NEAR(cloud.points[i].norm(), 10.0 / std::cos(core::deg2rad(1.0)), 1e-4);
      EXPECT_NEAR(cloud.points[i].y(), 0.0, 1e-4);
    }
  }
  EXPECT_TRUE(found);
}

TEST(ScanSimulator, RangeNoiseHasTheModelsSigma) {
  // The noise grows with range: measured against the model's sigma at each
  // return's range, the errors are standard normal.
  const LidarModel model = LidarModel::vlp16();
  const ScanSimulator sim(wallWorld(10.0), model, kNoisy);
  const auto cloud = sim.scan(still(poseAt(0, 0, 0)), 0.0, 1);
  ASSERT_GT(cloud.size(), 5000u);
  double sum = 0.0, sum_sq = 0.0;
  for (const auto& p : cloud.points) {
    const double r = p.norm();
    const double truth = 10.0 / (p.x() / r);  // the wall's range along the beam
    const double sigma =
        std::min(model.range_noise_sigma + model.range_noise_per_m * truth, model.range_noise_max);
    const double error = (r - truth) / sigma;
    sum += error;
    sum_sq += error * error;
  }
  const double n = static_cast<double>(cloud.size());
  const double mean = sum / n;
  EXPECT_NEAR(mean, 0.0, 0.1);
  EXPECT_NEAR(std::sqrt(sum_sq / n - mean * mean), 1.0, 0.1);
}

TEST(ScanSimulator, NothingPastMaxRange) {
  World world;  // a ground 2 km across, larger than any max range
  const auto a = world.addVertex({-1000.f, -1000.f, 0.f});
  const auto b = world.addVertex({1000.f, -1000.f, 0.f});
  const auto c = world.addVertex({1000.f, 1000.f, 0.f});
  const auto d = world.addVertex({-1000.f, 1000.f, 0.f});
  world.addQuad(a, b, c, d, Surface::ground);
  LidarModel model = LidarModel::vlp16();
  const auto route = still(poseAt(0, 0, 1.73));
  const auto full = ScanSimulator(world, model, kNoisy).scan(route, 0.0, 1);
  model.max_range = 30.0;
  const auto cut = ScanSimulator(world, model, kNoisy).scan(route, 0.0, 1);
  float full_max = 0.f, cut_max = 0.f;
  for (const auto& p : full.points) full_max = std::max(full_max, p.norm());
  for (const auto& p : cut.points) cut_max = std::max(cut_max, p.norm());
  EXPECT_LE(full_max, 100.0f);
  EXPECT_GT(full_max, 90.0f);  // the -1 deg ring reaches 99 m
  EXPECT_LE(cut_max, 30.0f);
  EXPECT_LT(cut.size(), full.size() * 9 / 10);
}

TEST(ScanSimulator, NothingBeforeMinRange) {
  World cell;  // a 0.4 m box around the sensor: every surface closer than min_range
  cell.addBox(poseAt(0, 0, -0.2), {0.4, 0.4, 0.4}, Surface::wall);
  LidarModel model = LidarModel::vlp16();
  EXPECT_TRUE(ScanSimulator(cell, model, kNoisy).scan(still(poseAt(0, 0, 0)), 0.0, 1).empty());
  model.min_range = 0.05;
  const auto seen = ScanSimulator(cell, model, kExact).scan(still(poseAt(0, 0, 0)), 0.0, 1);
  EXPECT_EQ(seen.size(), model.raysPerScan());
}

TEST(ScanSimulator, TheCarsBodyHidesTheLowestBeamsAheadAndBehindOnly) {
  World world;  // flat ground under an HDL-64 at its KITTI height
  const auto a = world.addVertex({-50.f, -50.f, 0.f});
  const auto b = world.addVertex({50.f, -50.f, 0.f});
  const auto c = world.addVertex({50.f, 50.f, 0.f});
  const auto d = world.addVertex({-50.f, 50.f, 0.f});
  world.addQuad(a, b, c, d, Surface::road);
  LidarModel model = LidarModel::hdl64();
  const auto route = still(poseAt(0, 0, model.mount_height));
  const auto count_ring0 = [&](const LidarModel& m, double azimuth_from, double azimuth_to) {
    const auto cloud = ScanSimulator(world, m, kExact).scan(route, 0.0, 1);
    int n = 0;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      const double azimuth = std::abs(std::atan2(cloud.points[i].y(), cloud.points[i].x()));
      n += cloud.ring[i] == 0 && azimuth >= azimuth_from && azimuth < azimuth_to;
    }
    return n;
  };
  const int all = count_ring0(model, 0.0, 4.0);
  EXPECT_EQ(count_ring0(model, 0.0, 0.3), 0);         // ahead: the bonnet
  EXPECT_EQ(count_ring0(model, M_PI - 0.3, 4.0), 0);  // behind: the boot
  EXPECT_GT(count_ring0(model, 1.3, 1.8), 250);       // the sides stay in view
  EXPECT_GT(all, model.columns * 55 / 100);           // KITTI keeps about 56 %
  EXPECT_LT(all, model.columns * 75 / 100);
  model.ego_body.reset();
  EXPECT_EQ(count_ring0(model, 0.0, 4.0), model.columns);
}

// ---------------------------------------------------------------- rings, times, dropout

TEST(ScanSimulator, RingsTimesAndOrderFollowTheBeamsAndTheSpin) {
  const LidarModel model = LidarModel::vlp16();
  const ScanSimulator sim(roomWorld(), model, kExact);
  const auto cloud = sim.scan(still(poseAt(0, 0, 0)), 0.0, 1);
  ASSERT_EQ(cloud.size(), model.raysPerScan());  // closed room, no noise: every beam returns
  ASSERT_TRUE(cloud.consistent());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p = cloud.points[i].cast<double>();
    const double elevation = core::rad2deg(std::asin(p.z() / p.norm()));
    EXPECT_NEAR(elevation, model.elevations_deg[cloud.ring[i]], 1e-3) << i;
    ASSERT_GE(cloud.time[i], 0.0f);
    ASSERT_LT(cloud.time[i], 0.1f);
    // Clockwise from behind: azimuth = pi - 2 pi t / T.
    const double expected = M_PI - 2.0 * M_PI * cloud.time[i] / 0.1;
    const double diff = std::remainder(std::atan2(p.y(), p.x()) - expected, 2.0 * M_PI);
    EXPECT_NEAR(diff, 0.0, 1e-4) << i;
    if (i == 0) continue;
    ASSERT_GE(cloud.time[i], cloud.time[i - 1]) << i;  // column-major
    if (cloud.time[i] == cloud.time[i - 1]) {
      ASSERT_EQ(cloud.ring[i], cloud.ring[i - 1] + 1) << i;  // ring order within a column
    }
  }
  EXPECT_EQ(cloud.time.front(), 0.0f);
  EXPECT_NEAR(cloud.time.back(), 0.1 * 1799.0 / 1800.0, 1e-7);
}

TEST(ScanSimulator, DropoutShareMatchesTheModel) {
  LidarModel model = LidarModel::vlp16();
  const auto route = still(poseAt(0, 0, 0));
  for (double dropout : {model.dropout, 0.2}) {
    model.dropout = dropout;
    const auto cloud = ScanSimulator(roomWorld(), model, kNoisy).scan(route, 0.0, 5);
    const double share = 1.0 - double(cloud.size()) / double(model.raysPerScan());
    EXPECT_NEAR(share, dropout, 0.006) << dropout;  // about 4 sigma of a binomial share
  }
}

TEST(ScanSimulator, IntensityFollowsReflectivityAndIncidence) {
  const auto route = still(poseAt(0, 0, 0));
  const auto mean_intensity = [&](Surface surface) {
    const auto cloud =
        ScanSimulator(wallWorld(10.0, surface), LidarModel::vlp16(), kNoisy).scan(route, 0.0, 1);
    double sum = 0.0;
    for (float v : cloud.intensity) {
      EXPECT_GE(v, 0.0f);
      EXPECT_LE(v, 1.0f);
      sum += v;
    }
    return sum / double(cloud.size());
  };
  EXPECT_GT(mean_intensity(Surface::vegetation), 2.0 * mean_intensity(Surface::road));
  // The same patch of wall returns more seen head-on than seen at a slant
  // from as far. Each half-metre cell of a surface has its own albedo (a
  // factor of about 2 either way), so both scans look at the same cells: one
  // column of cells (world y 0-0.5 m) on a face in the middle of a cell in x,
  // from 10.25 m straight ahead and from 10.25 m at 1 rad to the normal, ring
  // by ring where the ring's points fall in one cell in height. The receiver
  // compresses bright echoes, but never so much that a brighter echo reports
  // as little.
  constexpr double kFace = 10.25, kSlant = 1.0;
  const World wall = wallWorld(kFace, Surface::road);
  const Eigen::Vector3d patch(kFace, 0.25, 0.0);
  const Eigen::Vector3d head_on_at = patch - Eigen::Vector3d(kFace, 0.0, 0.0);
  const Eigen::Vector3d slant_at =
      patch - kFace * Eigen::Vector3d(std::cos(kSlant), std::sin(kSlant), 0.0);
  // Per ring: the sum and count of the patch's intensities, and the height cell(s).
  struct Ring {
    double sum = 0.0;
    std::size_t points = 0;
    long cell_min = std::numeric_limits<long>::max(), cell_max = std::numeric_limits<long>::min();
  };
  const auto patchRings = [&](const Eigen::Vector3d& at) {
    const auto cloud = ScanSimulator(wall, LidarModel::vlp16(), kExact)
                           .scan(still(poseAt(at.x(), at.y(), at.z())), 0, 1);
    std::vector<Ring> rings(16);
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      const Eigen::Vector3d p = at + cloud.points[i].cast<double>();
      if (std::abs(p.x() - kFace) > 0.01 || p.y() < 0.05 || p.y() > 0.45) continue;
      Ring& r = rings.at(cloud.ring[i]);
      r.sum += cloud.intensity[i];
      ++r.points;
      const long cell = static_cast<long>(std::floor(p.z() / 0.5));
      r.cell_min = std::min(r.cell_min, cell);
      r.cell_max = std::max(r.cell_max, cell);
    }
    return rings;
  };
  const std::vector<Ring> head_on = patchRings(head_on_at), slant = patchRings(slant_at);
  std::size_t compared = 0;
  for (std::size_t r = 0; r < 16; ++r) {
    const Ring& h = head_on[r];
    const Ring& s = slant[r];
    if (h.points == 0 || s.points == 0 || h.cell_min != h.cell_max || s.cell_min != s.cell_max ||
        h.cell_min != s.cell_min)
      continue;
    ++compared;
    // 1 / (0.75 + 0.25 cos 1) = 1.13 below the knee, 1.03 above it.
    EXPECT_GT(h.sum / double(h.points), 1.02 * s.sum / double(s.points)) << "ring " << r;
  }
  EXPECT_GE(compared, 8u);
}

// ---------------------------------------------------------------- determinism

TEST(ScanSimulator, SameSeedSameBitsWhateverTheThreads) {
  const World world = smallStreetWorld();
  const auto route = straight(10.0, 1.73);
  const LidarModel model = LidarModel::hdl64();
  const ScanSimulator parallel(world, model, {.parallel = true});
  const ScanSimulator serial(world, model, {.parallel = false});
  const auto a = parallel.scan(route, 0.3, 7);
  ASSERT_GT(a.size(), 50000u);
  EXPECT_TRUE(bitIdentical(a, parallel.scan(route, 0.3, 7)));
  EXPECT_TRUE(bitIdentical(a, serial.scan(route, 0.3, 7)));
  EXPECT_FALSE(bitIdentical(a, parallel.scan(route, 0.3, 8)));
  EXPECT_FALSE(bitIdentical(a, parallel.scan(route, 0.4, 7)));
}

// ---------------------------------------------------------------- motion

TEST(ScanSimulator, MovingTowardAWallSeesItNearerAtLaterColumns) {
  const auto route = straight(10.0, 0.0);  // at x = 10 m when the sweep starts at 1 s
  const World wall = wallWorld(30.0);
  const auto moving = ScanSimulator(wall, LidarModel::vlp16(), kExactMoving).scan(route, 1.0, 1);
  ASSERT_GT(moving.size(), 1000u);
  float first = 0.f, last = 0.f;
  for (std::size_t i = 0; i < moving.size(); ++i) {
    // Each column fires from where the sensor is at its time.
    EXPECT_NEAR(moving.points[i].x(), 30.0 - 10.0 * (1.0 + moving.time[i]), 1e-4) << i;
    if (i == 0) first = moving.time[i];
    last = moving.time[i];
  }
  EXPECT_GT(10.0 * (last - first), 0.3);  // the wall came that much nearer during the sweep
  const auto rigid = ScanSimulator(wall, LidarModel::vlp16(), kExact).scan(route, 1.0, 1);
  ASSERT_GT(rigid.size(), 1000u);
  for (const auto& p : rigid.points) EXPECT_NEAR(p.x(), 20.0, 1e-4);
}

TEST(ScanSimulator, PosesAreClampedToTheTrajectoryEnds) {
  const World world = smallStreetWorld();
  const auto route = straight(10.0, 1.73);
  const auto end = ScanSimulator(world, LidarModel::vlp16(), kExactMoving).scan(route, 5.0, 1);
  const auto rigid = ScanSimulator(world, LidarModel::vlp16(), kExact).scan(route, 5.0, 1);
  EXPECT_FALSE(end.empty());
  EXPECT_TRUE(bitIdentical(end, rigid));  // past the end every column fires from the last pose
}

TEST(ScanSimulator, PointsMappedByTheirGroundTruthPosesLieOnTheWorld) {
  const World world = smallStreetWorld();
  core::Trajectory route;  // an arc: moving and turning during the sweep
  for (int i = 0; i <= 20; ++i) {
    const double t = 0.1 * i;
    route.push_back(t, poseAt(-8.0 + 8.0 * t, 2.0 * std::sin(t), 1.73, 0.8 * t));
  }
  const ScanSimulator sim(world, LidarModel::vlp16(), kExactMoving);
  const double stamp = 0.95;
  const auto cloud = sim.scan(route, stamp, 1);
  ASSERT_GT(cloud.size(), 10000u);
  double worst = 0.0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Isometry3d T_world_sensor = *route.at(stamp + cloud.time[i]);
    worst = std::max(worst, distanceToMesh(world, T_world_sensor * cloud.points[i].cast<double>()));
  }
  EXPECT_LT(worst, 1e-3);
}

// ---------------------------------------------------------------- edges

TEST(ScanSimulator, EmptyWorldGivesAnEmptyConsistentCloud) {
  const auto cloud =
      ScanSimulator(World{}, LidarModel::vlp16(), {}).scan(still(poseAt(0, 0, 0)), 0.0, 1);
  EXPECT_TRUE(cloud.empty());
  EXPECT_TRUE(cloud.consistent());
}

TEST(ScanSimulator, AMiscalibratedLaserBendsAWallAsItsErrorsSay) {
  // The beam goes out along the laser's true elevation, the driver reports it
  // along the tabled one: a wall 10 m ahead, seen head-on by the -15 deg laser
  // whose true elevation is -14.5 deg and whose ranges read 0.1 m long, lies
  // at cos(15 deg) (10 / cos(14.5 deg) + 0.1) = 10.074 m. Its other lasers,
  // true to the table, see the wall where it is.
  const LidarModel model = LidarModel::vlp16();
  BeamCalibration unit;
  unit.elevation_error_deg.assign(16, 0.0);
  unit.range_offset.assign(16, 0.0);
  unit.elevation_error_deg[0] = 0.5;
  unit.range_offset[0] = 0.1;
  const ScanSimulator sim(wallWorld(10.0), model, kExact);
  const auto head_on_x = [](const core::PointCloud& cloud, int ring) {
    float best = 1.0f, x = 0.0f;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      if (cloud.ring[i] != ring) continue;
      const float azimuth = std::abs(std::atan2(cloud.points[i].y(), cloud.points[i].x()));
      if (azimuth < best) best = azimuth, x = cloud.points[i].x();
    }
    return x;
  };
  const auto bent = sim.scan(still(poseAt(0, 0, 0)), 0.0, 1, unit);
  const auto true_to_table = sim.scan(still(poseAt(0, 0, 0)), 0.0, 1);
  const double expected =
      std::cos(core::deg2rad(15.0)) * (10.0 / std::cos(core::deg2rad(14.5)) + 0.1);
  EXPECT_NEAR(head_on_x(bent, 0), expected, 1e-3);
  EXPECT_NEAR(head_on_x(true_to_table, 0), 10.0, 1e-3);
  EXPECT_NEAR(head_on_x(bent, 5), 10.0, 1e-3);
  // A calibration for another number of lasers is refused by name.
  unit.range_offset.pop_back();
  try {
    (void)sim.scan(still(poseAt(0, 0, 0)), 0.0, 1, unit);
    FAIL() << "no error for a calibration of the wrong size";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("vlp16"), std::string::npos) << e.what();
  }
}

TEST(ScanSimulator, AUnitWideElevationBiasBendsFlatGroundIntoACone) {
  // Every laser 0.205 deg above its tabled elevation, as KITTI's unit: a beam
  // of tabled elevation e meets flat ground h below at the range
  // h / sin(-(e + bias)), reported along e, so the ground seems to fall away
  // with distance by about tan(bias) per metre (7 cm at 20 m).
  const LidarModel model = LidarModel::hdl64();
  BeamCalibration unit;
  unit.elevation_error_deg.assign(model.elevations_deg.size(), 0.0);
  unit.range_offset.assign(model.elevations_deg.size(), 0.0);
  unit.elevation_bias_deg = 0.205;
  World world;
  addRoad(world, 200.f);
  LidarModel bodiless = model;
  bodiless.ego_body = std::nullopt;
  const ScanSimulator sim(world, bodiless, kExact);
  const double h = 1.73;
  const auto cone = sim.scan(still(poseAt(0, 0, h)), 0.0, 1, unit);
  const auto flat = sim.scan(still(poseAt(0, 0, h)), 0.0, 1);
  ASSERT_GT(cone.size(), 10000u);
  int far = 0;
  for (std::size_t i = 0; i < cone.size(); ++i) {
    const double tabled = core::deg2rad(model.elevations_deg[cone.ring[i]]);
    const double range = h / std::sin(-(tabled + core::deg2rad(0.205)));
    EXPECT_NEAR(cone.points[i].z(), range * std::sin(tabled), 2e-3) << "ring " << cone.ring[i];
    const double distance = cone.points[i].head<2>().norm();
    if (distance > 20.0) {
      ++far;
      EXPECT_LT(cone.points[i].z(), -h - 0.06) << "at " << distance << " m";
    }
  }
  EXPECT_GT(far, 1000);
  for (std::size_t i = 0; i < flat.size(); ++i) EXPECT_NEAR(flat.points[i].z(), -h, 2e-3);
}

TEST(ScanSimulator, RefusesAnEmptyTrajectoryAndABrokenModel) {
  const ScanSimulator sim(wallWorld(5.0), LidarModel::vlp16(), {});
  EXPECT_THROW((void)sim.scan(core::Trajectory{}, 0.0, 1), core::Error);
  LidarModel no_beams = LidarModel::vlp16();
  no_beams.elevations_deg.clear();
  EXPECT_THROW(ScanSimulator(wallWorld(5.0), no_beams, {}), core::Error);
  LidarModel inverted = LidarModel::vlp16();
  inverted.max_range = 0.1;
  EXPECT_THROW(ScanSimulator(wallWorld(5.0), inverted, {}), core::Error);
  EXPECT_EQ(sim.model().name, "vlp16");
}

}  // namespace
}  // namespace dcl::sim
