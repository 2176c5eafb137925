// Simulated scans are the same bits on every x86-64 machine: checksums of a
// few scans of every preset against values computed once and committed here.
// A change of the world generator, the sensor model or the ray caster that
// moves a single bit fails this test; regenerate the table then, on purpose
// (the test prints the values it computed).

#include <algorithm>
#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/sim/presets.hpp>
#include <dcl/sim/sim_source.hpp>

#include "dataset_test_util.hpp"

namespace dcl::sim {
namespace {

/// 64-bit FNV-1a, continued over `bytes`.
std::uint64_t fnv1a(std::uint64_t hash, const void* bytes, std::size_t size) {
  const auto* p = static_cast<const unsigned char*>(bytes);
  for (std::size_t i = 0; i < size; ++i) hash = (hash ^ p[i]) * 0x100000001b3ULL;
  return hash;
}

/// Every channel of a scan, bit for bit.
std::uint64_t checksum(const core::PointCloud& cloud) {
  std::uint64_t hash = 0xcbf29ce484222325ULL;
  for (const Eigen::Vector3f& p : cloud.points) hash = fnv1a(hash, p.data(), 3 * sizeof(float));
  hash = fnv1a(hash, cloud.intensity.data(), cloud.intensity.size() * sizeof(float));
  hash = fnv1a(hash, cloud.time.data(), cloud.time.size() * sizeof(float));
  return fnv1a(hash, cloud.ring.data(), cloud.ring.size() * sizeof(std::uint16_t));
}

/// The scans of a preset that are checked: three of its first robot and one
/// of its last, spread over their drives.
struct Expected {
  std::string preset;
  std::vector<std::uint64_t> checksums;  ///< first robot at 0, 1/2, 1; last robot at 1/3
};

void PrintTo(const Expected& expected, std::ostream* os) {
  *os << expected.preset;
}

class ScanChecksums : public ::testing::TestWithParam<Expected> {};

TEST_P(ScanChecksums, MatchTheCommittedValues) {
  const Expected& expected = GetParam();
  PresetOptions options;
  options.data_dir = DCL_DATA_DIR;
  const auto folder = test::freshDir();
  const SimWorld world(writeSimDataset(folder.string(), makePreset(expected.preset, options)));
  std::filesystem::remove_all(folder);
  const std::size_t last_robot = world.robots() - 1;
  const std::size_t first_size = world.groundTruth(0).size();
  const std::vector<std::pair<std::size_t, std::size_t>> scans{
      {0, 0},
      {0, first_size / 2},
      {0, first_size - 1},
      {last_robot, world.groundTruth(last_robot).size() / 3}};
  std::vector<std::uint64_t> computed;
  for (const auto& [robot, index] : scans) computed.push_back(checksum(world.scan(robot, index)));
  std::string listed;
  for (const std::uint64_t c : computed) {
    char text[32];
    std::snprintf(text, sizeof text, "0x%016" PRIx64 "ULL", c);
    listed += (listed.empty() ? "" : ", ") + std::string(text);
  }
  std::printf("%s: {%s}\n", expected.preset.c_str(), listed.c_str());
  EXPECT_EQ(computed, expected.checksums) << "computed {" << listed << "}";
}

/// The committed checksums, one entry a preset.
const std::vector<Expected>& committed() {
  static const std::vector<Expected> table{
      Expected{"kitti00-3",
               {0x803ddea622223675ULL, 0x1a08825bcf7b6dc8ULL, 0x71442ac7757fd037ULL,
                0xd9c0f9599589a3a5ULL}},
      Expected{"kitti05-3",
               {0x44a87de16eca26f9ULL, 0x9102729804316455ULL, 0x8f1433ad6bd72854ULL,
                0x881adb9515bebf9cULL}},
      Expected{"kitti08-2",
               {0xf431b85798abfe47ULL, 0x5984a71c22fab809ULL, 0x902a2cf3b865d1d9ULL,
                0x580d816bca4d19f1ULL}},
      Expected{"campus-3",
               {0xe6e1f12d5b3b4574ULL, 0x3a4d29bb24e19beaULL, 0x011252b403da85abULL,
                0x178a434da78222f4ULL}},
      Expected{"campus-9",
               {0x2419f6cbce0dd912ULL, 0x579e99dca92deb09ULL, 0x74e30ee2f391e2f2ULL,
                0x613577fb3b857af0ULL}},
      Expected{"aliasing-3",
               {0x5b82287c805c3562ULL, 0x86623afabb3ced60ULL, 0xa43ea67671f67284ULL,
                0xca27fb2d4de91f37ULL}},
      Expected{"crossing-2",
               {0xc5cf70d5b7258a4eULL, 0x284bd7734e6018e0ULL, 0x1072c1905b01e65bULL,
                0x06e5cf5099b916fcULL}},
      Expected{"demo",
               {0x231635b44c505f8bULL, 0xc0b77605de1337e2ULL, 0xd467830bb0e9947dULL,
                0x0957d4692a5585a9ULL}}};
  return table;
}

TEST(ScanChecksums, EveryPresetHasItsEntry) {
  std::vector<std::string> listed;
  for (const Expected& e : committed()) listed.push_back(e.preset);
  std::vector<std::string> presets = presetNames();
  std::sort(listed.begin(), listed.end());
  std::sort(presets.begin(), presets.end());
  EXPECT_EQ(listed, presets);
}

INSTANTIATE_TEST_SUITE_P(Presets, ScanChecksums, ::testing::ValuesIn(committed()),
                         [](const ::testing::TestParamInfo<Expected>& info) {
                           std::string name = info.param.preset;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

}  // namespace
}  // namespace dcl::sim
