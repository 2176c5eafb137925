#include "run_graphs.hpp"

#include <cstdint>
#include <filesystem>
#include <set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/core/error.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/io/pose_graph_g2o.hpp>

#include "commands.hpp"

namespace dcl::apps {
namespace {

using Json = nlohmann::ordered_json;

eval::RobotGraph readRobot(const std::string& run, const io::DatasetSpec& spec, std::size_t index) {
  eval::RobotGraph r;
  r.name = spec.robots[index].name;
  r.id = core::RobotId(static_cast<std::uint8_t>(index));
  const std::string folder = run + "/" + r.name;
  const core::Trajectory keyframes = io::readTumPoses(folder + "/trajectory.tum");
  r.ground_truth = io::readGroundTruth(spec, index);
  const backend::PoseGraph all = io::readPoseGraph(folder + "/graph.g2o");
  for (const auto& [key, T] : all.nodes())
    if (key.robot == r.id) r.graph.addNode(key, T);
  for (const backend::Factor& f : all.factors()) r.graph.addFactor(f);
  if (r.graph.size() != keyframes.size()) {
    throw core::Error(
        fmt::format("{}/graph.g2o: {} keyframes of robot '{}', but trajectory.tum has {}", folder,
                    r.graph.size(), r.name, keyframes.size()));
  }
  for (std::size_t k = 0; k < keyframes.size(); ++k) {
    if (!r.graph.hasNode({r.id, core::KeyframeId(k)})) {
      throw core::Error(
          fmt::format("{}/graph.g2o: no vertex for keyframe {} of robot '{}'", folder, k, r.name));
    }
    const auto gt = r.ground_truth.at(keyframes.stamp(k));
    if (!gt) {
      throw core::Error(fmt::format("{}: no ground truth at keyframe {} (t = {} s)", folder, k,
                                    keyframes.stamp(k)));
    }
    r.stamps.push_back(keyframes.stamp(k));
    r.T_world_gt.push_back(*gt);
  }
  return r;
}

}  // namespace

std::vector<eval::RobotGraph> readRunGraphs(const std::string& run, const std::string& dataset) {
  const io::DatasetSpec spec = io::readDataset(dataset, datasetReadOptions());
  std::vector<eval::RobotGraph> robots;
  for (std::size_t i = 0; i < spec.robots.size(); ++i) {
    if (!std::filesystem::exists(run + "/" + spec.robots[i].name + "/graph.g2o")) {
      throw core::Error("run '" + run + "' has no graph.g2o for robot '" + spec.robots[i].name +
                        "' of dataset '" + dataset + "' (is it the run of that dataset?)");
    }
    robots.push_back(readRobot(run, spec, i));
  }
  return robots;
}

void readRobotsThatLeft(const std::string& run, std::vector<eval::RobotGraph>& robots) {
  const std::string path = run + "/metrics.json";
  if (!std::filesystem::exists(path)) return;
  const std::vector<char> text = io::readFile(path);
  const Json j = Json::parse(text.begin(), text.end(), nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains("robots") || !j["robots"].is_array())
    throw core::FileError({.path = path}, "not a run's metrics (a JSON object with 'robots')");
  std::set<std::string> left;
  for (const Json& r : j["robots"]) {
    if (!r.is_object() || !r.contains("name") || !r["name"].is_string())
      throw core::FileError({.path = path}, "a robot without a 'name'");
    if (r.contains("left_at_s") && !r["left_at_s"].is_null())
      left.insert(r["name"].get<std::string>());
  }
  for (eval::RobotGraph& r : robots) r.left = left.contains(r.name);
}

}  // namespace dcl::apps
