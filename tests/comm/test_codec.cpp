#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <tuple>
#include <variant>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/comm/messages.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/place/descriptor_codec.hpp>
#include <dcl/place/lidar_iris.hpp>
#include <dcl/registration/cloud_codec.hpp>
#include <dcl/registration/verification.hpp>

#include "../common/keys.hpp"
#include "../common/kitti_test_data.hpp"

namespace dcl::comm {
namespace {

using dcl::test::robot;

core::KeyframeId keyframe(std::uint64_t id) {
  return core::KeyframeId(id);
}

Header header(int sender, std::optional<int> receiver, std::uint64_t sequence = 17) {
  Header h;
  h.sender = robot(sender);
  if (receiver) h.receiver = robot(*receiver);
  h.incarnation = 3;
  h.sequence = sequence;
  return h;
}

/// Encodes, decodes, and checks the header came back; returns the body.
template <class T>
T roundTrip(const Header& h, const T& body, std::size_t* bytes = nullptr) {
  const std::vector<std::uint8_t> wire = encode({h, body});
  if (bytes != nullptr) *bytes = wire.size();
  const Decoded d = decode(wire);
  EXPECT_TRUE(d.message.has_value()) << name(d.reason) << ": " << d.detail;
  if (!d.message) return {};
  EXPECT_EQ(d.message->header.sender, h.sender);
  EXPECT_EQ(d.message->header.receiver, h.receiver);
  EXPECT_EQ(d.message->header.incarnation, h.incarnation);
  EXPECT_EQ(d.message->header.sequence, h.sequence);
  EXPECT_EQ(d.message->header.version, kSchemaVersion);
  EXPECT_TRUE(std::holds_alternative<T>(d.message->body));
  return std::get<T>(d.message->body);
}

double rotationError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return core::rotationAngle(a.rotation().transpose() * b.rotation());
}

/// A real loop measurement: KITTI 00 frame 1 verified against frame 0.
const registration::VerificationResult& realVerification() {
  static const registration::VerificationResult result =
      registration::verifyLoop(test::kittiScan(1), 0.0, test::kittiScan(0));
  return result;
}

TEST(Codec, DescriptorRoundTripsAndDescribesTheSameOnReceipt) {
  const place::IrisDescriptor sent = place::describeIris(test::kittiScan(0));
  DescriptorMessage m{keyframe(42), 12.5, place::encodeIris(sent), std::nullopt, 0.2734F, {}};
  m.odometry = OdometryStep{keyframe(41), test::kittiRelative(0, 5), realVerification().covariance};
  std::size_t bytes = 0;
  const DescriptorMessage got = roundTrip(header(1, std::nullopt), m, &bytes);
  EXPECT_EQ(got.keyframe, m.keyframe);
  EXPECT_EQ(got.stamp, m.stamp);
  EXPECT_EQ(got.descriptor, m.descriptor);
  const place::IrisDescriptor received = place::decodeIris(got.descriptor);
  EXPECT_EQ(received.image.cells, sent.image.cells);
  EXPECT_EQ(received.features, sent.features);
  ASSERT_TRUE(got.odometry);
  EXPECT_EQ(got.odometry->previous, keyframe(41));
  EXPECT_LT((got.odometry->T_previous_keyframe.translation() -
             m.odometry->T_previous_keyframe.translation())
                .norm(),
            1e-5);
  EXPECT_NEAR(got.odometry->covariance(0, 0) / m.odometry->covariance(0, 0), 1.0, 1e-3);
  ASSERT_TRUE(got.look_alike);
  EXPECT_NEAR(*got.look_alike, 0.2734F, 1e-4F);
  // The envelope and the odometry step (ids, a pose and a covariance record)
  // add under a hundred bytes to the codec's.
  EXPECT_LE(bytes, m.descriptor.size() + 100);
  m.odometry.reset();
  m.look_alike.reset();
  const DescriptorMessage bare = roundTrip(header(1, std::nullopt), m);
  EXPECT_FALSE(bare.odometry);
  EXPECT_FALSE(bare.look_alike);
  m.look_alike = 1.5F;
  EXPECT_THROW((void)encode({header(1, std::nullopt), m}), core::Error);
}

TEST(Codec, DescriptorCarriesThePlacesItResembles) {
  DescriptorMessage m{keyframe(300), 90.0, {1, 2, 3, 4}, std::nullopt, 0.2F, {}};
  m.resembles = {{keyframe(12), 0.2F}, {keyframe(13), 0.31F}, {keyframe(140), 0.0F}};
  std::size_t with = 0;
  const DescriptorMessage got = roundTrip(header(2, std::nullopt), m, &with);
  ASSERT_EQ(got.resembles.size(), 3U);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(got.resembles[i].keyframe, m.resembles[i].keyframe);
    EXPECT_NEAR(got.resembles[i].distance, m.resembles[i].distance, 1e-4F);
  }
  // What the receiver reads is what the sender keeps (asDelivered): both judge alike.
  const auto delivered = std::get<DescriptorMessage>(asDelivered(m));
  for (std::size_t i = 0; i < 3; ++i)
    EXPECT_EQ(delivered.resembles[i].distance, got.resembles[i].distance);
  // Three repeats cost a few bytes each: a keyframe varint and a 16-bit distance.
  m.resembles.clear();
  std::size_t without = 0;
  (void)roundTrip(header(2, std::nullopt), m, &without);
  EXPECT_LE(with, without + 3 * 6);
  m.resembles.assign(kMaxResemblances + 1, {keyframe(1), 0.1F});
  EXPECT_THROW((void)encode({header(2, std::nullopt), m}), core::Error);
  m.resembles = {{keyframe(1), -0.1F}};
  EXPECT_THROW((void)encode({header(2, std::nullopt), m}), core::Error);
}

TEST(Codec, LoopCandidateCarriesTheCompactCloud) {
  const core::PointCloud scan = test::kittiScan(94);
  LoopCandidate m{keyframe(94), keyframe(3), -2.75F, 0.21F,
                  registration::encodeVerificationCloud(scan)};
  const LoopCandidate got = roundTrip(header(0, 2), m);
  EXPECT_EQ(got.query, m.query);
  EXPECT_EQ(got.match, m.match);
  EXPECT_EQ(got.yaw, m.yaw);
  EXPECT_EQ(got.distance, m.distance);
  EXPECT_EQ(got.cloud, m.cloud);
  EXPECT_GT(registration::decodeVerificationCloud(got.cloud).size(), 5000u);
}

TEST(Codec, LoopMeasurementIsUnder100BytesAndKeepsPoseAndCovariance) {
  const registration::VerificationResult& v = realVerification();
  ASSERT_TRUE(v.accepted);
  LoopMeasurement m;
  m.query = keyframe(1204);
  m.match = keyframe(377);
  m.T_match_query = v.T_candidate_query;
  m.covariance = v.covariance;
  std::size_t bytes = 0;
  const LoopMeasurement got = roundTrip(header(2, 0, 40000), m, &bytes);
  EXPECT_LE(bytes, 100u) << "issue target (the paper: 110 B)";
  EXPECT_EQ(got.status, LoopStatus::verified);
  EXPECT_EQ(got.query, m.query);
  EXPECT_EQ(got.match, m.match);
  EXPECT_LT((got.T_match_query.translation() - m.T_match_query.translation()).norm(), 1e-5);
  EXPECT_LT(rotationError(got.T_match_query, m.T_match_query), 1e-4);
  // Standard deviations within 0.05 %, correlations within 5e-5.
  for (int i = 0; i < 6; ++i) {
    const double sigma = std::sqrt(m.covariance(i, i));
    EXPECT_NEAR(std::sqrt(got.covariance(i, i)) / sigma, 1.0, 5e-4) << i;
    for (int j = i + 1; j < 6; ++j) {
      const double rho = m.covariance(i, j) / (sigma * std::sqrt(m.covariance(j, j)));
      const double rho_got =
          got.covariance(i, j) / std::sqrt(got.covariance(i, i) * got.covariance(j, j));
      EXPECT_NEAR(rho_got, rho, 5e-5) << i << "," << j;
    }
  }
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<core::Matrix6d>(got.covariance).eigenvalues().minCoeff(),
            0.0);
}

TEST(Codec, ARefusedCandidateAnswersWithItsReasonAlone) {
  LoopMeasurement m;
  m.query = keyframe(5);
  m.match = keyframe(9);
  m.status = LoopStatus::low_inlier_share;
  std::size_t bytes = 0;
  const LoopMeasurement got = roundTrip(header(1, 0), m, &bytes);
  EXPECT_EQ(got.status, LoopStatus::low_inlier_share);
  EXPECT_LE(bytes, 24u);
}

TEST(Codec, AnUnexplainedLoopNoticeCarriesItsRound) {
  LoopMeasurement m;
  m.query = keyframe(5);
  m.match = keyframe(9);
  m.status = LoopStatus::unexplained;
  m.round = 1026;
  const LoopMeasurement got = roundTrip(header(1, 0), m);
  EXPECT_EQ(got.status, LoopStatus::unexplained);
  EXPECT_EQ(got.round, 1026u);
  m.status = LoopStatus::degenerate;  // an answer: no round on the wire
  EXPECT_EQ(roundTrip(header(1, 0), m).round, 0u);
}

TEST(Codec, ARepeatedPlaceNoticeNamesTheLoopAlone) {
  LoopMeasurement m;
  m.query = keyframe(12);
  m.match = keyframe(107);
  m.status = LoopStatus::repeated;
  std::size_t bytes = 0;
  const LoopMeasurement got = roundTrip(header(2, 0), m, &bytes);
  EXPECT_EQ(got.status, LoopStatus::repeated);
  EXPECT_EQ(got.query, m.query);
  EXPECT_EQ(got.match, m.match);
  EXPECT_LE(bytes, 24u);
}

TEST(Codec, SeparatorPosesAreUnder30BytesEachOnRealTrajectories) {
  // 200 KITTI 00 poses as separator estimates of a robot whose keyframes count from 3000.
  PoseEstimates m;
  m.state.round = 4;
  m.state.iteration = 31;
  m.state.stage = OptimisationStage::refine;
  const auto& gt = test::kittiLidarPoses();
  for (std::size_t i = 0; i < 200; ++i) m.poses.emplace_back(keyframe(3000 + 7 * i), gt[20 * i]);
  std::size_t bytes = 0;
  const PoseEstimates got = roundTrip(header(3, 1), m, &bytes);
  EXPECT_LE(bytes, 30u * m.poses.size());
  EXPECT_EQ(got.state.round, m.state.round);
  EXPECT_EQ(got.state.iteration, m.state.iteration);
  EXPECT_EQ(got.state.stage, m.state.stage);
  ASSERT_EQ(got.poses.size(), m.poses.size());
  for (std::size_t i = 0; i < m.poses.size(); ++i) {
    EXPECT_EQ(got.poses[i].first, m.poses[i].first);
    // float32 translations hundreds of metres out: within 0.1 mm.
    EXPECT_LT((got.poses[i].second.translation() - m.poses[i].second.translation()).norm(), 1e-4);
    EXPECT_LT(rotationError(got.poses[i].second, m.poses[i].second), 1e-4);
  }
  // One separator pose alone, with its header, also within 30 bytes... plus the envelope.
  PoseEstimates one;
  one.poses.emplace_back(keyframe(1500), gt[1500]);
  std::size_t one_bytes = 0;
  (void)roundTrip(header(3, 1), one, &one_bytes);
  EXPECT_LE(one_bytes, 30u + 16u);
}

TEST(Codec, AsDeliveredHoldsExactlyWhatTheReceiverDecodes) {
  // A verifier keeps the loop it sends as its receiver will read it: both
  // robots of a pair then hold bit-identical factors.
  const registration::VerificationResult& v = realVerification();
  LoopMeasurement m;
  m.query = keyframe(1204);
  m.match = keyframe(377);
  m.T_match_query = v.T_candidate_query;
  m.covariance = v.covariance;
  const LoopMeasurement kept = std::get<LoopMeasurement>(asDelivered(m));
  const LoopMeasurement received = roundTrip(header(2, 0, 40000), m);
  EXPECT_TRUE(kept.T_match_query.isApprox(received.T_match_query, 0.0));
  EXPECT_TRUE(kept.covariance == received.covariance);
  EXPECT_FALSE(kept.T_match_query.isApprox(m.T_match_query, 1e-12));  // it was rounded
  // Delivered twice is delivered once: the records are fixed points of the codec.
  const LoopMeasurement twice = std::get<LoopMeasurement>(asDelivered(kept));
  EXPECT_TRUE(twice.T_match_query.isApprox(kept.T_match_query, 1e-12));
}

TEST(Codec, PreciseSeparatorPosesKeepRotationsHundredsOfTimesFiner) {
  PoseEstimates m;
  m.precise = true;
  m.state.stage = OptimisationStage::refine;
  const auto& gt = test::kittiLidarPoses();
  for (std::size_t i = 0; i < 100; ++i) m.poses.emplace_back(keyframe(7 * i), gt[30 * i]);
  std::size_t bytes = 0;
  const PoseEstimates got = roundTrip(header(2, 0), m, &bytes);
  EXPECT_TRUE(got.precise);
  EXPECT_LE(bytes, 30u * m.poses.size());
  ASSERT_EQ(got.poses.size(), m.poses.size());
  double worst = 0.0;
  for (std::size_t i = 0; i < m.poses.size(); ++i)
    worst = std::max(worst, rotationError(got.poses[i].second, m.poses[i].second));
  EXPECT_LT(worst, 2e-7);  // the ground truth's own rounding to 6 digits shows here
  // The 19-byte records of the same poses are far coarser.
  m.precise = false;
  const PoseEstimates coarse = roundTrip(header(2, 0), m);
  double coarse_worst = 0.0;
  for (std::size_t i = 0; i < m.poses.size(); ++i)
    coarse_worst = std::max(coarse_worst, rotationError(coarse.poses[i].second, m.poses[i].second));
  EXPECT_GT(coarse_worst, 100.0 * worst);
  std::printf("precise records: rotation within %.1e rad, 19-byte records %.1e rad\n", worst,
              coarse_worst);
}

TEST(Codec, PoseIncrementsKeepMicrometresInAFewBytes) {
  // A refinement step moves separators by micrometres: increments from the
  // last values cost a few bytes each, to 1e-8 rad and 1e-6 m; larger steps
  // (here one KITTI frame to the next, a metre) cost more, as precisely.
  const auto& gt = test::kittiLidarPoses();
  for (const double scale : {1e-4, 1.0}) {
    PoseEstimates m;
    m.increments = true;
    m.state.stage = OptimisationStage::refine;
    for (std::size_t i = 0; i < 100; ++i) {
      const Eigen::Isometry3d step = gt[i].inverse() * gt[i + 1];
      const Eigen::AngleAxisd aa(step.rotation());
      Eigen::Isometry3d D = Eigen::Isometry3d::Identity();
      D.linear() = Eigen::AngleAxisd(scale * aa.angle(), aa.axis()).toRotationMatrix();
      D.translation() = scale * step.translation();
      m.poses.emplace_back(keyframe(7 * i), D);
    }
    std::size_t bytes = 0;
    const PoseEstimates got = roundTrip(header(2, 0), m, &bytes);
    EXPECT_TRUE(got.increments);
    EXPECT_FALSE(got.precise);
    ASSERT_EQ(got.poses.size(), m.poses.size());
    for (std::size_t i = 0; i < m.poses.size(); ++i) {
      EXPECT_LT(rotationError(got.poses[i].second, m.poses[i].second), 1e-8);
      EXPECT_LT((got.poses[i].second.translation() - m.poses[i].second.translation()).norm(), 1e-6);
    }
    const double per_pose = static_cast<double>(bytes) / 100.0;
    EXPECT_LT(per_pose, scale < 1.0 ? 12.0 : 22.0) << "scale " << scale;
    std::printf("increments of %g of a KITTI frame step: %.1f B a pose\n", scale, per_pose);
  }
  PoseEstimates both;
  both.increments = both.precise = true;
  both.poses.emplace_back(keyframe(1), Eigen::Isometry3d::Identity());
  EXPECT_THROW((void)encode({header(2, 0), both}), core::Error);
}

TEST(Codec, RelaxedRotationsKeepFourDecimals) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 0.05);
  RotationEstimates m;
  m.state.round = 2;
  m.state.iteration = 9;
  for (std::uint64_t i = 0; i < 50; ++i) {
    const Eigen::Isometry3d& T = test::kittiLidarPoses()[i * 50];
    Eigen::Matrix3d relaxed = T.rotation();
    for (int k = 0; k < 9; ++k) relaxed(k / 3, k % 3) += noise(rng);  // not a rotation
    m.rotations.emplace_back(keyframe(i), relaxed);
  }
  std::size_t bytes = 0;
  const RotationEstimates got = roundTrip(header(0, 1), m, &bytes);
  EXPECT_LE(bytes, 21u * m.rotations.size() + 16u) << "paper: 36 B a rotation";
  ASSERT_EQ(got.rotations.size(), m.rotations.size());
  for (std::size_t i = 0; i < m.rotations.size(); ++i) {
    EXPECT_EQ(got.rotations[i].first, m.rotations[i].first);
    EXPECT_LE((got.rotations[i].second - m.rotations[i].second).cwiseAbs().maxCoeff(),
              0.5 / 16384.0 + 1e-12);
  }
  m.rotations[3].second(1, 1) = 2.5;
  EXPECT_THROW((void)encode({header(0, 1), m}), core::Error);
}

TEST(Codec, StateSummariesAndHeartbeatsRoundTrip) {
  DgsState s{7,
             OptimisationStage::rotation,
             12,
             true,
             false,
             true,
             0.037F,
             {{robot(0), 12, 9, false}, {robot(4), 11, -1, true}},
             std::nullopt,
             false};
  const DgsState gs = roundTrip(header(4, std::nullopt), s);
  EXPECT_EQ(gs.round, 7u);
  EXPECT_EQ(gs.stage, OptimisationStage::rotation);
  EXPECT_EQ(gs.iteration, 12u);
  EXPECT_TRUE(gs.initialised);
  EXPECT_FALSE(gs.converged);
  EXPECT_TRUE(gs.abort);
  EXPECT_EQ(gs.change, 0.037F);
  ASSERT_EQ(gs.progress.size(), 2u);
  EXPECT_EQ(gs.progress[0].robot, robot(0));
  EXPECT_EQ(gs.progress[0].iteration, 12);
  EXPECT_EQ(gs.progress[0].converged_since, 9);
  EXPECT_FALSE(gs.progress[0].finished);
  EXPECT_EQ(gs.progress[1].converged_since, -1);
  EXPECT_TRUE(gs.progress[1].finished);
  EXPECT_FALSE(gs.frame);
  EXPECT_FALSE(gs.warm);
  s.frame = robot(0);  // robot 0 must not read back as "no frame"
  s.warm = true;
  const DgsState warm = roundTrip(header(4, std::nullopt), s);
  EXPECT_EQ(warm.frame, robot(0));
  EXPECT_TRUE(warm.warm);
  EXPECT_TRUE(warm.abort);
  s.frame = robot(254);
  EXPECT_EQ(roundTrip(header(4, std::nullopt), s).frame, robot(254));

  Heartbeat h{31.25, 512, {{robot(0), 2, 40, 3}, {robot(7), 1, 0, 12}}};
  const Heartbeat gh = roundTrip(header(1, std::nullopt), h);
  EXPECT_EQ(gh.stamp, 31.25);
  EXPECT_EQ(gh.keyframes, 512u);
  ASSERT_EQ(gh.acks.size(), 2u);
  EXPECT_EQ(gh.acks[1].peer, robot(7));
  EXPECT_EQ(gh.acks[1].incarnation, 1u);
  EXPECT_EQ(gh.acks[1].unicast, 12u);
  EXPECT_EQ(gh.acks[0].broadcast, 40u);

  EXPECT_EQ(roundTrip(header(1, 2), SummaryRequest{SummaryKind::map}).what, SummaryKind::map);

  TrajectorySummary t;
  const auto& gt = test::kittiLidarPoses();
  for (std::size_t i = 0; i < gt.size(); i += 5) t.poses.emplace_back(keyframe(i / 5), gt[i]);
  std::size_t bytes = 0;
  const TrajectorySummary gtraj = roundTrip(header(2, 1), t, &bytes);
  EXPECT_EQ(gtraj.poses.size(), t.poses.size());
  EXPECT_LE(bytes, 22u * t.poses.size());

  MapSummary map{6, registration::encodeVerificationCloud(test::kittiScan(2))};
  const MapSummary gmap = roundTrip(header(2, 1), map);
  EXPECT_EQ(gmap.keyframes, 6u);
  EXPECT_EQ(gmap.cloud, map.cloud);
}

TEST(Codec, EncodeRefusesWhatCannotGoOnTheWire) {
  EXPECT_THROW(
      (void)encode(
          {header(0, 1), DescriptorMessage{keyframe(1), 0.0, {}, std::nullopt, std::nullopt, {}}}),
      core::Error);
  LoopMeasurement bad;
  bad.T_match_query.translation().x() = std::nan("");
  EXPECT_THROW((void)encode({header(0, 1), bad}), core::Error);
  LoopMeasurement zero_variance;
  zero_variance.covariance(2, 2) = 0.0;
  EXPECT_THROW((void)encode({header(0, 1), zero_variance}), core::Error);
  Header no_sender = header(0, 1);
  no_sender.sender = core::RobotId();
  EXPECT_THROW((void)encode({no_sender, SummaryRequest{}}), core::Error);
  EXPECT_THROW(
      (void)encode(
          {header(0, 1),
           DescriptorMessage{
               keyframe(std::uint64_t{1} << 57), 0.0, {1, 2, 3}, std::nullopt, std::nullopt, {}}}),
      core::Error);
}

// ---------------------------------------------------------------- hostile input

/// A protobuf varint written by hand.
void varint(std::vector<std::uint8_t>& out, std::uint64_t v) {
  do {
    std::uint8_t byte = v & 0x7F;
    v >>= 7;
    if (v != 0) byte |= 0x80;
    out.push_back(byte);
  } while (v != 0);
}

/// A protobuf field written by hand: tag and varint value.
void varintField(std::vector<std::uint8_t>& out, int field, std::uint64_t value) {
  varint(out, static_cast<std::uint64_t>(field) << 3);
  varint(out, value);
}

/// A valid request, then `field` = `value` appended (protobuf: the last value wins).
Decoded withField(int field, std::uint64_t value) {
  std::vector<std::uint8_t> bytes = encode({header(1, 2), SummaryRequest{}});
  varintField(bytes, field, value);
  return decode(bytes);
}

TEST(Codec, HeaderFieldsOutOfRangeAreDroppedByName) {
  const Decoded version = withField(1, 2);
  EXPECT_FALSE(version.message);
  EXPECT_EQ(version.reason, DropReason::wrong_version);
  EXPECT_NE(version.detail.find("version 2"), std::string::npos) << version.detail;
  for (const auto& [field, value, what] :
       {std::tuple{2, 300, "sender"}, std::tuple{3, 256, "receiver"},
        std::tuple{4, 0, "incarnation"}, std::tuple{5, 0, "sequence"}}) {
    const Decoded d = withField(field, static_cast<std::uint64_t>(value));
    EXPECT_FALSE(d.message) << what;
    EXPECT_EQ(d.reason, DropReason::invalid_field) << what;
    EXPECT_NE(d.detail.find(what), std::string::npos) << d.detail;
  }
  EXPECT_TRUE(withField(3, 255).message) << "receiver 254 is a robot";
}

TEST(Codec, OversizedGarbageAndEmptyBodiesAreDropped) {
  const std::vector<std::uint8_t> huge(kMaxMessageBytes + 1, 0);
  EXPECT_EQ(decode(huge).reason, DropReason::oversized);
  const std::vector<std::uint8_t> garbage = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
  EXPECT_EQ(decode(garbage).reason, DropReason::malformed);
  std::vector<std::uint8_t> header_only;
  varintField(header_only, 1, kSchemaVersion);
  varintField(header_only, 4, 1);
  varintField(header_only, 5, 1);
  const Decoded d = decode(header_only);
  EXPECT_EQ(d.reason, DropReason::invalid_field);
  EXPECT_NE(d.detail.find("no body"), std::string::npos);
}

/// A pose-estimates body written by hand: keyframes 1.. and `increments` as
/// raw zigzag varints (field 5, packed).
Decoded incrementsBody(std::size_t keyframes, const std::vector<std::uint64_t>& zigzags) {
  std::vector<std::uint8_t> body;
  const auto packed = [&body](int field, const std::vector<std::uint64_t>& values) {
    std::vector<std::uint8_t> payload;
    for (const std::uint64_t v : values) varint(payload, v);
    varint(body, static_cast<std::uint64_t>(field) << 3 | 2);
    varint(body, payload.size());
    body.insert(body.end(), payload.begin(), payload.end());
  };
  std::vector<std::uint64_t> ids;
  for (std::size_t k = 1; k <= keyframes; ++k) ids.push_back(k);
  packed(2, ids);
  packed(5, zigzags);
  std::vector<std::uint8_t> bytes;
  varintField(bytes, 1, kSchemaVersion);
  varintField(bytes, 2, 1);
  varintField(bytes, 4, 1);
  varintField(bytes, 5, 1);
  varint(bytes, 16 << 3 | 2);  // the envelope's pose_estimates, length-delimited
  varint(bytes, body.size());
  bytes.insert(bytes.end(), body.begin(), body.end());
  return decode(bytes);
}

TEST(Codec, PoseIncrementsOutOfRangeAreDroppedByName) {
  EXPECT_TRUE(incrementsBody(1, {2, 1, 4, 3, 0, 6}).message) << incrementsBody(1, {}).detail;
  const Decoded short_of_six = incrementsBody(2, {2, 1, 4, 3, 0, 6, 1});
  EXPECT_EQ(short_of_six.reason, DropReason::invalid_field);
  EXPECT_NE(short_of_six.detail.find("six each"), std::string::npos) << short_of_six.detail;
  // 4 rad about x (zigzag 8e8): beyond pi.
  const Decoded turned = incrementsBody(1, {800'000'000, 0, 0, 0, 0, 0});
  EXPECT_EQ(turned.reason, DropReason::invalid_field);
  EXPECT_NE(turned.detail.find("beyond pi"), std::string::npos) << turned.detail;
  // 2100 m along y (zigzag 4.2e9, beyond an int32's 4294967295 / 2): not a sint32.
  const Decoded far = incrementsBody(1, {0, 0, 0, 0, 4'200'000'000, 0});
  EXPECT_EQ(far.reason, DropReason::invalid_field);
  EXPECT_NE(far.detail.find("beyond kMaxIncrement"), std::string::npos) << far.detail;
}

/// Every message kind with realistic content.
std::vector<Message> samples() {
  const registration::VerificationResult& v = realVerification();
  LoopMeasurement loop;
  loop.query = keyframe(12);
  loop.match = keyframe(800);
  loop.T_match_query = v.T_candidate_query;
  loop.covariance = v.covariance;
  PoseEstimates poses;
  poses.state = {3,
                 OptimisationStage::pose,
                 8,
                 true,
                 false,
                 false,
                 0.01F,
                 {{robot(1), 8, -1, false}},
                 std::nullopt,
                 false};
  RotationEstimates rotations;
  rotations.state.stage = OptimisationStage::rotation;
  for (std::uint64_t i = 0; i < 6; ++i) {
    poses.poses.emplace_back(keyframe(i * 3), test::kittiLidarPoses()[i * 100]);
    rotations.rotations.emplace_back(keyframe(i), test::kittiLidarPoses()[i * 90].rotation());
  }
  registration::CloudCodecConfig coarse;
  coarse.voxel_size = 2.0;
  const std::vector<std::uint8_t> small_cloud =
      registration::encodeVerificationCloud(test::kittiScan(3), coarse);
  return {
      {header(0, std::nullopt, 1), Heartbeat{1.0, 3, {{robot(1), 1, 2, 0}}}},
      {header(0, std::nullopt, 2),
       DescriptorMessage{keyframe(3), 4.5, {9, 8, 7, 6, 5}, std::nullopt, std::nullopt, {}}},
      {header(0, 1, 3), LoopCandidate{keyframe(3), keyframe(7), 0.5F, 0.2F, small_cloud}},
      {header(1, 0, 4), loop},
      {header(1, 0, 5), DgsState{2,
                                 OptimisationStage::pose,
                                 4,
                                 true,
                                 true,
                                 false,
                                 0.5F,
                                 {{robot(0), 4, 2, false}},
                                 std::nullopt,
                                 false}},
      {header(1, 0, 6), rotations},
      {header(1, 0, 7), poses},
      {header(1, 0, 8), SummaryRequest{SummaryKind::trajectory}},
      {header(0, 1, 9), TrajectorySummary{poses.poses}},
      {header(0, 1, 10), MapSummary{2, small_cloud}},
  };
}

TEST(Codec, EveryTruncationOfEveryKindIsDroppedOrDecodesValid) {
  const std::vector<Message> all = samples();
  ASSERT_EQ(all.size(), kMessageKinds);
  for (const Message& m : all) {
    const std::vector<std::uint8_t> bytes = encode(m);
    const Decoded whole = decode(bytes);
    ASSERT_TRUE(whole.message) << name(m.kind()) << ": " << whole.detail;
    EXPECT_EQ(whole.message->kind(), m.kind());
    std::size_t dropped = 0;
    for (std::size_t n = 0; n < bytes.size(); ++n) {
      const Decoded d = decode(std::span(bytes.data(), n));
      if (!d.message) {
        ++dropped;
        EXPECT_FALSE(d.detail.empty()) << name(m.kind()) << " cut at " << n;
      }
    }
    // Cutting a protobuf message at a field boundary can leave a valid,
    // shorter one; most cuts are not at one.
    EXPECT_GT(dropped, bytes.size() / 2) << name(m.kind());
  }
}

TEST(Codec, RandomBitFlipsNeverCrashAndDecodeOnlyValidValues) {
  std::mt19937_64 rng(11);
  std::size_t decoded = 0;
  std::size_t dropped = 0;
  for (const Message& m : samples()) {
    const std::vector<std::uint8_t> clean = encode(m);
    for (int trial = 0; trial < 300; ++trial) {
      std::vector<std::uint8_t> bytes = clean;
      const int flips = 1 + static_cast<int>(rng() % 4);
      for (int f = 0; f < flips; ++f) bytes[rng() % bytes.size()] ^= 1U << (rng() % 8);
      const Decoded d = decode(bytes);
      if (!d.message) {
        ++dropped;
        continue;
      }
      ++decoded;
      // Whatever decodes holds values the schema allows: it encodes again.
      try {
        (void)encode(*d.message);
      } catch (const core::Error& e) {
        ADD_FAILURE() << name(d.message->kind()) << ": " << e.what();
      }
    }
  }
  EXPECT_GT(dropped, 0u);
  EXPECT_GT(decoded, 0u);
}

TEST(Codec, AnIndefiniteCovarianceIsRefused) {
  LoopMeasurement m;
  m.query = keyframe(1);
  m.match = keyframe(2);
  std::vector<std::uint8_t> bytes = encode({header(0, 1), m});
  // The covariance record is the last 42 bytes; its correlations the last 30.
  // Correlations of 0.9 between x-y, y-z and -0.9 between x-z cannot all hold.
  const auto setCorrelation = [&bytes](int index, double rho) {
    const auto q = static_cast<std::int16_t>(std::lround(rho * 32767.0));
    std::memcpy(bytes.data() + bytes.size() - 30 + 2 * index, &q, 2);
  };
  setCorrelation(0, 0.9);   // (0,1)
  setCorrelation(1, -0.9);  // (0,2)
  setCorrelation(5, 0.9);   // (1,2)
  const Decoded d = decode(bytes);
  EXPECT_FALSE(d.message);
  EXPECT_EQ(d.reason, DropReason::invalid_field);
  EXPECT_NE(d.detail.find("covariance"), std::string::npos) << d.detail;
}

TEST(Codec, FuzzerFindingsStayFixed) {
  // A loop measurement whose covariance needed its quantisation repaired, with
  // standard deviations at the top of the range: it decoded, then would not encode.
  const std::vector<std::uint8_t> repaired_at_the_edge = {
      0x08, 0x01, 0x10, 0x01, 0x18, 0x03, 0x20, 0x01, 0x28, 0xff, 0xff, 0xff, 0xcc, 0x04, 0x6a,
      0x45, 0x08, 0x04, 0x10, 0x5a, 0x22, 0x13, 0x00, 0x92, 0x12, 0x49, 0xc8, 0x25, 0x25, 0x00,
      0x00, 0x40, 0x41, 0x0b, 0x00, 0x60, 0xc0, 0x00, 0x00, 0x80, 0x3e, 0x2a, 0x2a, 0x6d, 0xff,
      0xff, 0xff, 0x73, 0x65, 0x6d, 0x65, 0x6d, 0x65, 0x6d, 0x65, 0x66, 0x26, 0x00, 0x00, 0x00,
      0x00, 0x00, 0x72, 0x0d, 0x08, 0xed, 0xed, 0xed, 0xed, 0xed, 0xed, 0xed, 0xed, 0xed, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x08, 0x00, 0x00,
  };
  const Decoded d = decode(repaired_at_the_edge);
  ASSERT_TRUE(d.message) << d.detail;
  EXPECT_NO_THROW((void)encode(*d.message));
}

}  // namespace
}  // namespace dcl::comm
