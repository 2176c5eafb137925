// Back-end kernels, one core: PCM (paper §III-C) on real inter-robot loops.
// The main case is 500 candidate loops between two robots of City10000 (the
// mixRobust split): its 100 wrong loops, which come in mutually consistent
// groups, and 400 of its 626 true ones. Target (issue): PCM with 500
// candidate loops under 1 s.
#include <algorithm>
#include <set>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include <dcl/backend/max_clique.hpp>
#include <dcl/backend/pcm.hpp>
#include <dcl/backend/pcm_evaluation.hpp>
#include <dcl/backend/pcm_trajectory.hpp>

namespace {

using dcl::backend::Factor;

std::string outliers(const std::string& relative) {
  return std::string(DCL_DATA_DIR) + "/pose_graphs/multi_robot_outliers/mixrobust_real2d_split/" +
         relative;
}

/// City10000 split in two robots, cut to 500 candidate loops.
struct City500 {
  dcl::backend::PoseGraph graph;             ///< robot factors and the 500 loops
  std::vector<Factor> robot_factors;         ///< odometry and intra-robot loops
  std::vector<Factor> loops;                 ///< the 500 candidates
  std::set<dcl::backend::LoopId> reference;  ///< true loops
};

const City500& city500() {
  static const City500 city = [] {
    City500 c;
    const auto full = dcl::backend::readMultiRobotGraph(outliers("city10000/spilt_part_spoiled"));
    c.reference =
        dcl::backend::readReferenceLoops(outliers("city10000/spilt_part/fullgraph.g2o"), full);
    std::vector<Factor> inliers;
    for (const Factor& f : full.factors()) {
      if (f.from.robot == f.to.robot) {
        c.robot_factors.push_back(f);
      } else {
        (c.reference.contains(dcl::backend::loopId(f)) ? inliers : c.loops).push_back(f);
      }
    }
    for (std::size_t i = 0; i < 400; ++i) c.loops.push_back(inliers[i * inliers.size() / 400]);
    for (const auto& [key, pose] : full.nodes()) c.graph.addNode(key, pose);
    for (const Factor& f : c.robot_factors) c.graph.addFactor(f);
    for (const Factor& f : c.loops) c.graph.addFactor(f);
    return c;
  }();
  return city;
}

/// The consistency graph of the 500 loops, built once.
const dcl::backend::AdjacencyGraph& cityConsistency() {
  static const dcl::backend::AdjacencyGraph graph = [] {
    const City500& c = city500();
    dcl::backend::TrajectoryTree a(dcl::core::RobotId(0)), b(dcl::core::RobotId(1));
    for (const Factor& f : c.robot_factors) (f.from.robot == a.robot() ? a : b).add(f);
    dcl::backend::AdjacencyGraph g(c.loops.size());
    for (std::size_t i = 0; i < c.loops.size(); ++i) {
      for (std::size_t j = i + 1; j < c.loops.size(); ++j) {
        if (dcl::backend::cycleDistance(c.loops[i], c.loops[j], a, b) <=
            dcl::backend::PcmConfig{}.threshold) {
          g.addEdge(i, j);
        }
      }
    }
    return g;
  }();
  return graph;
}

void BM_PcmCity500Loops(benchmark::State& state) {
  const City500& c = city500();
  dcl::backend::PcmResult result;
  for (auto _ : state) {
    result = dcl::backend::runPcm(c.graph);
    benchmark::DoNotOptimize(result);
  }
  const dcl::backend::LoopScore s = dcl::backend::scoreLoops(result, c.reference);
  state.counters["loops"] = static_cast<double>(s.candidates);
  state.counters["kept"] = static_cast<double>(s.kept);
  state.counters["precision"] = s.precision;
  state.counters["recall"] = s.recall;
}
BENCHMARK(BM_PcmCity500Loops)->Unit(benchmark::kMillisecond);

/// The same loops arriving one by one, with a decision after each.
void BM_PcmCity500LoopsIncremental(benchmark::State& state) {
  const City500& c = city500();
  std::size_t kept = 0;
  for (auto _ : state) {
    dcl::backend::PairwiseConsistency pcm(dcl::core::RobotId(0), dcl::core::RobotId(1));
    for (const Factor& f : c.robot_factors) pcm.addRobotFactor(f);
    for (const Factor& f : c.loops) {
      pcm.addLoop(f);
      kept = pcm.decide().accepted.size();
    }
  }
  state.counters["kept"] = static_cast<double>(kept);
  state.counters["s_per_loop"] = benchmark::Counter(
      static_cast<double>(c.loops.size()),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_PcmCity500LoopsIncremental)->Unit(benchmark::kMillisecond);

void BM_CycleDistance(benchmark::State& state) {
  const City500& c = city500();
  dcl::backend::TrajectoryTree a(dcl::core::RobotId(0)), b(dcl::core::RobotId(1));
  for (const Factor& f : c.robot_factors) (f.from.robot == a.robot() ? a : b).add(f);
  std::size_t i = 0;
  for (auto _ : state) {
    const std::size_t j = (i * 7919 + 13) % c.loops.size();
    benchmark::DoNotOptimize(dcl::backend::cycleDistance(c.loops[i], c.loops[j], a, b));
    i = (i + 1) % c.loops.size();
  }
}
BENCHMARK(BM_CycleDistance)->Unit(benchmark::kMicrosecond);

void BM_MaxCliqueCity500(benchmark::State& state) {
  const dcl::backend::AdjacencyGraph& g = cityConsistency();
  dcl::backend::CliqueResult r;
  for (auto _ : state) {
    r = dcl::backend::maximumClique(g);
    benchmark::DoNotOptimize(r);
  }
  state.counters["clique"] = static_cast<double>(r.vertices.size());
  state.counters["exact"] = r.exact ? 1 : 0;
  state.counters["branch_nodes"] = static_cast<double>(r.branch_nodes);
}
BENCHMARK(BM_MaxCliqueCity500)->Unit(benchmark::kMillisecond);

void BM_HeuristicCliqueCity500(benchmark::State& state) {
  const dcl::backend::AdjacencyGraph& g = cityConsistency();
  std::size_t size = 0;
  for (auto _ : state) {
    const auto clique = dcl::backend::heuristicClique(g);
    size = clique.size();
    benchmark::DoNotOptimize(clique.data());
  }
  state.counters["clique"] = static_cast<double>(size);
}
BENCHMARK(BM_HeuristicCliqueCity500)->Unit(benchmark::kMillisecond);

/// CSAIL with 190 random wrong loops among 299.
void BM_PcmCsail299Loops(benchmark::State& state) {
  static const auto graph = dcl::backend::readMultiRobotGraph(outliers("CSAIL/spilt_190random"));
  for (auto _ : state) benchmark::DoNotOptimize(dcl::backend::runPcm(graph));
}
BENCHMARK(BM_PcmCsail299Loops)->Unit(benchmark::kMillisecond);

}  // namespace
