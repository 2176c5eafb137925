// Place recognition kernels on a real KITTI 00 HDL-64 scan, one core:
// LiDAR-Iris description (image, then features), one pair match (phase
// correlation + Hamming on bit-packed features), the wire codec, and Scan
// Context for comparison. Targets (BENCHMARKS.md): description < 1 ms, one
// match < 50 us; the original LiDAR-Iris takes 4.6 ms and 2.6 ms.
#include <cstdio>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include <dcl/io/kitti_scan.hpp>
#include <dcl/place/descriptor_codec.hpp>
#include <dcl/place/lidar_iris.hpp>
#include <dcl/place/scan_context.hpp>

namespace {

const dcl::core::PointCloud& kittiScan(int frame) {
  static std::vector<dcl::core::PointCloud> scans = [] {
    std::vector<dcl::core::PointCloud> s;
    for (const char* name : {"000000.bin", "000001.bin"})
      s.push_back(dcl::io::readKittiScan(std::string(DCL_DATA_DIR) +
                                         "/lidar_scans/kitti_00/velodyne/" + name));
    return s;
  }();
  return scans[static_cast<std::size_t>(frame)];
}

void BM_IrisImage(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(dcl::place::makeIrisImage(kittiScan(0)));
  state.counters["points"] = static_cast<double>(kittiScan(0).size());
}
BENCHMARK(BM_IrisImage)->Unit(benchmark::kMicrosecond);

void BM_IrisFeatures(benchmark::State& state) {
  const dcl::place::IrisImage image = dcl::place::makeIrisImage(kittiScan(0));
  for (auto _ : state) benchmark::DoNotOptimize(dcl::place::describeIrisImage(image));
}
BENCHMARK(BM_IrisFeatures)->Unit(benchmark::kMicrosecond);

void BM_IrisDescribe(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(dcl::place::describeIris(kittiScan(0)));
}
BENCHMARK(BM_IrisDescribe)->Unit(benchmark::kMicrosecond);

void BM_IrisMatch(benchmark::State& state) {
  const auto a = dcl::place::describeIris(kittiScan(0));
  const auto b = dcl::place::describeIris(kittiScan(1));
  for (auto _ : state) benchmark::DoNotOptimize(dcl::place::matchIris(a, b));
}
BENCHMARK(BM_IrisMatch)->Unit(benchmark::kMicrosecond);

void BM_IrisShiftCorrelation(benchmark::State& state) {
  const auto a = dcl::place::describeIris(kittiScan(0));
  const auto b = dcl::place::describeIris(kittiScan(1));
  for (auto _ : state) benchmark::DoNotOptimize(dcl::place::irisShiftCorrelation(a, b));
}
BENCHMARK(BM_IrisShiftCorrelation)->Unit(benchmark::kMicrosecond);

void BM_IrisHamming(benchmark::State& state) {
  const auto a = dcl::place::describeIris(kittiScan(0));
  const auto b = dcl::place::describeIris(kittiScan(1));
  for (auto _ : state) benchmark::DoNotOptimize(dcl::place::irisHammingDistance(a, b, 3));
}
BENCHMARK(BM_IrisHamming)->Unit(benchmark::kMicrosecond);

void BM_IrisEncode(benchmark::State& state) {
  const auto a = dcl::place::describeIris(kittiScan(0));
  std::size_t bytes = 0;
  for (auto _ : state) bytes = dcl::place::encodeIris(a).size();
  state.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_IrisEncode)->Unit(benchmark::kMicrosecond);

void BM_IrisDecode(benchmark::State& state) {
  const std::vector<std::uint8_t> bytes =
      dcl::place::encodeIris(dcl::place::describeIris(kittiScan(0)));
  for (auto _ : state) benchmark::DoNotOptimize(dcl::place::decodeIris(bytes));
}
BENCHMARK(BM_IrisDecode)->Unit(benchmark::kMicrosecond);

void BM_ScanContextDescribe(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(dcl::place::describeScanContext(kittiScan(0)));
}
BENCHMARK(BM_ScanContextDescribe)->Unit(benchmark::kMicrosecond);

void BM_ScanContextMatch(benchmark::State& state) {
  const auto a = dcl::place::describeScanContext(kittiScan(0));
  const auto b = dcl::place::describeScanContext(kittiScan(1));
  for (auto _ : state) benchmark::DoNotOptimize(dcl::place::matchScanContext(a, b));
}
BENCHMARK(BM_ScanContextMatch)->Unit(benchmark::kMicrosecond);

}  // namespace
