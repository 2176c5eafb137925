// Simulated datasets: the folder holds only dataset.yaml and ground truth, and
// scans regenerate bit-identically, across independently opened sources too,
// one per ground-truth pose, lining up with the world at their ground truth.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/sim/sim_source.hpp>

#include "dataset_test_util.hpp"

namespace dcl::sim {
namespace {

namespace fs = std::filesystem;

/// Closest point to `p` on triangle abc (Voronoi regions of vertices, edges, face).
Eigen::Vector3d closestOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                  const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  }
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

/// Distance from `p` to the nearest triangle of `world` (capped at `cap`).
double distanceToWorld(const World& world, const Eigen::Vector3d& p, double cap) {
  double best = cap;
  for (std::size_t t = 0; t < world.triangleCount(); ++t) {
    const auto& tri = world.triangles[t];
    const Eigen::Vector3d a = world.vertices[tri[0]].cast<double>();
    const Eigen::Vector3d b = world.vertices[tri[1]].cast<double>();
    const Eigen::Vector3d c = world.vertices[tri[2]].cast<double>();
    const Eigen::Vector3d lo = a.cwiseMin(b).cwiseMin(c).array() - best;
    const Eigen::Vector3d hi = a.cwiseMax(b).cwiseMax(c).array() + best;
    if ((p.array() < lo.array()).any() || (p.array() > hi.array()).any()) continue;
    best = std::min(best, (closestOnTriangle(p, a, b, c) - p).norm());
  }
  return best;
}

/// The median distance to the world of every `step`-th point of `cloud` placed by `T_world_sensor`.
double medianDistance(const World& world, const core::PointCloud& cloud,
                      const Eigen::Isometry3d& T_world_sensor, std::size_t step, double* max) {
  std::vector<double> d;
  for (std::size_t i = 0; i < cloud.size(); i += step) {
    d.push_back(distanceToWorld(world, T_world_sensor * cloud.points[i].cast<double>(), 1.0));
  }
  std::sort(d.begin(), d.end());
  if (max) *max = d.back();
  return d[d.size() / 2];
}

class SimSourceTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::freshDir(); }

  [[nodiscard]] io::DatasetSpec write(const Preset& preset, const SimDatasetOptions& o = {}) const {
    return writeSimDataset(dir_.string(), preset, o);
  }

  fs::path dir_;
};

TEST_F(SimSourceTest, FolderHoldsOnlyDescriptionAndGroundTruth) {
  const io::DatasetSpec spec = write(test::tinyPreset());
  std::uintmax_t bytes = 0;
  std::vector<std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir_)) {
    if (!e.is_regular_file()) continue;
    bytes += e.file_size();
    files.push_back(fs::relative(e.path(), dir_).string());
  }
  std::sort(files.begin(), files.end());
  EXPECT_EQ(files,
            (std::vector<std::string>{"dataset.yaml", "ground_truth/a.tum", "ground_truth/b.tum"}));
  EXPECT_LT(bytes, 8000u);
  ASSERT_TRUE(spec.sim);
  EXPECT_EQ(spec.sim->seed, 7u);
  EXPECT_EQ(spec.sim->world, io::WorldKind::city);
  EXPECT_EQ(spec.sensor, "vlp16");
  EXPECT_EQ(spec.robots[1].scans.type, io::ScanSourceType::sim);
}

TEST_F(SimSourceTest, OneScanPerGroundTruthPoseAtItsStamp) {
  const io::DatasetSpec spec = write(test::tinyPreset(7, 5));
  const auto sources = openDatasetScans(spec);
  ASSERT_EQ(sources.size(), 2u);
  const core::Trajectory gt = io::readGroundTruth(spec, 1);
  ASSERT_EQ(sources[1]->size(), gt.size());
  EXPECT_EQ(sources[1]->size(), 5u);
  EXPECT_EQ(sources[1]->stamp(4), gt.stamp(4));
  const core::PointCloud scan = sources[1]->scan(4);
  EXPECT_GT(scan.size(), 10000u);  // VLP-16: 28,800 rays, most hit the street
  EXPECT_TRUE(scan.consistent());
  EXPECT_TRUE(scan.hasRing() && scan.hasTime() && scan.hasIntensity());
  EXPECT_THROW((void)sources[1]->scan(5), core::Error);
  EXPECT_THROW((void)sources[1]->stamp(5), core::Error);
}

TEST_F(SimSourceTest, RegenerationIsBitIdenticalAcrossIndependentSources) {
  const io::DatasetSpec spec = write(test::tinyPreset());
  const auto first = openDatasetScans(spec);
  const core::PointCloud a2 = first[0]->scan(2);
  EXPECT_TRUE(test::sameCloud(a2, first[0]->scan(2)));  // the same scan twice
  // A second world built from the files alone, scanning in another order and in parallel.
  const auto second = openDatasetScans(io::readDataset(dir_.string()), {.parallel = false});
  core::PointCloud b1, a2_again;
  std::thread t1([&] { b1 = second[1]->scan(1); });
  std::thread t2([&] { a2_again = second[0]->scan(2); });
  t1.join();
  t2.join();
  EXPECT_TRUE(test::sameCloud(a2, a2_again));
  EXPECT_TRUE(test::sameCloud(first[1]->scan(1), b1));
  // Different scans differ (pose and noise seed).
  EXPECT_FALSE(test::sameCloud(a2, first[0]->scan(3)));
}

TEST_F(SimSourceTest, SeedChangesScans) {
  const auto seven = openDatasetScans(write(test::tinyPreset(7)));
  const core::PointCloud scan7 = seven[0]->scan(0);
  dir_ = test::freshDir("_other_seed");
  const auto eight = openDatasetScans(write(test::tinyPreset(8)));
  EXPECT_FALSE(test::sameCloud(scan7, eight[0]->scan(0)));
}

TEST_F(SimSourceTest, ScanSeedsAreDistinct) {
  EXPECT_NE(scanSeed(1, 0, 1), scanSeed(1, 1, 0));
  EXPECT_NE(scanSeed(1, 0, 0), scanSeed(2, 0, 0));
  EXPECT_EQ(scanSeed(5, 2, 9), scanSeed(5, 2, 9));
}

TEST_F(SimSourceTest, ScansAtTheirGroundTruthLieOnTheWorld) {
  const io::DatasetSpec spec =
      write(test::tinyPreset(7, 4), {.motion_distortion = false, .noise = false});
  const SimWorld world(spec);
  const core::Trajectory gt = io::readGroundTruth(spec, 0);  // as a user reads it
  const core::PointCloud scan = world.scan(0, 3);
  double max = 0.0;
  const double median = medianDistance(world.world(), scan, gt.pose(3), 97, &max);
  EXPECT_LT(median, 1e-5);  // float precision of the points: exact
  EXPECT_LT(max, 1e-4);
  // Control: 0.2 m off along each axis, most points leave the surfaces.
  Eigen::Isometry3d off = gt.pose(3);
  off.translation() += Eigen::Vector3d(0.2, 0.2, 0.2);
  EXPECT_GT(medianDistance(world.world(), scan, off, 97, nullptr), 0.02);
}

TEST_F(SimSourceTest, DistortedPointsLieOnTheWorldAtTheirFiringPose) {
  const io::DatasetSpec spec = write(test::tinyPreset(7, 4), {.noise = false});
  const SimWorld world(spec);
  const core::Trajectory& gt = world.groundTruth(0);
  const core::PointCloud scan = world.scan(0, 1);
  ASSERT_TRUE(scan.hasTime());
  std::vector<double> at_firing, at_stamp;
  for (std::size_t i = 0; i < scan.size(); i += 31) {
    const Eigen::Vector3d p = scan.points[i].cast<double>();
    const auto T_firing = gt.at(gt.stamp(1) + scan.time[i]);
    ASSERT_TRUE(T_firing);
    at_firing.push_back(distanceToWorld(world.world(), *T_firing * p, 1.0));
    at_stamp.push_back(distanceToWorld(world.world(), gt.pose(1) * p, 1.0));
  }
  std::sort(at_firing.begin(), at_firing.end());
  std::sort(at_stamp.begin(), at_stamp.end());
  EXPECT_LT(at_firing.back(), 1e-3);
  // The robot moves 2 m/s along the street: the sweep's end is 0.2 m from its
  // start, which moves points on surfaces across the street (ground and facades
  // along it barely notice).
  EXPECT_GT(at_stamp.back(), 0.01);
}

TEST_F(SimSourceTest, NoisyScansLineUpWithinTheNoise) {
  const io::DatasetSpec spec = write(test::tinyPreset(7, 4), {.motion_distortion = false});
  const SimWorld world(spec);
  const core::PointCloud scan = world.scan(1, 2);
  double max = 0;
  const double median = medianDistance(world.world(), scan, world.groundTruth(1).pose(2), 97, &max);
  // The unit's errors: up to 3 sigma of range offset (6 cm) and of each
  // laser's elevation (0.45 deg: 16 cm on the far side of a 20 m street), and
  // the elevation all its lasers share, which lifts or lowers a surface by
  // its tangent times the distance (a street's 10 m typically, 20 m at most).
  const double bias = std::tan(core::deg2rad(std::abs(world.unit(1).elevation_bias_deg)));
  EXPECT_GT(median, 1e-4);  // noise-free points are within 1e-5
  EXPECT_LT(median, 0.02 + 10.0 * bias);
  EXPECT_LT(max, 0.35 + 20.0 * bias);
  // Without the unit's errors, the noise alone: range noise of 2 cm sigma
  // along the beam, less to the surface at grazing incidence (most ground
  // returns), so the median is a few mm.
  io::DatasetSpec perfect = spec;
  perfect.sim->calibration_error = false;
  const SimWorld perfect_world(perfect);
  double perfect_max = 0;
  const double perfect_median =
      medianDistance(perfect_world.world(), perfect_world.scan(1, 2),
                     perfect_world.groundTruth(1).pose(2), 97, &perfect_max);
  EXPECT_GT(perfect_median, 1e-4);
  EXPECT_LT(perfect_median, 0.02);
  EXPECT_LT(perfect_max, 0.1);  // 5 sigma
  std::printf("median %.4f m with the unit (bias %.3f deg), %.4f m without\n", median,
              world.unit(1).elevation_bias_deg, perfect_median);
}

TEST_F(SimSourceTest, RobotsCarryTheirOwnUnitOrShareTheFirstRobots) {
  io::DatasetSpec spec = write(test::tinyPreset());
  const SimWorld own(spec);
  ASSERT_FALSE(own.unit(0).empty());
  ASSERT_EQ(own.unit(0).elevation_error_deg.size(), 16u);  // VLP-16
  EXPECT_NE(own.unit(0).elevation_error_deg, own.unit(1).elevation_error_deg);
  EXPECT_NE(own.unit(0).range_offset, own.unit(1).range_offset);

  // One car's drive split into robots: b carries a's unit, and b's scans change.
  spec.sim->shared_unit = true;
  const SimWorld shared(spec);
  EXPECT_EQ(shared.unit(0).elevation_error_deg, own.unit(0).elevation_error_deg);
  EXPECT_EQ(shared.unit(1).elevation_error_deg, own.unit(0).elevation_error_deg);
  EXPECT_EQ(shared.unit(1).range_offset, own.unit(0).range_offset);
  EXPECT_TRUE(test::sameCloud(shared.scan(0, 2), own.scan(0, 2)));
  EXPECT_FALSE(test::sameCloud(shared.scan(1, 2), own.scan(1, 2)));

  // Without calibration error there is nothing to share: perfect lasers.
  spec.sim->calibration_error = false;
  EXPECT_TRUE(SimWorld(spec).unit(1).empty());
}

TEST_F(SimSourceTest, AnImuReadsUpWithEveryScanAndLeavesTheScansAsTheyWere) {
  io::DatasetSpec spec = write(test::tinyPreset());
  ASSERT_FALSE(spec.sim->imu);  // the tiny preset has none
  const SimWorld without(spec);
  EXPECT_FALSE(without.up(0, 2).has_value());
  EXPECT_FALSE(SimScanSource(std::make_shared<const SimWorld>(spec), 0).up(2).has_value());

  spec.sim->imu = true;
  const SimWorld with(spec);
  EXPECT_TRUE(test::sameCloud(with.scan(1, 3), without.scan(1, 3)));  // its own numbers
  // Each reading is the truth turned by the unit's tilt and the reading's
  // noise (0.03 and 0.02 deg a axis): well inside 0.2 deg. The mean error over
  // a robot's readings is its unit's tilt, and each robot carries its own.
  std::array<Eigen::Vector3d, 2> mean_error{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  for (std::size_t r = 0; r < 2; ++r) {
    const core::Trajectory& truth = with.groundTruth(r);
    for (std::size_t i = 0; i < truth.size(); ++i) {
      const std::optional<Eigen::Vector3d> up = with.up(r, i);
      ASSERT_TRUE(up.has_value());
      const Eigen::Vector3d true_up =
          truth.pose(i).rotation().transpose() * Eigen::Vector3d::UnitZ();
      EXPECT_LT(core::rad2deg(std::acos(std::min(1.0, up->dot(true_up)))), 0.2) << r << " " << i;
      mean_error[r] += (*up - true_up) / static_cast<double>(truth.size());
    }
  }
  EXPECT_GT((mean_error[0] - mean_error[1]).norm(), 1e-5);
  EXPECT_EQ(*with.up(1, 3), *SimWorld(spec).up(1, 3));  // regenerated alike
  EXPECT_THROW((void)with.up(0, 99), core::Error);

  // One car's drive split into robots: one IMU, one tilt.
  spec.sim->shared_unit = true;
  const SimWorld shared(spec);
  const Eigen::Vector3d true_up =
      shared.groundTruth(1).pose(3).rotation().transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d own_error = *with.up(1, 3) - true_up;
  const Eigen::Vector3d shared_error = *shared.up(1, 3) - true_up;
  EXPECT_GT((own_error - shared_error).norm(), 1e-7);
}

TEST_F(SimSourceTest, OpensFileRobotsThroughIoAndRefusesNonSimDatasets) {
  io::DatasetSpec spec = write(test::tinyPreset());
  EXPECT_NE(openRobotScans(spec, 0)->describe().find("simulated robot 'a'"), std::string::npos);
  spec.sim.reset();
  EXPECT_THROW(SimWorld{spec}, core::Error);
  spec.robots[0].scans = {
      .type = io::ScanSourceType::kitti, .folder = "nowhere", .times = "none.txt"};
  EXPECT_THROW((void)openRobotScans(spec, 0), core::FileError);  // went to io's KITTI reader
}

TEST_F(SimSourceTest, RefusesAGroundTruthPoseFarOutsideAnyWorld) {
  // One pose 1000 km out (a typo, a file in another frame): the world over
  // the routes' extent would be built without end.
  const io::DatasetSpec spec = write(test::tinyPreset());
  const std::string file = spec.resolve(spec.robots[0].ground_truth);
  core::Trajectory route = io::readTumPoses(file);
  route.pose(2).translation().x() = 1e6;
  io::writeTumPoses(file, route);
  try {
    SimWorld world(spec);
    FAIL() << "a world was built";
  } catch (const core::Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("robot 'a'"), std::string::npos) << message;
    EXPECT_NE(message.find("pose 3 of " + file), std::string::npos) << message;
    EXPECT_NE(message.find("1000000.0"), std::string::npos) << message;
  }
}

/// The scan cache (DCL_SCAN_CACHE) of a folder of this test's own, the
/// environment as it was restored after it.
class ScanCacheTest : public SimSourceTest {
 protected:
  void SetUp() override {
    SimSourceTest::SetUp();
    for (const char* name : {kScanCacheVariable, kScanCacheSizeVariable}) {
      const char* value = std::getenv(name);
      saved_.emplace_back(name, value ? std::optional<std::string>(value) : std::nullopt);
      ::unsetenv(name);
    }
    cache_ = dir_.string() + "_cache";
    fs::remove_all(cache_);
    ::setenv(kScanCacheVariable, cache_.c_str(), 1);
  }
  void TearDown() override {
    for (const auto& [name, value] : saved_) {
      if (value)
        ::setenv(name.c_str(), value->c_str(), 1);
      else
        ::unsetenv(name.c_str());
    }
  }

  /// Every scan file in the cache and their bytes.
  [[nodiscard]] std::pair<std::vector<fs::path>, std::uintmax_t> cachedFiles() const {
    std::vector<fs::path> files;
    std::uintmax_t bytes = 0;
    if (!fs::exists(cache_)) return {files, bytes};
    for (const auto& entry : fs::recursive_directory_iterator(cache_)) {
      if (!entry.is_regular_file()) continue;
      files.push_back(entry.path());
      bytes += entry.file_size();
    }
    std::sort(files.begin(), files.end());
    return {files, bytes};
  }

  fs::path cache_;
  std::vector<std::pair<std::string, std::optional<std::string>>> saved_;
};

TEST_F(ScanCacheTest, ScansReadBackAreTheBitsCastAndACopiedDatasetFindsThem) {
  const io::DatasetSpec spec = write(test::tinyPreset());
  const SimWorld cast(spec, {.scan_cache = false});
  {
    const SimWorld first(spec);
    for (std::size_t robot = 0; robot < 2; ++robot)
      for (std::size_t i = 0; i < 4; ++i)
        EXPECT_TRUE(test::sameCloud(first.scan(robot, i), cast.scan(robot, i)));
    EXPECT_EQ(first.cachedScansStored(), 8u);
    EXPECT_EQ(first.cachedScansRead(), 0u);
    EXPECT_EQ(cast.cachedScansStored(), 0u);
  }
  EXPECT_EQ(cachedFiles().first.size(), 8u);
  // The dataset copied to another folder: the same scans, read and not cast.
  const fs::path copy = dir_.string() + "_copy";
  fs::remove_all(copy);
  fs::copy(spec.folder, copy, fs::copy_options::recursive);
  const SimWorld again(io::readDataset(copy.string()));
  for (std::size_t robot = 0; robot < 2; ++robot)
    for (std::size_t i = 0; i < 4; ++i)
      EXPECT_TRUE(test::sameCloud(again.scan(robot, i), cast.scan(robot, i)));
  EXPECT_EQ(again.cachedScansRead(), 8u);
  EXPECT_EQ(again.cachedScansStored(), 0u);
  // Another seed is another world: nothing of the first is read for it.
  const fs::path other_folder = dir_.string() + "_other";
  fs::remove_all(other_folder);
  const SimWorld other(writeSimDataset(other_folder.string(), test::tinyPreset(8)));
  EXPECT_FALSE(test::sameCloud(other.scan(0, 1), cast.scan(0, 1)));
  EXPECT_EQ(other.cachedScansRead(), 0u);
}

TEST_F(ScanCacheTest, ADamagedFileIsCastAgainAndReplaced) {
  const io::DatasetSpec spec = write(test::tinyPreset());
  const SimWorld cast(spec, {.scan_cache = false});
  { (void)SimWorld(spec).scan(0, 2); }
  const auto files = cachedFiles().first;
  ASSERT_EQ(files.size(), 1u);
  fs::resize_file(files[0], fs::file_size(files[0]) / 2);  // as a disk that filled leaves it
  {
    const SimWorld damaged(spec);
    EXPECT_TRUE(test::sameCloud(damaged.scan(0, 2), cast.scan(0, 2)));
    EXPECT_EQ(damaged.cachedScansRead(), 0u);
    EXPECT_EQ(damaged.cachedScansStored(), 1u);
  }
  const SimWorld repaired(spec);
  EXPECT_TRUE(test::sameCloud(repaired.scan(0, 2), cast.scan(0, 2)));
  EXPECT_EQ(repaired.cachedScansRead(), 1u);
}

TEST_F(ScanCacheTest, TheFolderStaysWithinItsBound) {
  const io::DatasetSpec spec = write(test::tinyPreset(7, 40));
  ::setenv(kScanCacheSizeVariable, "1", 1);  // 1 MB: a few VLP-16 scans
  const SimWorld world(spec);
  // Files the cache did not write, beside its own: never removed.
  const fs::path notes = cache_ / "notes.txt";
  const fs::path kept = cache_ / "0123456789abcdef" / "keep.pcd";
  for (const fs::path& f : {notes, kept}) {
    fs::create_directories(f.parent_path());
    std::ofstream(f) << "mine";
  }
  std::uintmax_t one_scan = 0;
  for (std::size_t i = 0; i < 40; ++i) {
    (void)world.scan(i % 2, i / 2);
    auto [files, bytes] = cachedFiles();
    bytes -= 8;  // the two files of mine
    if (i == 0) one_scan = bytes;
    // The bound, and at most an eighth of it more written before the folder is measured again.
    EXPECT_LE(bytes, (1u << 20) + (1u << 20) / 8 + one_scan) << "after scan " << i;
  }
  EXPECT_EQ(world.cachedScansStored(), 40u);
  const auto [files, bytes] = cachedFiles();
  EXPECT_GT(files.size(), 2u);
  EXPECT_LT(files.size(), 40u);
  EXPECT_TRUE(fs::exists(notes));
  EXPECT_TRUE(fs::exists(kept));
  // The latest scan stays: the files read or written longest ago went first.
  EXPECT_TRUE(std::any_of(files.begin(), files.end(),
                          [](const fs::path& f) { return f.filename() == "1-000019.pcd"; }));
}

TEST_F(ScanCacheTest, AFolderThatCannotBeWrittenLeavesTheScansAsCast) {
  const io::DatasetSpec spec = write(test::tinyPreset());
  std::ofstream(cache_) << "a file where the folder would be";
  const SimWorld world(spec);
  const SimWorld cast(spec, {.scan_cache = false});
  EXPECT_TRUE(test::sameCloud(world.scan(0, 1), cast.scan(0, 1)));
  EXPECT_TRUE(test::sameCloud(world.scan(1, 2), cast.scan(1, 2)));
  EXPECT_EQ(world.cachedScansStored(), 0u);
  EXPECT_TRUE(fs::is_regular_file(cache_));
}

TEST_F(ScanCacheTest, ASizeThatIsNotANumberIsNamed) {
  const io::DatasetSpec spec = write(test::tinyPreset());
  ::setenv(kScanCacheSizeVariable, "2GB", 1);
  try {
    SimWorld world(spec);
    FAIL() << "a world was built";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("DCL_SCAN_CACHE_MB: '2GB'"), std::string::npos)
        << e.what();
  }
  ::setenv(kScanCacheVariable, "", 1);  // an empty folder name: no cache, nothing read
  const SimWorld world(spec);
  (void)world.scan(0, 0);
  EXPECT_EQ(world.cachedScansStored(), 0u);
}

}  // namespace
}  // namespace dcl::sim
