// Reading the formats a run starts from: a real KITTI scan, a real PCD scan,
// a pose-graph benchmark and a ground-truth trajectory.
#include <string>

#include <benchmark/benchmark.h>

#include <dcl/io/g2o.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/io/pcd.hpp>
#include <dcl/io/pose_file.hpp>

namespace {

const std::string kData = DCL_DATA_DIR;

void BM_ReadKittiScan(benchmark::State& state) {
  const std::string path = kData + "/lidar_scans/kitti_00/velodyne/000000.bin";
  std::size_t points = 0;
  for (auto _ : state) points = dcl::io::readKittiScan(path).size();
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(points));
}
BENCHMARK(BM_ReadKittiScan)->Unit(benchmark::kMillisecond);

void BM_ReadPcdBinary(benchmark::State& state) {
  const std::string path = kData + "/lidar_scans/hdl_outdoor_pair_fast_gicp/251370668.pcd";
  std::size_t points = 0;
  for (auto _ : state) points = dcl::io::readPcd(path).size();
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(points));
}
BENCHMARK(BM_ReadPcdBinary)->Unit(benchmark::kMillisecond);

void BM_ReadG2oSphere2500(benchmark::State& state) {
  const std::string path = kData + "/pose_graphs/3d/sphere2500.g2o";
  for (auto _ : state) benchmark::DoNotOptimize(dcl::io::readG2o(path).edges.size());
}
BENCHMARK(BM_ReadG2oSphere2500)->Unit(benchmark::kMillisecond);

void BM_ReadKittiPoses00(benchmark::State& state) {
  const std::string path = kData + "/trajectories/evo/KITTI_00_gt.txt";
  for (auto _ : state) benchmark::DoNotOptimize(dcl::io::readKittiPoses(path).size());
}
BENCHMARK(BM_ReadKittiPoses00)->Unit(benchmark::kMillisecond);

}  // namespace
