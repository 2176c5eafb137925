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
               {0x854abb14f0b34b1eULL, 0x00cb0dfecaf80badULL, 0xe3a57e05d0a167a6ULL,
                0x1f2f3ed5bd4a3b6cULL}},
      Expected{"kitti05-3",
               {0xc5d1b182fe2836b7ULL, 0x6cafa375d66a3a9bULL, 0x874d33f94de48d1fULL,
                0x3ed652fbb10bfbabULL}},
      Expected{"kitti08-2",
               {0x6c026ae61e25d09aULL, 0x3eaa77acfbbba0ccULL, 0xd9f3577aad3237b8ULL,
                0x73bc45c520b45af4ULL}},
      Expected{"campus-3",
               {0x518e70f463c05653ULL, 0x0b53cf4b3cc3d087ULL, 0x2abb34825dbeaa93ULL,
                0xa7f598298cbd3bfeULL}},
      Expected{"campus-9",
               {0x3d8f3781e88cfc23ULL, 0x03296e957d476cb4ULL, 0x0f08595f15b7d7b2ULL,
                0x3dd2ec611c7660c8ULL}},
      Expected{"aliasing-3",
               {0xc951731e6ff3152aULL, 0x282fb1945f31cb39ULL, 0xe0b33d3b0bbe14c8ULL,
                0x4b7986c42649a4dcULL}},
      Expected{"crossing-2",
               {0xbdc665528ab089ebULL, 0x074a00c2697bf0bdULL, 0x6d7f2128e352bb78ULL,
                0x9aba1f4b11cd3a48ULL}},
      Expected{"demo",
               {0x6fda9240de464b67ULL, 0xd14ff1025ec8ee28ULL, 0x1b5a9e1bb16082ddULL,
                0x4867fbb7cc270594ULL}}};
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
