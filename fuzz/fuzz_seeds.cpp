// Writes the fuzzers' seed corpora: every message kind with realistic values,
// and a real KITTI descriptor and verification cloud, so that fuzzing starts
// from inputs that reach deep into each decoder.
// Usage: fuzz_seeds DIR   (writes DIR/message, DIR/descriptor, DIR/cloud, DIR/bag)
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <dcl/comm/messages.hpp>
#include <dcl/io/bag_writer.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/place/descriptor_codec.hpp>
#include <dcl/place/lidar_iris.hpp>
#include <dcl/registration/cloud_codec.hpp>

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
  std::uint64_t sequence = 1;
  for (const comm::Body& body : bodies(descriptor, small_cloud)) {
    const comm::Message m{header(sequence), body};
    write(dir / "message", std::string(comm::name(m.kind())) + "_" + std::to_string(sequence),
          comm::encode(m));
    ++sequence;
  }
  // A bag as dcl-slam exports one: a few points of the scan, and odometry.
  dcl::io::BagWriter bag((dir / "bag" / "export.bag").string());
  dcl::core::PointCloud few;
  for (std::size_t i = 0; i < scan.size(); i += scan.size() / 16) {
    few.points.push_back(scan.points[i]);
    few.intensity.push_back(scan.intensity.empty() ? 0.0F : scan.intensity[i]);
  }
  for (int k = 0; k < 2; ++k) {
    bag.writeCloud("/points", 100.0 + k, few, "lidar");
    bag.writeOdometry("/odom", 100.0 + k,
                      dcl::core::makePose(Eigen::Vector3d(k, 0, 0), Eigen::Quaterniond::Identity()),
                      "odom", "base_link");
  }
  bag.close();
  std::filesystem::copy_file(std::string(DCL_DATA_DIR) + "/rosbags/evo_tf_example.bag",
                             dir / "bag" / "evo_tf_example.bag",
                             std::filesystem::copy_options::overwrite_existing);
  std::printf("seeds written to %s\n", dir.c_str());
  return 0;
}
