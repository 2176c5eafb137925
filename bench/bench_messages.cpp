// The wire format (dcl::comm) on realistic content, one core: every message
// kind encoded and decoded, with its size as a counter (`bytes`; per estimate
// or pose in `bytes_per_item`). Content: a LiDAR-Iris descriptor and compact
// verification clouds of real KITTI 00 HDL-64 scans, a loop measurement from a
// real verification, KITTI 00 ground-truth poses as separator estimates.
// Targets (issue: communication): a loop measurement <= 100 B (the paper: 110 B),
// a separator pose estimate <= 30 B.
#include <cstdio>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include <dcl/comm/messages.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/place/descriptor_codec.hpp>
#include <dcl/place/lidar_iris.hpp>
#include <dcl/registration/cloud_codec.hpp>
#include <dcl/registration/verification.hpp>

namespace {

namespace comm = dcl::comm;
using dcl::core::KeyframeId;
using dcl::core::RobotId;

dcl::core::PointCloud kittiScan(int frame) {
  char name[16];
  std::snprintf(name, sizeof(name), "%06d.bin", frame);
  return dcl::io::readKittiScan(std::string(DCL_DATA_DIR) + "/lidar_scans/kitti_00/velodyne/" +
                                name);
}

comm::Header header(std::optional<RobotId> receiver) {
  comm::Header h;
  h.sender = RobotId(1);
  h.receiver = receiver;
  h.incarnation = 1'764'000'000;  // a start time in seconds, as robots over DDS use
  h.sequence = 1500;
  return h;
}

/// Keyframe poses a few hundred metres from the origin, 1.2 m and 0.6 deg apart.
std::vector<std::pair<KeyframeId, Eigen::Isometry3d>> separatorPoses(std::size_t count) {
  std::vector<std::pair<KeyframeId, Eigen::Isometry3d>> poses;
  Eigen::Isometry3d T = dcl::core::makePose(
      Eigen::Vector3d(312.4, -87.2, 2.1), Eigen::Quaterniond(0.93, 0.01, -0.02, 0.36).normalized());
  const Eigen::Isometry3d step =
      dcl::core::makePose(Eigen::Vector3d(1.2, 0.05, 0.01),
                          Eigen::Quaterniond(Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitZ())));
  for (std::size_t i = 0; i < count; ++i) {
    poses.emplace_back(KeyframeId(1200 + 3 * i), T);
    T = T * step;
  }
  return poses;
}

struct Sample {
  comm::Message message;
  std::size_t items = 1;  ///< estimates or poses it carries
};

/// One message of every kind, as a robot would send it.
const std::vector<Sample>& samples() {
  static const std::vector<Sample> all = [] {
    const dcl::core::PointCloud scan = kittiScan(0);
    const std::vector<std::uint8_t> descriptor =
        dcl::place::encodeIris(dcl::place::describeIris(scan));
    const std::vector<std::uint8_t> cloud = dcl::registration::encodeVerificationCloud(scan);
    const auto verification = dcl::registration::verifyLoop(kittiScan(1), 0.0, scan);
    if (!verification.accepted) throw dcl::core::Error("bench: the KITTI pair did not verify");
    const auto poses = separatorPoses(50);
    // A member of a group of three, in the middle of stage 1.
    const comm::DgsState state{4,     comm::OptimisationStage::rotation,
                               17,    true,
                               false, false,
                               0.08F, {{RobotId(0), 17, 15, false}, {RobotId(2), 16, -1, false}}};
    comm::RotationEstimates rotations{state, {}};
    for (const auto& [id, T] : poses) rotations.rotations.emplace_back(id, T.rotation());
    comm::Heartbeat heartbeat{812.5, 640, {}};
    for (std::uint8_t r = 0; r < 2; ++r)
      heartbeat.acks.push_back({RobotId(r), 1'764'000'000, 600, 40});
    std::vector<std::uint8_t> map = dcl::registration::encodeVerificationCloud(
        scan, dcl::registration::CloudCodecConfig{.voxel_size = 1.0});
    return std::vector<Sample>{
        {{header(std::nullopt), heartbeat}},
        {{header(std::nullopt),
          comm::DescriptorMessage{KeyframeId(1204), 812.4, descriptor, std::nullopt, 0.31F, {}}}},
        {{header(RobotId(2)),
          comm::LoopCandidate{KeyframeId(1204), KeyframeId(377), -2.9F, 0.24F, cloud}}},
        {{header(RobotId(2)),
          comm::LoopMeasurement{KeyframeId(1204), KeyframeId(377), comm::LoopStatus::verified,
                                verification.T_candidate_query, verification.covariance}}},
        {{header(RobotId(2)), state}},
        {{header(RobotId(2)), rotations}, poses.size()},
        {{header(RobotId(2)), comm::PoseEstimates{state, poses, false, false}}, poses.size()},
        {{header(RobotId(2)), comm::SummaryRequest{comm::SummaryKind::trajectory}}},
        {{header(RobotId(2)), comm::TrajectorySummary{separatorPoses(1000)}}, 1000},
        {{header(RobotId(2)), comm::MapSummary{1, map}}},
    };
  }();
  return all;
}

void setCounters(benchmark::State& state, const Sample& sample, std::size_t bytes) {
  state.SetLabel(std::string(comm::name(sample.message.kind())));
  state.counters["bytes"] = static_cast<double>(bytes);
  state.counters["bytes_per_item"] = static_cast<double>(bytes) / static_cast<double>(sample.items);
}

void BM_EncodeMessage(benchmark::State& state) {
  const Sample& sample = samples()[static_cast<std::size_t>(state.range(0))];
  std::size_t bytes = 0;
  for (auto _ : state) {
    const std::vector<std::uint8_t> wire = comm::encode(sample.message);
    bytes = wire.size();
    benchmark::DoNotOptimize(wire.data());
  }
  setCounters(state, sample, bytes);
}
BENCHMARK(BM_EncodeMessage)->DenseRange(0, comm::kMessageKinds - 1)->Unit(benchmark::kMicrosecond);

void BM_DecodeMessage(benchmark::State& state) {
  const Sample& sample = samples()[static_cast<std::size_t>(state.range(0))];
  const std::vector<std::uint8_t> wire = comm::encode(sample.message);
  for (auto _ : state) {
    const comm::Decoded decoded = comm::decode(wire);
    if (!decoded.message) state.SkipWithError(decoded.detail.c_str());
    benchmark::DoNotOptimize(decoded.message);
  }
  setCounters(state, sample, wire.size());
}
BENCHMARK(BM_DecodeMessage)->DenseRange(0, comm::kMessageKinds - 1)->Unit(benchmark::kMicrosecond);

}  // namespace
