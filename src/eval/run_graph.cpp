#include <algorithm>
#include <map>
#include <set>
#include <utility>

#include <dcl/eval/run_graph.hpp>

namespace dcl::eval {

backend::PoseGraph jointGraph(const std::vector<RobotGraph>& robots, JointFactors factors) {
  const bool inter = factors == JointFactors::joint || factors == JointFactors::exact;
  const bool true_loops = factors == JointFactors::exact;
  std::map<core::RobotId, const RobotGraph*> by_id;
  for (const RobotGraph& r : robots) by_id[r.id] = &r;
  backend::PoseGraph joint;
  std::set<std::pair<core::PoseKey, core::PoseKey>> loops;
  std::set<core::RobotId> tied;  ///< robots with an inter-robot loop in the graph
  for (const RobotGraph& r : robots) {
    for (const auto& [key, T] : r.graph.nodes()) joint.addNode(key, T);
    for (backend::Factor f : r.graph.factors()) {
      if (f.from.robot == f.to.robot) {
        if (f.from.robot == r.id &&
            (f.kind == backend::FactorKind::odometry || factors != JointFactors::odometry))
          joint.addFactor(f);
        continue;
      }
      if (!inter || !by_id.contains(f.from.robot) || !by_id.contains(f.to.robot)) continue;
      const auto pair = std::minmax(f.from, f.to);
      if (!loops.insert({pair.first, pair.second}).second) continue;
      if (true_loops) {
        const RobotGraph& a = *by_id.at(f.from.robot);
        const RobotGraph& b = *by_id.at(f.to.robot);
        const std::size_t i = f.from.keyframe.value(), j = f.to.keyframe.value();
        if (i >= a.T_world_gt.size() || j >= b.T_world_gt.size()) continue;
        f.T_from_to = a.T_world_gt[i].inverse() * b.T_world_gt[j];
      }
      joint.addFactor(f);
      tied.insert({f.from.robot, f.to.robot});
    }
  }
  // Every robot's first keyframe holds its frame: a robot without loops would
  // otherwise float, and the others are moved by their loops regardless.
  for (const RobotGraph& r : robots)
    if (!tied.contains(r.id) || &r == &robots.front()) joint.fix({r.id, core::KeyframeId(0)});
  return joint;
}

std::vector<std::size_t> loopGroups(const std::vector<RobotGraph>& robots) {
  std::vector<std::size_t> group(robots.size());
  for (std::size_t i = 0; i < robots.size(); ++i) group[i] = i;
  const auto root = [&](std::size_t i) {
    while (group[i] != i) i = group[i];
    return i;
  };
  std::map<core::RobotId, std::size_t> index;
  for (std::size_t i = 0; i < robots.size(); ++i) index[robots[i].id] = i;
  for (const RobotGraph& r : robots) {
    for (const backend::Factor& f : r.graph.factors()) {
      if (f.from.robot == f.to.robot || !index.contains(f.from.robot) ||
          !index.contains(f.to.robot))
        continue;
      const std::size_t a = root(index.at(f.from.robot));
      const std::size_t b = root(index.at(f.to.robot));
      group[std::max(a, b)] = std::min(a, b);
    }
  }
  for (std::size_t i = 0; i < robots.size(); ++i) group[i] = root(i);
  return group;
}

}  // namespace dcl::eval
