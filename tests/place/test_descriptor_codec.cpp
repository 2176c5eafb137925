#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include <dcl/place/descriptor_codec.hpp>

#include "descriptor_test_data.hpp"

namespace dcl::place {
namespace {

const std::vector<int> kFrames = {0, 1, 2, 3, 4, 5, 94, 95, 198, 199};

const std::vector<IrisDescriptor>& kittiDescriptors() {
  static const std::vector<IrisDescriptor> all = [] {
    std::vector<IrisDescriptor> d;
    for (int f : kFrames) d.push_back(describeIris(test::kittiScan(f)));
    return d;
  }();
  return all;
}

std::vector<std::uint8_t> encoded(int i = 0) {
  return encodeIris(kittiDescriptors()[static_cast<std::size_t>(i)]);
}

/// True when decoding `bytes` throws DecodeError (and nothing else happens).
bool rejected(std::span<const std::uint8_t> bytes) {
  try {
    (void)decodeIris(bytes);
  } catch (const DecodeError&) {
    return true;
  }
  return false;
}

TEST(IrisCodec, RoundTripsRealScansExactlyWithinThreeKilobytes) {
  std::size_t total = 0;
  for (const IrisDescriptor& d : kittiDescriptors()) {
    const std::vector<std::uint8_t> bytes = encodeIris(d);
    total += bytes.size();
    const IrisDescriptor back = decodeIris(bytes);
    EXPECT_EQ(back.image.cells, d.image.cells);
    EXPECT_EQ(back.row_key, d.row_key);
    EXPECT_EQ(back.features, d.features);  // recomputed on receipt, bit for bit
    EXPECT_EQ(back.mask, d.mask);
  }
  const double mean = static_cast<double>(total) / static_cast<double>(kFrames.size());
  std::printf("mean encoded LiDAR-Iris descriptor: %.0f bytes (KITTI 00, %zu scans)\n", mean,
              kFrames.size());
  EXPECT_LE(mean, 3000.0);
}

TEST(IrisCodec, EncodesAnyImageLosslessly) {
  std::mt19937 rng(7);
  IrisImage image{80, 360, std::vector<std::uint8_t>(80 * 360)};
  for (std::uint8_t& c : image.cells) c = static_cast<std::uint8_t>(rng());
  EXPECT_EQ(decodeIrisImage(encodeIrisImage(image)).cells, image.cells);
  const IrisImage empty{80, 360, std::vector<std::uint8_t>(80 * 360, 0)};
  const std::vector<std::uint8_t> bytes = encodeIrisImage(empty);
  EXPECT_LT(bytes.size(), 64U);
  EXPECT_EQ(decodeIrisImage(bytes).cells, empty.cells);
  EXPECT_THROW(encodeIrisImage(IrisImage{80, 360, {}}), core::Error);
}

TEST(IrisCodec, RejectsEveryTruncation) {
  const std::vector<std::uint8_t> bytes = encoded();
  for (std::size_t n = 0; n < bytes.size(); ++n)
    EXPECT_TRUE(rejected(std::span(bytes).first(n))) << n << " bytes";
  std::vector<std::uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_TRUE(rejected(longer));  // trailing bytes
}

TEST(IrisCodec, RejectsBadHeaders) {
  const std::vector<std::uint8_t> good = encoded(1);
  auto with = [&](std::size_t at, std::uint8_t value) {
    std::vector<std::uint8_t> b = good;
    b[at] = value;
    return b;
  };
  EXPECT_TRUE(rejected(with(0, 'X')));                    // magic
  EXPECT_TRUE(rejected(with(2, kIrisCodecVersion + 1)));  // version
  EXPECT_TRUE(rejected(with(3, 9)));                      // kind
  EXPECT_TRUE(rejected(with(4, 81)));                     // rows no longer match the frame
  // Hostile dimensions are refused before anything is allocated.
  std::vector<std::uint8_t> huge = with(4, 0xFF);
  huge[5] = huge[6] = huge[7] = 0xFF;
  EXPECT_TRUE(rejected(huge));
  // A valid image of other dimensions than the receiver's configuration.
  const std::vector<std::uint8_t> small =
      encodeIrisImage(IrisImage{40, 360, std::vector<std::uint8_t>(40 * 360, 1)});
  EXPECT_NO_THROW(decodeIrisImage(small));
  EXPECT_TRUE(rejected(small));
}

TEST(IrisCodec, RejectsCorruptPayloadsAndRandomBytes) {
  const std::vector<std::uint8_t> good = encoded(2);
  std::mt19937 rng(42);
  int accepted = 0;
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<std::uint8_t> b = good;
    const std::size_t at = kIrisCodecHeaderBytes + rng() % (b.size() - kIrisCodecHeaderBytes);
    b[at] ^= static_cast<std::uint8_t>(1U << (rng() % 8));
    try {
      const IrisImage image = decodeIrisImage(b);
      accepted += image.cells == kittiDescriptors()[2].image.cells
                      ? 0
                      : 1;  // only a harmless flip may pass
    } catch (const DecodeError&) {
    }
  }
  EXPECT_EQ(accepted, 0);  // the frame checksum catches altered images
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<std::uint8_t> b(rng() % 4000);
    for (std::uint8_t& x : b) x = static_cast<std::uint8_t>(rng());
    if (trial % 2 == 0 && b.size() >= kIrisCodecHeaderBytes)
      std::copy(good.begin(), good.begin() + kIrisCodecHeaderBytes,
                b.begin());  // a plausible header
    EXPECT_TRUE(rejected(b));
  }
}

}  // namespace
}  // namespace dcl::place
