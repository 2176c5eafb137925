// The metrics on KITTI 00 (4541 poses, 3.7 km): what `dcl-slam eval` costs.
#include <string>

#include <benchmark/benchmark.h>

#include <dcl/eval/ate.hpp>
#include <dcl/eval/rpe.hpp>
#include <dcl/io/pose_file.hpp>

namespace {

const dcl::eval::Association& kitti00Pairs() {
  static const dcl::eval::Association pairs = [] {
    const std::string dir = std::string(DCL_DATA_DIR) + "/trajectories/evo/";
    return dcl::eval::associateByIndex(dcl::io::readKittiPoses(dir + "KITTI_00_ORB.txt"),
                                       dcl::io::readKittiPoses(dir + "KITTI_00_gt.txt"));
  }();
  return pairs;
}

void BM_AteSim3Kitti00(benchmark::State& state) {
  const auto& pairs = kitti00Pairs();
  for (auto _ : state) {
    benchmark::DoNotOptimize(dcl::eval::computeAte(pairs, dcl::eval::Alignment::sim3));
  }
}
BENCHMARK(BM_AteSim3Kitti00)->Unit(benchmark::kMillisecond);

void BM_RpeFramesKitti00(benchmark::State& state) {
  const auto& pairs = kitti00Pairs();
  dcl::eval::RpeOptions options;
  options.kitti = false;
  for (auto _ : state) benchmark::DoNotOptimize(dcl::eval::computeRpe(pairs, options));
}
BENCHMARK(BM_RpeFramesKitti00)->Unit(benchmark::kMillisecond);

void BM_KittiMetricKitti00(benchmark::State& state) {
  const auto& pairs = kitti00Pairs();
  for (auto _ : state) benchmark::DoNotOptimize(dcl::eval::computeKittiMetric(pairs));
}
BENCHMARK(BM_KittiMetricKitti00)->Unit(benchmark::kMillisecond);

}  // namespace
