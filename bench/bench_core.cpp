// Micro-benchmarks of the SE(3) helpers every module leans on.
#include <random>

#include <benchmark/benchmark.h>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/se3.hpp>

namespace {

using dcl::core::Vector6d;

Vector6d sampleTangent() {
  Vector6d xi;
  xi << 0.4, -1.2, 0.7, 0.3, -0.5, 1.1;
  return xi;
}

void BM_ExpSE3(benchmark::State& state) {
  const Vector6d xi = sampleTangent();
  for (auto _ : state) benchmark::DoNotOptimize(dcl::core::expSE3(xi));
}
BENCHMARK(BM_ExpSE3);

void BM_LogSE3(benchmark::State& state) {
  const Eigen::Isometry3d T = dcl::core::expSE3(sampleTangent());
  for (auto _ : state) benchmark::DoNotOptimize(dcl::core::logSE3(T));
}
BENCHMARK(BM_LogSE3);

void BM_ProjectToSO3(benchmark::State& state) {
  Eigen::Matrix3d M = dcl::core::expSO3(Eigen::Vector3d(0.3, -0.2, 1.1));
  M(0, 1) += 1e-3;
  for (auto _ : state) benchmark::DoNotOptimize(dcl::core::projectToSO3(M));
}
BENCHMARK(BM_ProjectToSO3);

// Moving a full HDL-64 scan (about 120k points) into another frame.
void BM_TransformCloud(benchmark::State& state) {
  dcl::core::PointCloud cloud;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-80.f, 80.f);
  cloud.points.resize(static_cast<std::size_t>(state.range(0)));
  for (auto& p : cloud.points) p = {u(rng), u(rng), u(rng) * 0.05f};
  const Eigen::Isometry3d T = dcl::core::expSE3(sampleTangent());
  for (auto _ : state) {
    cloud.transform(T);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_TransformCloud)->Arg(120000);

}  // namespace
