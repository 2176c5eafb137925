// The place index at scale: a query against 10,000 stored LiDAR-Iris keyframes
// (target under 1 ms on one core) and the cost of incremental insertion.
//
// The 10,000 descriptions come from the real KITTI 00 scans: each is one scan's
// bird's-eye image turned by a random yaw with a few percent of its height bits
// flipped, described again; so keys and features are all distinct and realistic.
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include <dcl/io/kitti_scan.hpp>
#include <dcl/place/lidar_iris.hpp>
#include <dcl/place/place_index.hpp>

namespace {

using dcl::place::IrisImage;

IrisImage kittiImage(int frame) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06d.bin", frame);
  const auto scan =
      dcl::io::readKittiScan(std::string(DCL_DATA_DIR) + "/lidar_scans/kitti_00/velodyne/" + name);
  return dcl::place::makeIrisImage(scan);
}

/// `image` turned by `shift` columns with each cell's bits flipped at rate `flip`.
IrisImage perturbed(const IrisImage& image, int shift, double flip, std::mt19937& rng) {
  IrisImage out = image;
  std::bernoulli_distribution coin(flip);
  std::uniform_int_distribution<int> bit(0, 7);
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.columns; ++c) {
      auto& cell =
          out.cells[static_cast<std::size_t>(r * image.columns + (c + shift) % image.columns)];
      cell = image.at(r, c);
      if (coin(rng)) cell ^= static_cast<std::uint8_t>(1u << bit(rng));
    }
  }
  return out;
}

/// 10,000 descriptions made once for all benchmarks.
const std::vector<std::shared_ptr<const dcl::place::PlaceDescriptor>>& stored() {
  static const auto all = [] {
    std::vector<IrisImage> bases;
    for (int frame : {0, 2, 4, 94, 198}) bases.push_back(kittiImage(frame));
    std::mt19937 rng(7);
    std::uniform_int_distribution<int> shift(0, 359);
    std::vector<std::shared_ptr<const dcl::place::PlaceDescriptor>> out;
    for (int i = 0; i < 10000; ++i) {
      const IrisImage image = perturbed(bases[i % bases.size()], shift(rng), 0.05, rng);
      out.push_back(
          std::make_shared<dcl::place::IrisDescriptor>(dcl::place::describeIrisImage(image)));
    }
    return out;
  }();
  return all;
}

dcl::place::PlaceIndex makeIndex(std::size_t n) {
  dcl::place::PlaceIndex index(std::make_shared<dcl::place::LidarIris>(), dcl::core::RobotId(0));
  for (std::size_t i = 0; i < n; ++i) index.add(dcl::core::KeyframeId(i), stored()[i]);
  return index;
}

/// One query (10 nearest row keys, re-ranked by the full match) against N stored keyframes.
void BM_PlaceIndexQuery(benchmark::State& state) {
  const auto index = makeIndex(static_cast<std::size_t>(state.range(0)));
  const auto query =
      std::make_shared<dcl::place::IrisDescriptor>(dcl::place::describeIrisImage(kittiImage(1)));
  for (auto _ : state) benchmark::DoNotOptimize(index.query(*query));
}
BENCHMARK(BM_PlaceIndexQuery)->Arg(1000)->Arg(10000)->Unit(benchmark::kMicrosecond);

/// Filling an index with N keyframes one by one (time a keyframe, amortised).
void BM_PlaceIndexInsert(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  stored();
  for (auto _ : state) benchmark::DoNotOptimize(makeIndex(n).size());
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
}
BENCHMARK(BM_PlaceIndexInsert)->Arg(10000)->Unit(benchmark::kMillisecond);

}  // namespace
