// LiDAR sweep simulation: scans per second for HDL-64 and VLP-16 in a generated
// city, on one core (serial casting) and on two (TBB), and the scan stream of the
// kitti05-3 preset against real time.
#include <cstdint>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <dcl/core/se3.hpp>
#include <dcl/sim/presets.hpp>
#include <dcl/sim/scan_simulator.hpp>
#include <dcl/sim/world_gen.hpp>

namespace {

constexpr double kStreetLength = 1000.0;  // m
constexpr double kSpeed = 10.0;           // m/s

/// A straight 1 km drive at 10 m/s, poses at 10 Hz.
dcl::core::Trajectory straightRoute(double mount_height) {
  dcl::core::Trajectory route;
  for (double t = 0.0; t <= kStreetLength / kSpeed; t += 0.1)
    route.push_back(t, dcl::core::makePose(Eigen::Vector3d(kSpeed * t, 0.0, mount_height),
                                           Eigen::Matrix3d::Identity()));
  return route;
}

/// The city generated along the straight route (about 10^5 triangles).
const dcl::sim::World& cityWorld() {
  static const dcl::sim::World world = [] {
    const std::vector<dcl::core::Trajectory> routes{straightRoute(1.73)};
    return dcl::sim::generateCityWorld({.routes = routes, .mount_height = 1.73, .seed = 1});
  }();
  return world;
}

/// Casting on `threads` cores: one casts serially, more use TBB limited to that many.
dcl::sim::ScanSimulator makeSimulator(const dcl::sim::World& world, dcl::sim::LidarModel model,
                                      int threads) {
  return {
      world, std::move(model), {.motion_distortion = true, .noise = true, .parallel = threads > 1}};
}

/// Scans along the straight route at 10 Hz; reports points and mean intensity a scan.
void scanCity(benchmark::State& state, const dcl::sim::LidarModel& model) {
  const int threads = static_cast<int>(state.range(0));
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                            static_cast<std::size_t>(threads));
  const auto simulator = makeSimulator(cityWorld(), model, threads);
  const auto route = straightRoute(model.mount_height);
  std::uint64_t frame = 0;
  std::size_t points = 0;
  double intensity = 0.0;
  for (auto _ : state) {
    const double stamp = 2.0 + 0.1 * static_cast<double>(frame % 900);
    const auto cloud = simulator.scan(route, stamp, frame);
    points += cloud.size();
    for (float v : cloud.intensity) intensity += v;
    ++frame;
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(frame));
  state.counters["points"] = static_cast<double>(points) / static_cast<double>(frame);
  state.counters["intensity"] = intensity / static_cast<double>(points);
  state.counters["triangles"] = static_cast<double>(cityWorld().triangleCount());
}

void BM_ScanHdl64(benchmark::State& state) {
  scanCity(state, dcl::sim::LidarModel::hdl64());
}
BENCHMARK(BM_ScanHdl64)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ScanVlp16(benchmark::State& state) {
  scanCity(state, dcl::sim::LidarModel::vlp16());
}
BENCHMARK(BM_ScanVlp16)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

/// Building the Embree scene of the city (once per world).
void BM_BuildCityScene(benchmark::State& state) {
  for (auto _ : state) {
    const dcl::sim::ScanSimulator simulator(cityWorld(), dcl::sim::LidarModel::hdl64());
    benchmark::DoNotOptimize(&simulator);
  }
  state.counters["triangles"] = static_cast<double>(cityWorld().triangleCount());
}
BENCHMARK(BM_BuildCityScene)->Unit(benchmark::kMillisecond)->UseRealTime();

/// The kitti05-3 preset: its city and its three robots' routes.
struct Kitti05 {
  dcl::sim::Preset preset;
  dcl::sim::World world;
};

const Kitti05& kitti05() {
  static const Kitti05 data = [] {
    Kitti05 d{dcl::sim::makePreset("kitti05-3", {.data_dir = DCL_DATA_DIR}), {}};
    std::vector<dcl::core::Trajectory> routes;
    for (const auto& route : d.preset.routes) routes.push_back(route.T_world_sensor);
    d.world = dcl::sim::generateCityWorld(
        {.routes = routes, .mount_height = d.preset.mount_height, .seed = d.preset.seed});
    return d;
  }();
  return data;
}

/// The kitti05-3 scan stream: scans of all robots, spread over their routes.
/// `realtime` is scans a second over the 10 Hz of all robots together
/// (above 1: the dataset's scans are made faster than the robots record them).
void BM_Kitti05Stream(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                            static_cast<std::size_t>(threads));
  const auto& data = kitti05();
  const auto simulator =
      makeSimulator(data.world, dcl::sim::LidarModel::byName(data.preset.sensor), threads);
  const auto& routes = data.preset.routes;
  std::uint64_t frame = 0;
  for (auto _ : state) {
    const auto& route = routes[frame % routes.size()].T_world_sensor;
    const auto scans = static_cast<std::uint64_t>(route.stamps().back() * 10.0);
    const double stamp = 0.1 * static_cast<double>((frame * 37) % scans);
    benchmark::DoNotOptimize(simulator.scan(route, stamp, frame).size());
    ++frame;
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(frame));
  state.counters["realtime"] =
      benchmark::Counter(static_cast<double>(frame) / (10.0 * static_cast<double>(routes.size())),
                         benchmark::Counter::kIsRate);
  state.counters["triangles"] = static_cast<double>(data.world.triangleCount());
}
BENCHMARK(BM_Kitti05Stream)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
