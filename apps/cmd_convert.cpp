// `dcl-slam convert`: between scan formats and between pose formats, and from
// the topics of ROS1 bags and ROS 2 bags (MCAP) to either.
#include <algorithm>
#include <filesystem>
#include <optional>
#include <string>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/core/progress.hpp>
#include <dcl/io/cloud_file.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/io/rosbag.hpp>
#include <dcl/ros/ros2_bag.hpp>

#include "commands.hpp"
#include "output_folder.hpp"

namespace dcl::apps {

namespace {

namespace fs = std::filesystem;

struct ConvertOptions {
  std::string input;
  std::string output;
  std::string from;                  ///< pose format of the input (kitti | tum)
  std::string to;                    ///< pose format of the output (kitti | tum)
  std::string topic;                 ///< bag topic
  std::string times;                 ///< times file of a KITTI pose input
  std::string out_times;             ///< times file to write beside a KITTI pose output
  std::string encoding = "binary";   ///< PCD / PLY encoding: ascii | binary
  std::string cloud_format = "bin";  ///< per-scan files from a bag: bin | pcd | ply
  bool force = false;                ///< replace a scan folder that holds other files
};

std::string extensionOf(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

bool isCloudFile(const std::string& path) {
  return io::cloudFormatOf(path).has_value();
}

std::optional<std::string> optionalPath(const std::string& path) {
  return path.empty() ? std::nullopt : std::optional<std::string>(path);
}

io::CloudWriteOptions writeOptions(const std::string& encoding) {
  if (encoding != "ascii" && encoding != "binary") {
    throw core::Error("--encoding: '" + encoding + "' is not ascii or binary");
  }
  return {.ascii = encoding == "ascii"};
}

void convertCloud(const ConvertOptions& o) {
  if (!isCloudFile(o.output)) {
    throw core::Error("output '" + o.output + "': a scan converts to .bin, .pcd or .ply");
  }
  const core::PointCloud cloud = io::readCloud(o.input);
  io::writeCloud(o.output, cloud, writeOptions(o.encoding));
  fmt::print("{} points: {} -> {}\n", cloud.size(), o.input, o.output);
}

void convertPoses(const ConvertOptions& o) {
  if (o.from.empty() || o.to.empty()) {
    throw core::Error("pose files need --from and --to (kitti or tum)");
  }
  const core::Trajectory trajectory =
      io::readPoses(o.input, io::parsePoseFormat(o.from), optionalPath(o.times));
  io::writePoses(o.output, io::parsePoseFormat(o.to), trajectory, optionalPath(o.out_times));
  fmt::print("{} poses: {} ({}) -> {} ({})\n", trajectory.size(), o.input, o.from, o.output, o.to);
}

/// Every cloud of a bag topic as numbered files in a folder, with their stamps
/// in times.txt; `Reader` reads a ROS1 bag or a ROS 2 one (MCAP).
template <class Reader>
void convertBagClouds(const ConvertOptions& o) {
  OutputFolder out(o.output, o.force);  // the scans appear together, or not at all
  Reader reader(o.input, o.topic);
  const fs::path folder(out.path());
  std::vector<double> stamps;
  core::ProgressBar progress("convert", reader.size(), "scans");
  while (auto scan = reader.next()) {
    const auto name = fmt::format("{:06}.{}", stamps.size(), o.cloud_format);
    io::writeCloud((folder / name).string(), scan->cloud, writeOptions(o.encoding));
    stamps.push_back(scan->stamp);
    progress.update(stamps.size());
  }
  progress.finish();
  io::writeFileAtomic((folder / "times.txt").string(), [&](std::ostream& s) {
    for (double t : stamps) s << fmt::format("{:.9f}\n", t);
  });
  out.commit();
  fmt::print("{} scans of {} -> {}/\n", stamps.size(), o.topic, o.output);
}

std::string topicsWithCounts(const std::vector<io::BagTopic>& topics) {
  std::string list;
  for (const auto& t : topics) {
    list += fmt::format("{}{} ({}, {} messages)", list.empty() ? " " : ", ", t.name, t.type,
                        t.messages);
  }
  return list;
}

/// How a ROS1 bag or a ROS 2 bag (MCAP) is read.
struct BagReaders {
  std::vector<io::BagTopic> (*topics)(const std::string& path);
  core::Trajectory (*trajectory)(const std::string& path, const std::string& topic);
  void (*clouds)(const ConvertOptions& o);
};

constexpr BagReaders kRos1Bag{&io::listBagTopics, &io::readBagTrajectory,
                              &convertBagClouds<io::BagCloudReader>};
constexpr BagReaders kRos2Bag{&ros2::listMcapTopics, &ros2::readMcapTrajectory,
                              &convertBagClouds<ros2::McapCloudReader>};

void convertBag(const ConvertOptions& o, const BagReaders& bag) {
  const auto topics = bag.topics(o.input);
  if (o.topic.empty())
    throw core::Error("a bag input needs --topic; its topics:" + topicsWithCounts(topics));
  if (o.cloud_format != "bin" && o.cloud_format != "pcd" && o.cloud_format != "ply") {
    throw core::Error("--cloud-format: '" + o.cloud_format + "' is not bin, pcd or ply");
  }
  const auto it = std::find_if(topics.begin(), topics.end(), [&](const io::BagTopic& t) {
    return t.name == o.topic || t.name == "/" + o.topic || "/" + t.name == o.topic;
  });
  const bool cloud = it != topics.end() && (it->type == "sensor_msgs/PointCloud2" ||
                                            it->type == "sensor_msgs/msg/PointCloud2");
  if (cloud) return bag.clouds(o);
  const core::Trajectory trajectory = bag.trajectory(o.input, o.topic);
  const std::string to = o.to.empty() ? "tum" : o.to;
  io::writePoses(o.output, io::parsePoseFormat(to), trajectory, optionalPath(o.out_times));
  fmt::print("{} poses of {} -> {} ({})\n", trajectory.size(), o.topic, o.output, to);
}

void runConvert(const ConvertOptions& o) {
  if (extensionOf(o.input) == ".bag") return convertBag(o, kRos1Bag);
  if (extensionOf(o.input) == ".mcap") return convertBag(o, kRos2Bag);
  if (isCloudFile(o.input)) return convertCloud(o);
  convertPoses(o);
}

}  // namespace

void addConvertCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "convert",
      "convert scans (.bin .pcd .ply), pose files (--from/--to kitti|tum), or topics of ROS1 "
      "bags (.bag) and ROS 2 bags (.mcap)");
  auto o = std::make_shared<ConvertOptions>();
  cmd->add_option("input", o->input, "input file (scan, pose file, .bag or .mcap)")->required();
  cmd->add_option("output", o->output, "output file (or folder, for a bag's scans)")->required();
  cmd->add_option("--from", o->from, "pose format of the input: kitti or tum");
  cmd->add_option("--to", o->to, "pose format of the output: kitti or tum (bags: tum)");
  cmd->add_option("--topic", o->topic,
                  "bag topic: sensor_msgs/PointCloud2, nav_msgs/Odometry "
                  "or geometry_msgs/PoseStamped");
  cmd->add_option("--times", o->times, "times file of a KITTI pose input");
  cmd->add_option("--out-times", o->out_times, "times file to write with a KITTI pose output");
  cmd->add_option("--encoding", o->encoding, "PCD / PLY output: ascii or binary")
      ->capture_default_str();
  cmd->add_option("--cloud-format", o->cloud_format, "scan files from a bag: bin, pcd or ply")
      ->capture_default_str();
  addForceFlag(*cmd, o->force);
  cmd->callback([o] { runConvert(*o); });
}

}  // namespace dcl::apps
