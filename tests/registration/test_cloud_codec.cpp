// The compact verification cloud: size on real HDL-64 scans, registration
// from it against registration from the full scan, exactness within the
// quantisation, and hostile input.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/registration/cloud_codec.hpp>
#include <dcl/registration/verification.hpp>
#include <dcl/registration/voxel_filter.hpp>

#include "registration_test_data.hpp"

namespace dcl::registration {
namespace {

using test::poseError;

/// True when decoding `bytes` throws CloudDecodeError (and nothing else happens).
bool rejected(std::span<const std::uint8_t> bytes) {
  try {
    (void)decodeVerificationCloud(bytes);
  } catch (const CloudDecodeError&) {
    return true;
  }
  return false;
}

const std::vector<std::uint8_t>& encodedScan() {
  static const std::vector<std::uint8_t> bytes = encodeVerificationCloud(test::kittiScan(0));
  return bytes;
}

/// The float step stored in a message's header.
double stepOf(const std::vector<std::uint8_t>& bytes) {
  float step = 0.0F;
  std::memcpy(&step, bytes.data() + 4, sizeof(step));
  return step;
}

TEST(CloudCodec, AnHdl64KeyframeFitsInTwentyFiveKilobytes) {
  std::size_t largest = 0;
  for (int frame : {0, 1, 2, 3, 4, 5, 94, 95, 198, 199}) {
    const core::PointCloud scan = test::kittiScan(frame);
    const std::vector<std::uint8_t> bytes = encodeVerificationCloud(scan);
    largest = std::max(largest, bytes.size());
    const core::PointCloud back = decodeVerificationCloud(bytes);
    EXPECT_EQ(back.size(), voxelDownsample(scan.points, CloudCodecConfig{}.voxel_size).size());
    EXPECT_FALSE(back.hasIntensity());
  }
  std::printf("largest compact KITTI 00 keyframe: %zu bytes (float xyz of the full scan: %zu)\n",
              largest, test::kittiScan(0).size() * 12);
  EXPECT_LE(largest, 25000U);
}

TEST(CloudCodec, RegistrationFromTheCompactCloudMatchesTheFullScan) {
  for (auto [query, candidate] : {std::pair{94, 95}, std::pair{199, 198}, std::pair{0, 5}}) {
    const core::PointCloud full = test::kittiScan(query);
    const core::PointCloud target = test::kittiScan(candidate);
    const double yaw = test::yawOf(test::kittiTruth(query, candidate));
    const VerificationResult from_full = verifyLoop(full, yaw, target);
    const VerificationResult from_compact =
        verifyLoop(decodeVerificationCloud(encodeVerificationCloud(full)), yaw, target);
    ASSERT_TRUE(from_full.accepted);
    ASSERT_TRUE(from_compact.accepted);
    const auto difference = poseError(from_compact.T_candidate_query, from_full.T_candidate_query);
    EXPECT_LT(difference.translation, 0.02) << query;
    EXPECT_LT(difference.rotation_deg, 0.1) << query;
  }
}

TEST(CloudCodec, RoundTripsWithinHalfAStep) {
  const core::PointCloud scan = test::kittiScan(198);
  CloudCodecConfig raw;
  raw.voxel_size = 0.0;  // every point, so that each can be found again
  core::PointCloud some;
  for (std::size_t i = 0; i < scan.size(); i += 7) some.points.push_back(scan.points[i]);
  const std::vector<std::uint8_t> bytes = encodeVerificationCloud(some, raw);
  const double step = stepOf(bytes);
  EXPECT_NEAR(step, raw.resolution, 1e-8);  // the range fits: the configured step (in float)
  const core::PointCloud back = decodeVerificationCloud(bytes);
  ASSERT_EQ(back.size(), some.size());
  // The decoded points come in another order: match them by their grid cell.
  auto cell = [step](const Eigen::Vector3f& p) {
    return std::array<long, 3>{std::lround(p.x() / step), std::lround(p.y() / step),
                               std::lround(p.z() / step)};
  };
  std::vector<std::array<long, 3>> sent;
  std::vector<std::array<long, 3>> received;
  for (const Eigen::Vector3f& p : some.points) sent.push_back(cell(p));
  for (const Eigen::Vector3f& p : back.points) received.push_back(cell(p));
  std::sort(sent.begin(), sent.end());
  std::sort(received.begin(), received.end());
  EXPECT_EQ(sent, received);
  for (const Eigen::Vector3f& p : back.points) {
    for (int axis = 0; axis < 3; ++axis) {
      const double q = p[axis] / step;
      EXPECT_NEAR(q, std::round(q), 1e-3);  // on the grid
    }
  }
  // Points already on the grid come back bit for bit.
  const core::PointCloud again = decodeVerificationCloud(encodeVerificationCloud(back, raw));
  std::vector<Eigen::Vector3f> a = back.points;
  std::vector<Eigen::Vector3f> b = again.points;
  auto lexicographic = [](const Eigen::Vector3f& u, const Eigen::Vector3f& v) {
    return std::tie(u.x(), u.y(), u.z()) < std::tie(v.x(), v.y(), v.z());
  };
  std::sort(a.begin(), a.end(), lexicographic);
  std::sort(b.begin(), b.end(), lexicographic);
  EXPECT_EQ(a, b);
}

TEST(CloudCodec, CoarsensTheStepForFarPointsAndDropsWhatItCannotSend) {
  core::PointCloud cloud;
  cloud.points = {{1.0F, 2.0F, 3.0F},
                  {900.0F, -5.0F, 0.5F},
                  {std::numeric_limits<float>::quiet_NaN(), 0.0F, 0.0F}};
  CloudCodecConfig raw;
  raw.voxel_size = 0.0;
  const std::vector<std::uint8_t> bytes = encodeVerificationCloud(cloud, raw);
  EXPECT_GE(stepOf(bytes) * 32767.0, 900.0);  // 900 m does not fit 32767 steps of 2 cm
  const core::PointCloud back = decodeVerificationCloud(bytes);
  ASSERT_EQ(back.size(), 2U);  // the NaN point is not sent
  const double half = stepOf(bytes) / 2.0 + 1e-6;
  const auto far = std::find_if(back.points.begin(), back.points.end(),
                                [](const Eigen::Vector3f& p) { return p.x() > 100.0F; });
  ASSERT_NE(far, back.points.end());
  EXPECT_LE((far->cast<double>() - Eigen::Vector3d(900.0, -5.0, 0.5)).cwiseAbs().maxCoeff(), half);
  raw.max_range = 100.0;
  EXPECT_EQ(decodeVerificationCloud(encodeVerificationCloud(cloud, raw)).size(), 1U);
  EXPECT_TRUE(decodeVerificationCloud(encodeVerificationCloud(core::PointCloud{})).empty());
  cloud.points = {{1e5F, 0.0F, 0.0F}};  // 100 km: no 16-bit grid reaches it
  EXPECT_THROW(encodeVerificationCloud(cloud), core::Error);
  const std::vector<void (*)(CloudCodecConfig&)> breakers = {
      [](CloudCodecConfig& c) { c.resolution = 0.0; },
      [](CloudCodecConfig& c) { c.voxel_size = -1.0; },
      [](CloudCodecConfig& c) { c.zstd_level = 0; }};
  for (auto bad : breakers) {
    CloudCodecConfig config;
    bad(config);
    EXPECT_THROW(encodeVerificationCloud(test::kittiScan(94), config), core::Error);
  }
}

TEST(CloudCodec, RejectsEveryTruncationAndTrailingBytes) {
  const std::vector<std::uint8_t>& bytes = encodedScan();
  // Every header length, then every 97th longer prefix (the frame is 23 kB).
  for (std::size_t n = 0; n < bytes.size(); n += n < 64 ? 1 : 97)
    EXPECT_TRUE(rejected(std::span(bytes).first(n))) << n << " bytes";
  EXPECT_TRUE(rejected(std::span(bytes).first(bytes.size() - 1)));
  std::vector<std::uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_TRUE(rejected(longer));
}

TEST(CloudCodec, RejectsBadHeaders) {
  const std::vector<std::uint8_t>& good = encodedScan();
  auto with = [&](std::size_t at, std::uint8_t value) {
    std::vector<std::uint8_t> b = good;
    b[at] = value;
    return b;
  };
  auto withFloat = [&](float step) {
    std::vector<std::uint8_t> b = good;
    std::memcpy(b.data() + 4, &step, sizeof(step));
    return b;
  };
  EXPECT_TRUE(rejected(with(0, 'X')));                     // magic
  EXPECT_TRUE(rejected(with(2, kCloudCodecVersion + 1)));  // version
  EXPECT_TRUE(rejected(with(3, 1)));                       // flags
  EXPECT_TRUE(rejected(withFloat(0.0F)));                  // resolution
  EXPECT_TRUE(rejected(withFloat(-0.02F)));
  EXPECT_TRUE(rejected(withFloat(std::numeric_limits<float>::quiet_NaN())));
  EXPECT_TRUE(rejected(withFloat(std::numeric_limits<float>::infinity())));
  EXPECT_TRUE(rejected(withFloat(1e-30F)));
  EXPECT_TRUE(rejected(withFloat(5.0F)));
  EXPECT_TRUE(rejected(with(8, static_cast<std::uint8_t>(good[8] + 1))));  // count vs frame
  // A hostile count is refused before anything is allocated.
  std::vector<std::uint8_t> huge = good;
  huge[8] = huge[9] = huge[10] = huge[11] = 0xFF;
  EXPECT_TRUE(rejected(huge));
  // The same step with another valid value still decodes (a receiver-side check).
  EXPECT_NO_THROW(decodeVerificationCloud(withFloat(0.04F)));
}

TEST(CloudCodec, RejectsCorruptPayloadsAndRandomBytes) {
  const std::vector<std::uint8_t>& good = encodedScan();
  std::mt19937 rng(42);
  const core::PointCloud original = decodeVerificationCloud(good);
  int altered = 0;
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<std::uint8_t> b = good;
    const std::size_t at = kCloudCodecHeaderBytes + rng() % (b.size() - kCloudCodecHeaderBytes);
    b[at] ^= static_cast<std::uint8_t>(1U << (rng() % 8));
    try {
      altered += decodeVerificationCloud(b).points == original.points ? 0 : 1;
    } catch (const CloudDecodeError&) {
    }
  }
  EXPECT_EQ(altered, 0);  // the frame checksum catches every altered cloud
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<std::uint8_t> b(rng() % 3000);
    for (std::uint8_t& x : b) x = static_cast<std::uint8_t>(rng());
    if (trial % 2 == 0 && b.size() >= kCloudCodecHeaderBytes)
      std::copy(good.begin(), good.begin() + kCloudCodecHeaderBytes, b.begin());
    EXPECT_TRUE(rejected(b)) << "random trial " << trial;
  }
  // A valid frame of the right size but for another count.
  std::vector<std::uint8_t> other = encodeVerificationCloud(test::kittiScan(198));
  std::copy(good.begin() + 8, good.begin() + 12, other.begin() + 8);
  EXPECT_TRUE(rejected(other));
}

}  // namespace
}  // namespace dcl::registration
