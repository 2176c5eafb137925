// Writes the fuzzers' seed corpora: every message kind with realistic values,
// a real KITTI descriptor and verification cloud, and small pieces of real
// files (bags, pose-graph benchmarks, KITTI and TUM trajectories, KITTI scans,
// PCD and PLY clouds through our writers), the program's `config --dump` and
// dataset.yaml as the simulator writes it, so that fuzzing starts from inputs
// that reach deep into each decoder and reader.
// Usage: fuzz_seeds DIR   (writes DIR/<target> for every target)
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include <dcl/comm/messages.hpp>
#include <dcl/io/bag_writer.hpp>
#include <dcl/io/config.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/io/pcd.hpp>
#include <dcl/io/ply.hpp>
#include <dcl/place/descriptor_codec.hpp>
#include <dcl/place/lidar_iris.hpp>
#include <dcl/registration/cloud_codec.hpp>
#include <dcl/ros/ros1_messages.hpp>
#include <dcl/ros/ros2_bag.hpp>
#include <dcl/ros/ros2_messages.hpp>

#include "app_config.hpp"

namespace {

namespace comm = dcl::comm;
using dcl::core::KeyframeId;
using dcl::core::RobotId;

void write(const std::filesystem::path& dir, const std::string& name,
           const std::vector<std::uint8_t>& bytes) {
  std::filesystem::create_directories(dir);
  std::ofstream(dir / name, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
}

void write(const std::filesystem::path& dir, const std::string& name, const std::string& bytes) {
  write(dir, name, std::vector<std::uint8_t>(bytes.begin(), bytes.end()));
}

std::string dataPath(const std::string& relative) {
  return std::string(DCL_DATA_DIR) + "/" + relative;
}

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// The first `head` and the last `tail` lines of a text file: small seeds that
/// still hold what files keep for their end (TORO's EQUIV lines).
std::string headAndTail(const std::string& path, std::size_t head, std::size_t tail = 0) {
  std::vector<std::string> lines;
  std::istringstream in(readText(path));
  for (std::string line; std::getline(in, line);) lines.push_back(line + "\n");
  std::string out;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (i < head || i + tail >= lines.size()) out += lines[i];
  }
  return out;
}

/// Pieces of the pose-graph benchmarks, one per tag family and id scheme.
void writeGraphSeeds(const std::filesystem::path& dir) {
  const std::vector<std::string> graphs = {
      "3d/tinyGrid3D.g2o",                    // VERTEX_SE3:QUAT, EDGE_SE3:QUAT
      "3d/gtsam_pose3example.g2o",            //
      "3d/sphere_smallnoise.graph",           // VERTEX3, EDGE3 without information
      "3d/sphere2500_groundtruth.graph",      // EDGE3 with information, no vertices
      "2d/intel.g2o",                         // VERTEX_SE2, EDGE_SE2
      "2d/kitti_00.g2o",                      // EDGE_SE2 only: chained
      "2d/w100.graph",                        // VERTEX2, EDGE2, EQUIV
      "2d/gtsam_noisyToyGraph.g2o",           //
      "multi_robot/kimera_rpgo/ordered.g2o",  // plain ids and 'u' symbols
      "multi_robot/distributed_mapper/example_2robots/0.g2o",  // a robot's file
      "multi_robot_outliers/robust_distributed_mapper/pairwise_consistency_maximization/"
      "spoiled/simulation/example_2robots/1.g2o",  // a damaged line 16
  };
  for (const std::string& graph : graphs) {
    std::string name = graph;
    std::replace(name.begin(), name.end(), '/', '_');
    write(dir, name, headAndTail(dataPath("pose_graphs/" + graph), 30, 5));
  }
}

void writePoseSeeds(const std::filesystem::path& dir) {
  write(dir, "kitti_00_gt", headAndTail(dataPath("trajectories/evo/KITTI_00_gt.txt"), 20));
  write(dir, "kitti_00_times", headAndTail(dataPath("trajectories/evo/KITTI_00_gt_times.txt"), 20));
  write(dir, "freiburg1_xyz",
        headAndTail(dataPath("trajectories/evo/freiburg1_xyz-groundtruth.txt"), 20));
  write(dir, "kitti_00_calib", readText(dataPath("lidar_scans/kitti_00/calib.txt")));
}

/// The first `n` points of `cloud`, with its channels.
dcl::core::PointCloud firstPoints(const dcl::core::PointCloud& cloud, std::size_t n) {
  dcl::core::PointCloud out;
  for (std::size_t i = 0; i < n && i < cloud.size(); ++i) {
    out.points.push_back(cloud.points[i]);
    if (cloud.hasIntensity()) out.intensity.push_back(cloud.intensity[i]);
    if (cloud.hasTime()) out.time.push_back(cloud.time[i]);
    if (cloud.hasRing()) out.ring.push_back(cloud.ring[i]);
  }
  return out;
}

/// Real points with every channel: a KITTI scan's, with a firing time and a ring.
dcl::core::PointCloud everyChannel(const dcl::core::PointCloud& scan) {
  dcl::core::PointCloud cloud = firstPoints(scan, 40);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    cloud.time.push_back(static_cast<float>(i) * 1e-3F);
    cloud.ring.push_back(static_cast<std::uint16_t>(i % 64));
  }
  return cloud;
}

void writeCloudFileSeeds(const std::filesystem::path& dir, const dcl::core::PointCloud& scan) {
  namespace io = dcl::io;
  std::filesystem::create_directories(dir / "pcd");
  std::filesystem::create_directories(dir / "ply");
  const dcl::core::PointCloud full = everyChannel(scan);
  const dcl::core::PointCloud pcd = firstPoints(
      io::readPcd(dataPath("lidar_scans/hdl_outdoor_pair_fast_gicp/251370668.pcd")), 40);
  const dcl::core::PointCloud ply =
      firstPoints(io::readPly(dataPath("lidar_scans/small_gicp_pair/target.ply")), 40);
  for (const auto& [name, encoding] : {std::pair{"ascii", io::PcdEncoding::kAscii},
                                       {"binary", io::PcdEncoding::kBinary},
                                       {"compressed", io::PcdEncoding::kBinaryCompressed}}) {
    io::writePcd((dir / "pcd" / (std::string("kitti_") + name)).string(), full, {encoding});
    io::writePcd((dir / "pcd" / (std::string("hdl_") + name)).string(), pcd, {encoding});
  }
  const std::vector<Eigen::Vector3f> points(ply.points.begin(), ply.points.end());
  const std::vector<dcl::io::Rgb> colours(points.size(), dcl::io::Rgb{200, 30, 90});
  for (const auto& [name, encoding] : {std::pair{"ascii", io::PlyEncoding::kAscii},
                                       {"binary", io::PlyEncoding::kBinaryLittleEndian}}) {
    io::writePly((dir / "ply" / (std::string("kitti_") + name)).string(), full, {encoding});
    io::writePly((dir / "ply" / (std::string("small_gicp_") + name)).string(), ply, {encoding});
    io::writeColouredPly((dir / "ply" / (std::string("coloured_") + name)).string(), points,
                         colours, {encoding});
  }
  // Big-endian doubles and a face element with a list, which the reader skips.
  std::string big_endian =
      "ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty double x\n"
      "property double y\nproperty double z\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n";
  big_endian += std::string("\x3f\xf0\0\0\0\0\0\0\x40\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0", 24);
  big_endian += std::string("\x01\0\0\0\0", 5);
  write(dir / "ply", "big_endian_with_faces", big_endian);
}

/// The first 64 points of real scans, as KITTI stores them.
void writeKittiScanSeeds(const std::filesystem::path& dir) {
  for (const char* frame : {"000000", "000094", "000198"}) {
    const std::string bytes =
        readText(dataPath(std::string("lidar_scans/kitti_00/velodyne/") + frame + ".bin"));
    write(dir, frame, bytes.substr(0, 64 * dcl::io::kKittiRecordBytes));
  }
}

comm::Header header(std::uint64_t sequence) {
  comm::Header h;
  h.sender = RobotId(1);
  h.receiver = RobotId(2);
  h.incarnation = 1;
  h.sequence = sequence;
  return h;
}

std::vector<comm::Body> bodies(const std::vector<std::uint8_t>& descriptor,
                               const std::vector<std::uint8_t>& cloud) {
  Eigen::Isometry3d T = dcl::core::makePose(Eigen::Vector3d(12.0, -3.5, 0.25),
                                            Eigen::Quaterniond(0.9, 0.1, -0.3, 0.2).normalized());
  comm::LoopMeasurement loop{KeyframeId(4), KeyframeId(90), comm::LoopStatus::verified, T,
                             dcl::core::Matrix6d::Identity() * 1e-4};
  loop.covariance(0, 1) = loop.covariance(1, 0) = 3e-5;
  const comm::DgsState state{3,          comm::OptimisationStage::pose,
                             7,          true,
                             false,      false,
                             0.05F,      {{RobotId(0), 7, 5, false}, {RobotId(1), 6, -1, false}},
                             RobotId(0), false};
  comm::PoseEstimates poses{state, {{KeyframeId(5), T}}, false, false};
  comm::DgsState refine = state;
  refine.stage = comm::OptimisationStage::refine;
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
  step.translation() = Eigen::Vector3d(2e-5, -1e-6, 3e-6);
  comm::PoseEstimates increments{refine, {{KeyframeId(5), step}, {KeyframeId(6), T}}, false, true};
  comm::RotationEstimates rotations{state, {{KeyframeId(5), T.rotation()}}};
  return {
      comm::Heartbeat{2.5, 40, {{RobotId(0), 1, 12, 3}}},
      comm::DescriptorMessage{KeyframeId(4),
                              3.0,
                              descriptor,
                              comm::OdometryStep{KeyframeId(3), T, loop.covariance},
                              0.27F,
                              {{KeyframeId(1), 0.27F}, {KeyframeId(2), 0.3F}}},
      comm::LoopCandidate{KeyframeId(4), KeyframeId(90), 1.2F, 0.18F, cloud},
      loop,
      comm::LoopMeasurement{KeyframeId(4), KeyframeId(91), comm::LoopStatus::degenerate},
      [] {
        comm::LoopMeasurement notice{KeyframeId(4), KeyframeId(91), comm::LoopStatus::unexplained};
        notice.round = 1026;
        return notice;
      }(),
      state,
      rotations,
      poses,
      increments,
      comm::SummaryRequest{comm::SummaryKind::map},
      comm::TrajectorySummary{poses.poses},
      comm::MapSummary{12, cloud}};
}

/// The config target's seeds: the program's `config --dump`, and dataset.yaml
/// as the simulator writes it (a preset) and as its exports do (KITTI, bags).
/// The dump is also cut into its top-level sections, one seed each: a mutation
/// of a short seed parses many times faster than one of the whole dump.
void writeConfigSeeds(const std::filesystem::path& dir) {
  const std::string dump = dcl::io::dumpConfig(dcl::apps::AppConfig{});
  write(dir, "dump.yaml", dump);
  std::vector<std::string> lines;
  std::istringstream in(dump);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  // A section starts at the comments right above its top-level key.
  std::vector<std::size_t> starts;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (lines[i].empty() || lines[i][0] == ' ' || lines[i][0] == '#') continue;
    std::size_t start = i;
    while (start > 0 && !lines[start - 1].empty() && lines[start - 1][0] == '#') --start;
    starts.push_back(start);
  }
  for (std::size_t s = 0; s < starts.size(); ++s) {
    const std::size_t end = s + 1 < starts.size() ? starts[s + 1] : lines.size();
    std::string text, key;
    for (std::size_t i = starts[s]; i < end; ++i) {
      if (key.empty() && lines[i][0] != '#') key = lines[i].substr(0, lines[i].find(':'));
      text += lines[i] + "\n";
    }
    write(dir, "section_" + key + ".yaml", text);
  }
  write(dir, "overrides.yaml",
        "odometry: {max_range: 80, min_range: 3}\nplace:\n  descriptor:\n    kind: scancontext\n");
  dcl::io::DatasetSpec spec;
  spec.name = "kitti05-3";
  spec.description = "KITTI 05 split in three robots in a generated city";
  spec.sim = dcl::io::SimSpec{.world = dcl::io::WorldKind::city, .seed = 3, .shared_unit = true};
  for (const std::string name : {"a", "b", "c"}) {
    spec.robots.push_back(
        {.name = name, .ground_truth = "ground_truth/" + name + ".tum", .start_time = 0.0});
  }
  write(dir, "dataset_sim.yaml", dcl::io::datasetYaml(spec));
  spec.sim.reset();
  spec.sensor = "vlp16";
  spec.mount_height = 0.8;
  spec.robots[0].scans = {
      .type = dcl::io::ScanSourceType::kitti, .folder = "a/velodyne", .times = "a/times.txt"};
  spec.robots[1].scans = {
      .type = dcl::io::ScanSourceType::bag, .file = "b/b.bag", .topic = "/points"};
  spec.robots[2].start_time = 12.5;
  write(dir, "dataset_export.yaml", dcl::io::datasetYaml(spec));
}

/// About `n` points of `scan`, evenly through it, with their intensities.
dcl::core::PointCloud fewPoints(const dcl::core::PointCloud& scan, std::size_t n) {
  dcl::core::PointCloud few;
  for (std::size_t i = 0; i < scan.size(); i += scan.size() / n) {
    few.points.push_back(scan.points[i]);
    few.intensity.push_back(scan.intensity.empty() ? 0.0F : scan.intensity[i]);
  }
  return few;
}

/// The ROS 2 target's seeds: a scan as a driver publishes it, and each message a robot publishes.
void writeRos2Seeds(const std::filesystem::path& dir, const dcl::core::PointCloud& scan) {
  using namespace dcl::ros2;
  const dcl::core::PointCloud few = fewPoints(scan, 64);
  write(dir, "cloud.cdr", encode(toPointCloud2(few, {100.5, "velodyne"})));
  Odometry odometry;
  odometry.header = {100.5, "odom"};
  odometry.child_frame_id = "base_link";
  odometry.pose.translation() = Eigen::Vector3d(1, 2, 3);
  write(dir, "odometry.cdr", encode(odometry));
  write(dir, "imu.cdr",
        encode(dcl::msg::imuOfUp(Eigen::Vector3d(0.01, 0.02, 1.0), 1e-6, {100.5, "imu"})));
  Path path;
  path.header = {100.5, "map"};
  path.poses = {{{100.0, "map"}, odometry.pose}, {{100.5, "map"}, odometry.pose}};
  write(dir, "path.cdr", encode(path));
  TFMessage tf;
  tf.transforms = {{{100.5, "map"}, "odom", odometry.pose}};
  write(dir, "tf.cdr", encode(tf));
  Marker loops;
  loops.header = {100.5, "map"};
  loops.ns = "loops";
  loops.points = {{0, 0, 0}, {1, 1, 0}};
  loops.colors = {{1, 0, 0, 1}, {0, 1, 0, 1}};
  MarkerArray markers;
  markers.markers = {loops};
  write(dir, "markers.cdr", encode(markers));
}

/// The MCAP target's seeds: small ROS 2 bags as dcl-slam writes them (a few
/// points, odometry and poses), in each compression, unchunked and without summary.
void writeMcapSeeds(const std::filesystem::path& dir, const dcl::core::PointCloud& few) {
  using dcl::io::McapCompression;
  struct Seed {
    const char* name;
    dcl::io::McapWriteOptions options;
  };
  for (const Seed& seed :
       {Seed{"zstd.mcap", {.chunk_size = 512}},
        Seed{"lz4.mcap", {.compression = McapCompression::lz4, .chunk_size = 512}},
        Seed{"none.mcap", {.compression = McapCompression::none, .chunk_size = 512}},
        Seed{"unchunked.mcap", {.chunked = false}},
        Seed{"no_summary.mcap", {.compression = McapCompression::none, .summary = false}}}) {
    dcl::ros2::McapBagWriter bag((dir / seed.name).string(), seed.options);
    for (int k = 0; k < 2; ++k) {
      const Eigen::Isometry3d T =
          dcl::core::makePose(Eigen::Vector3d(k, 0, 0), Eigen::Quaterniond::Identity());
      bag.writeCloud("/points", 100.0 + k, few, "lidar");
      bag.writeOdometry("/odom", 100.0 + k, T, "odom", "base_link");
      bag.writePose("/pose", 100.5 + k, T, "map");
      bag.writeImu("/imu",
                   dcl::msg::imuOfUp(Eigen::Vector3d(0.01, 0.02, 1.0), 1e-6, {100.0 + k, "imu"}));
    }
    bag.close();
  }
}

/// The ROS 1 target's seeds: a scan as a driver publishes it, and each message a robot publishes.
void writeRos1Seeds(const std::filesystem::path& dir, const dcl::core::PointCloud& scan) {
  namespace ros1 = dcl::ros1;
  namespace msg = dcl::msg;
  const dcl::core::PointCloud few = fewPoints(scan, 64);
  write(dir, "cloud.ros1", ros1::encode(msg::toPointCloud2(few, {100.5, "velodyne"}), 7));
  msg::Odometry odometry;
  odometry.header = {100.5, "odom"};
  odometry.child_frame_id = "base_link";
  odometry.pose.translation() = Eigen::Vector3d(1, 2, 3);
  write(dir, "odometry.ros1", ros1::encode(odometry, 7));
  write(dir, "imu.ros1",
        ros1::encode(msg::imuOfUp(Eigen::Vector3d(0.01, 0.02, 1.0), 1e-6, {100.5, "imu"}), 7));
  const msg::PoseStamped pose{{100.5, "map"}, odometry.pose};
  write(dir, "pose.ros1", ros1::encode(pose, 7));
  msg::Path path;
  path.header = {100.5, "map"};
  path.poses = {{{100.0, "map"}, odometry.pose}, pose};
  write(dir, "path.ros1", ros1::encode(path, 7));
  msg::TFMessage tf;
  tf.transforms = {{{100.5, "map"}, "odom", odometry.pose}};
  write(dir, "tf.ros1", ros1::encode(tf));
  msg::Marker loops;
  loops.header = {100.5, "map"};
  loops.ns = "loops";
  loops.lifetime = 1.5;
  loops.points = {{0, 0, 0}, {1, 1, 0}};
  loops.colors = {{1, 0, 0, 1}, {0, 1, 0, 1}};
  loops.text = "a-b";
  msg::MarkerArray markers;
  markers.markers = {loops};
  write(dir, "markers.ros1", ros1::encode(markers));
}

/// Every message kind of the swarm's wire format, encoded.
void writeMessageSeeds(const std::filesystem::path& dir,
                       const std::vector<std::uint8_t>& descriptor,
                       const std::vector<std::uint8_t>& small_cloud) {
  std::uint64_t sequence = 1;
  for (const comm::Body& body : bodies(descriptor, small_cloud)) {
    const comm::Message m{header(sequence), body};
    write(dir, std::string(comm::name(m.kind())) + "_" + std::to_string(sequence), comm::encode(m));
    ++sequence;
  }
}

/// A bag as dcl-slam exports one (a few points of the scan, IMU readings and
/// odometry), and a real one of tf messages.
void writeBagSeeds(const std::filesystem::path& dir, const dcl::core::PointCloud& few) {
  dcl::io::BagWriter bag((dir / "export.bag").string());
  for (int k = 0; k < 2; ++k) {
    bag.writeCloud("/points", 100.0 + k, few, "lidar");
    bag.writeOdometry("/odom", 100.0 + k,
                      dcl::core::makePose(Eigen::Vector3d(k, 0, 0), Eigen::Quaterniond::Identity()),
                      "odom", "base_link");
    const dcl::ros1::MessageType& imu = dcl::ros1::messageType<dcl::msg::Imu>();
    bag.writeSerialised("/imu", 100.0 + k, imu.name, imu.md5sum, imu.definition,
                        dcl::ros1::encode(dcl::msg::imuOfUp(Eigen::Vector3d(0.01, 0.02, 1.0), 1e-6,
                                                            {100.0 + k, "imu"})));
  }
  bag.close();
  std::filesystem::copy_file(std::string(DCL_DATA_DIR) + "/rosbags/evo_tf_example.bag",
                             dir / "evo_tf_example.bag",
                             std::filesystem::copy_options::overwrite_existing);
}

/// What Foxglove Studio sends a server it watches.
void writeVizSeeds(const std::filesystem::path& dir) {
  write(
      dir, "subscribe.json",
      std::string(
          R"({"op":"subscribe","subscriptions":[{"id":0,"channelId":1},{"id":1,"channelId":4}]})"));
  write(dir, "unsubscribe.json", std::string(R"({"op":"unsubscribe","subscriptionIds":[0,1]})"));
  write(dir, "other.json", std::string(R"({"op":"getParameters","parameterNames":[],"id":"x"})"));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_seeds DIR\n");
    return 2;
  }
  const std::filesystem::path dir = argv[1];
  const dcl::core::PointCloud scan = dcl::io::readKittiScan(
      std::string(DCL_DATA_DIR) + "/lidar_scans/kitti_00/velodyne/000000.bin");
  const std::vector<std::uint8_t> descriptor =
      dcl::place::encodeIris(dcl::place::describeIris(scan));
  dcl::registration::CloudCodecConfig coarse;
  coarse.voxel_size = 3.0;
  const std::vector<std::uint8_t> small_cloud =
      dcl::registration::encodeVerificationCloud(scan, coarse);
  write(dir / "descriptor", "kitti_00_000000", descriptor);
  write(dir / "cloud", "kitti_00_000000", dcl::registration::encodeVerificationCloud(scan));
  write(dir / "cloud", "kitti_00_000000_coarse", small_cloud);
  writeGraphSeeds(dir / "g2o");
  writePoseSeeds(dir / "poses");
  writeCloudFileSeeds(dir, scan);
  writeKittiScanSeeds(dir / "kitti_scan");
  writeMessageSeeds(dir / "message", descriptor, small_cloud);
  const dcl::core::PointCloud few = fewPoints(scan, 16);
  writeBagSeeds(dir / "bag", few);
  writeConfigSeeds(dir / "config");
  writeRos2Seeds(dir / "ros2", scan);
  writeRos1Seeds(dir / "ros1", scan);
  writeMcapSeeds(dir / "mcap", few);
  writeVizSeeds(dir / "viz");
  std::printf("seeds written to %s\n", dir.c_str());
  return 0;
}
