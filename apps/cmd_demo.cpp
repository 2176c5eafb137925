// `dcl-slam demo`: the built-in default run. Until the swarm pipeline lands it
// shows what exists: evo-compatible evaluation of published KITTI 00
// estimates, a LiDAR map built from real HDL-64 scans and ground truth, a look
// at real multi-robot pose graphs, and a simulated three-robot swarm dataset.
#include <cstdlib>
#include <filesystem>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/core/error.hpp>
#include <dcl/core/progress.hpp>
#include <dcl/eval/ate.hpp>
#include <dcl/eval/rpe.hpp>
#include <dcl/io/cloud_file.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/g2o.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/io/ply.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/sim/export.hpp>
#include <dcl/sim/presets.hpp>
#include <dcl/sim/preview.hpp>
#include <dcl/sim/sim_source.hpp>

#include "commands.hpp"

namespace dcl::apps {

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;

struct DemoOptions {
  std::string data;              ///< the shared data folder
  std::string out = "out/demo";  ///< where results go
};

Json evaluateEstimate(const std::string& dir, const std::string& name, const std::string& file) {
  const auto gt = io::readKittiPoses(dir + "/KITTI_00_gt.txt");
  const auto est = io::readKittiPoses(dir + "/" + file);
  const auto pairs = eval::associateByIndex(est, gt);
  const auto se3 = eval::computeAte(pairs, eval::Alignment::se3);
  const auto sim3 = eval::computeAte(pairs, eval::Alignment::sim3);
  const auto rpe = eval::computeRpe(pairs);
  const double t_pct = rpe.kitti ? rpe.kitti->translation_percent : 0.0;
  const double r_100 = rpe.kitti ? rpe.kitti->rotation_deg_per_100m : 0.0;
  fmt::print("  {:<12} {:>9.3f} {:>9.3f} {:>7.4f} {:>9.3f} {:>11.4f}\n", name,
             se3.translation_m.rmse, sim3.translation_m.rmse, sim3.S_gt_est.s, t_pct, r_100);
  return {{"method", name},
          {"poses", pairs.size()},
          {"ate_se3_rmse_m", se3.translation_m.rmse},
          {"ate_sim3_rmse_m", sim3.translation_m.rmse},
          {"sim3_scale", sim3.S_gt_est.s},
          {"kitti_translation_percent", t_pct},
          {"kitti_rotation_deg_per_100m", r_100}};
}

Json evaluationPart(const std::string& data) {
  const std::string dir = data + "/trajectories/evo";
  fmt::print("\n1. Published KITTI 00 estimates against ground truth (4541 poses)\n");
  fmt::print("  {:<12} {:>9} {:>9} {:>7} {:>9} {:>11}\n", "method", "ATE se3", "ATE sim3", "scale",
             "KITTI t%", "r deg/100m");
  Json rows = Json::array();
  rows.push_back(evaluateEstimate(dir, "ORB-SLAM2", "KITTI_00_ORB.txt"));
  rows.push_back(evaluateEstimate(dir, "S-PTAM", "KITTI_00_SPTAM.txt"));
  return rows;
}

/// Frames 0-5 of KITTI 00 put into the world frame with the ground truth and
/// the camera-LiDAR calibration, every 4th point kept, written as one PLY map.
Json mapPart(const std::string& data, const std::string& out) {
  const std::string scans = data + "/lidar_scans/kitti_00";
  const auto calib = io::readKittiCalib(scans + "/calib.txt");
  const auto gt = io::readKittiPoses(data + "/trajectories/evo/KITTI_00_gt.txt");
  fmt::print("\n2. A map from real HDL-64 scans (KITTI 00 frames 0-5) and ground truth\n");
  core::PointCloud map;
  core::ProgressBar progress("  scans", 6, "scans");
  std::size_t raw_points = 0;
  for (std::size_t i = 0; i < 6; ++i) {
    const auto scan = io::readKittiScan(fmt::format("{}/velodyne/{:06}.bin", scans, i));
    raw_points += scan.size();
    core::PointCloud thin;
    for (std::size_t k = 0; k < scan.size(); k += 4) thin.points.push_back(scan.points[k]);
    map.append(core::transformed(thin, gt.pose(i) * calib.T_cam_velo));
    progress.update(i + 1);
  }
  progress.finish();
  const std::string path = out + "/kitti00_map.ply";
  io::writePly(path, map);
  fmt::print("  {} scan points read, {} written to {}\n", raw_points, map.size(), path);
  return {{"scans", 6}, {"points_read", raw_points}, {"map_points", map.size()}, {"map", path}};
}

Json graphPart(const std::string& data) {
  const std::string dir = data + "/pose_graphs/multi_robot/distributed_mapper/example_4robots";
  fmt::print("\n3. A real multi-robot pose graph, split per robot ({})\n", "example_4robots");
  fmt::print("  {:<6} {:>8} {:>8} {:>12}\n", "robot", "poses", "edges", "inter-robot");
  Json robots = Json::array();
  for (int r = 0; r < 4; ++r) {
    const auto graph = io::readG2o(fmt::format("{}/{}.g2o", dir, r));
    const auto inter = io::interRobotEdges(graph).size();
    fmt::print("  {:<6} {:>8} {:>8} {:>12}\n", r, graph.vertices.size(), graph.edges.size(), inter);
    robots.push_back({{"robot", r},
                      {"poses", graph.vertices.size()},
                      {"edges", graph.edges.size()},
                      {"inter_robot_edges", inter}});
  }
  return robots;
}

/// The `demo` preset of the simulator: three robots in a campus world, their
/// dataset (regenerated on demand, so only ground truth on disk), a bird's-eye
/// preview, and one simulated scan per robot.
Json swarmPart(const std::string& out) {
  fmt::print("\n4. A simulated three-robot swarm dataset (preset 'demo')\n");
  const std::string folder = out + "/swarm";
  const sim::Preset preset = sim::makePreset("demo");
  const io::DatasetSpec spec = sim::writeSimDataset(folder, preset);
  const sim::SimWorld world(spec);
  std::vector<core::Trajectory> routes;
  Json robots = Json::array();
  fmt::print("  {:<6} {:>9} {:>8} {:>14}\n", "robot", "length m", "scans", "points/scan");
  for (std::size_t r = 0; r < world.robots(); ++r) {
    routes.push_back(world.groundTruth(r));
    const auto points = world.scan(r, routes.back().size() / 2).size();
    fmt::print("  {:<6} {:>9.1f} {:>8} {:>14}\n", spec.robots[r].name, routes.back().length(),
               routes.back().size(), points);
    robots.push_back({{"robot", spec.robots[r].name},
                      {"length_m", routes.back().length()},
                      {"scans", routes.back().size()},
                      {"points_per_scan", points}});
  }
  sim::writeWorldPreview(world.world(), routes, folder + "/preview_world.png");
  fmt::print("  {} triangles; dataset and preview_world.png in {}\n", world.world().triangleCount(),
             folder);
  return {{"dataset", folder}, {"triangles", world.world().triangleCount()}, {"robots", robots}};
}

void runDemo(const DemoOptions& o) {
  if (!fs::is_directory(o.data)) {
    throw core::Error("data folder '" + o.data +
                      "' not found; pass --data DIR or set DCL_DATA_DIR");
  }
  fmt::print("dcl-slam demo (data: {}, results: {})\n", o.data, o.out);
  fs::create_directories(o.out);
  Json metrics = {{"evaluation", evaluationPart(o.data)},
                  {"map", mapPart(o.data, o.out)},
                  {"pose_graph", graphPart(o.data)},
                  {"swarm", swarmPart(o.out)}};
  const std::string path = o.out + "/metrics.json";
  io::writeFileAtomic(path, [&](std::ostream& s) { s << metrics.dump(2) << "\n"; });
  fmt::print("\nwrote {}\n", path);
}

}  // namespace

void addDemoCommand(CLI::App& app, const AppConfig& /*config*/) {
  auto* cmd = app.add_subcommand("demo", "the built-in default run (no arguments needed)");
  auto o = std::make_shared<DemoOptions>();
  o->data = defaultDataDir();
  cmd->add_option("--data", o->data, "the shared data folder (or DCL_DATA_DIR)")
      ->capture_default_str();
  cmd->add_option("--out", o->out, "output folder")->capture_default_str();
  cmd->callback([o] { runDemo(*o); });
}

}  // namespace dcl::apps
