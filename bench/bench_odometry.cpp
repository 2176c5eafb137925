// The built-in LiDAR odometry: time a frame on the real KITTI 00 scans (frames
// 0..5, HDL-64) on one and two cores, and over simulated HDL-64 (kitti05-3
// robot a) and VLP-16 (campus-3 robot a) sequences, with their drift.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <dcl/core/trajectory.hpp>
#include <dcl/eval/association.hpp>
#include <dcl/eval/ate.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/odometry/lidar_odometry.hpp>
#include <dcl/sim/presets.hpp>
#include <dcl/sim/sim_source.hpp>

namespace {

/// KITTI 00 frames 0..5 as read from the shared data.
const std::vector<dcl::core::PointCloud>& kittiFrames() {
  static const std::vector<dcl::core::PointCloud> frames = [] {
    std::vector<dcl::core::PointCloud> scans;
    for (int i = 0; i <= 5; ++i) {
      char name[16];
      std::snprintf(name, sizeof(name), "%06d.bin", i);
      scans.push_back(dcl::io::readKittiScan(std::string(DCL_DATA_DIR) +
                                             "/lidar_scans/kitti_00/velodyne/" + name));
    }
    return scans;
  }();
  return frames;
}

/// One iteration is one frame; the sequence 0..5 restarts with a fresh odometry.
void BM_OdometryKitti00(benchmark::State& state) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                            static_cast<std::size_t>(state.range(0)));
  const auto& frames = kittiFrames();
  auto odometry = std::make_unique<dcl::odometry::LidarOdometry>();
  std::size_t frame = 0;
  for (auto _ : state) {
    if (frame == frames.size()) {
      odometry = std::make_unique<dcl::odometry::LidarOdometry>();
      frame = 0;
    }
    benchmark::DoNotOptimize(odometry->process(0.1 * static_cast<double>(frame), frames[frame]));
    ++frame;
  }
  state.counters["points_per_scan"] = static_cast<double>(frames[1].size());
}
BENCHMARK(BM_OdometryKitti00)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

/// A simulated dataset written to a scratch folder and its world (built once per preset).
const dcl::sim::SimWorld& simWorld(const std::string& preset) {
  static std::map<std::string, std::unique_ptr<dcl::sim::SimWorld>> worlds;
  auto& world = worlds[preset];
  if (!world) {
    const auto folder = std::filesystem::temp_directory_path() /
                        ("dcl_bench_odometry_" + preset + "_" + std::to_string(::getpid()));
    dcl::sim::PresetOptions options;
    options.data_dir = DCL_DATA_DIR;
    const auto spec =
        dcl::sim::writeSimDataset(folder.string(), dcl::sim::makePreset(preset, options));
    world = std::make_unique<dcl::sim::SimWorld>(spec);
    std::filesystem::remove_all(folder);
  }
  return *world;
}

/// Frames 0..N-1 of robot a (N = the iteration count); scans are generated
/// outside the timed region. Counters: drift at the end and ATE (no alignment).
void odometrySim(benchmark::State& state, const std::string& preset) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                            static_cast<std::size_t>(state.range(0)));
  const auto& world = simWorld(preset);
  const auto& truth = world.groundTruth(0);
  dcl::odometry::LidarOdometry odometry;
  dcl::core::Trajectory estimate, reference;
  std::size_t frame = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const auto scan = world.scan(0, frame);
    state.ResumeTiming();
    const auto result = odometry.process(truth.stamp(frame), scan);
    estimate.push_back(truth.stamp(frame), result.T_odom_sensor);
    reference.push_back(truth.stamp(frame), truth.pose(0).inverse() * truth.pose(frame));
    ++frame;
  }
  const auto ate = dcl::eval::computeAte(dcl::eval::associateByIndex(estimate, reference),
                                         dcl::eval::Alignment::none);
  const double end_error =
      (estimate.poses().back().translation() - reference.poses().back().translation()).norm();
  state.counters["path_m"] = reference.length();
  state.counters["end_error_percent"] = 100.0 * end_error / std::max(reference.length(), 1e-9);
  state.counters["ate_rmse_m"] = ate.translation_m.rmse;
}

void BM_OdometrySimHdl64(benchmark::State& state) {
  odometrySim(state, "kitti05-3");
}
void BM_OdometrySimVlp16(benchmark::State& state) {
  odometrySim(state, "campus-3");
}
BENCHMARK(BM_OdometrySimHdl64)
    ->Arg(1)
    ->Arg(2)
    ->Iterations(150)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_OdometrySimVlp16)
    ->Arg(1)
    ->Arg(2)
    ->Iterations(300)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
