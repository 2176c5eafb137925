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
               {0x6e628f125405867fULL, 0xc7a9e564f724673bULL, 0xe1f2d71ea8eeb6e5ULL,
                0x12247aec5a277766ULL}},
      Expected{"kitti05-3",
               {0x2dab18c3bd54212fULL, 0xd4e2bdd4b7deb3adULL, 0x3d1320d49b370207ULL,
                0xe4a49b5c74f408d7ULL}},
      Expected{"kitti08-2",
               {0xad0f16714c4ab773ULL, 0xd35e4d2189013251ULL, 0xfe7d972d709c5d10ULL,
                0x4884eb61eb6d8f32ULL}},
      Expected{"campus-3",
               {0xf7747699d28f1aa8ULL, 0x86fae9c20bd115f4ULL, 0xe4293928ec8d75ccULL,
                0xb6308ad846720decULL}},
      Expected{"campus-9",
               {0x334fe3802492e20dULL, 0x2480593a8e8e5ea1ULL, 0x3d7ee91add2b0738ULL,
                0xb430322f502f54d7ULL}},
      Expected{"aliasing-3",
               {0xbac071b5072dd937ULL, 0x1a19892555d32653ULL, 0xa310c1bb4d6d8cd1ULL,
                0x9702ab89f389aa8bULL}},
      Expected{"crossing-2",
               {0x83cdba4a7f5ef5b2ULL, 0xcab9288aa7405995ULL, 0xd0b6028c6263ccb4ULL,
                0xd26d405d2a397feaULL}},
      Expected{"demo",
               {0x8b18618644a6aeebULL, 0x4b5bc452fc8536bfULL, 0x2cd8141484e7ea63ULL,
                0x9fa3cd46c6906862ULL}}};
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
