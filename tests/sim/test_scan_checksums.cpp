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
struct ExpectedChecksums {
  std::string preset;
  std::vector<std::uint64_t> checksums;  ///< first robot at 0, 1/2, 1; last robot at 1/3
};

void PrintTo(const ExpectedChecksums& expected, std::ostream* os) {
  *os << expected.preset;
}

class ScanChecksums : public ::testing::TestWithParam<ExpectedChecksums> {};

TEST_P(ScanChecksums, MatchTheCommittedValues) {
  const ExpectedChecksums& expected = GetParam();
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
const std::vector<ExpectedChecksums>& committed() {
  static const std::vector<ExpectedChecksums> table{
      ExpectedChecksums{"kitti00-3",
                        {0x5543b37ac17b08a4ULL, 0xafc6395625503240ULL, 0x4965d88fdadd1e7cULL,
                         0xa0305ea10e40ea8dULL}},
      ExpectedChecksums{"kitti05-3",
                        {0x7598e381c5c27d02ULL, 0x9019ef3febfe7cc5ULL, 0xc669887723d7ef61ULL,
                         0x348252ab6adb7a81ULL}},
      ExpectedChecksums{"kitti08-2",
                        {0x6ea4b6204598ac08ULL, 0x1d2d6bc53740cd1fULL, 0x6a655bc4f38616c8ULL,
                         0x20c9247f9a8e5e9aULL}},
      ExpectedChecksums{"campus-3",
                        {0xe6e1f12d5b3b4574ULL, 0x3a4d29bb24e19beaULL, 0x011252b403da85abULL,
                         0x178a434da78222f4ULL}},
      ExpectedChecksums{"campus-9",
                        {0x2419f6cbce0dd912ULL, 0x579e99dca92deb09ULL, 0x74e30ee2f391e2f2ULL,
                         0x613577fb3b857af0ULL}},
      ExpectedChecksums{"aliasing-3",
                        {0x5b82287c805c3562ULL, 0x86623afabb3ced60ULL, 0xa43ea67671f67284ULL,
                         0xca27fb2d4de91f37ULL}},
      ExpectedChecksums{"crossing-2",
                        {0xc5cf70d5b7258a4eULL, 0x284bd7734e6018e0ULL, 0x1072c1905b01e65bULL,
                         0x06e5cf5099b916fcULL}},
      ExpectedChecksums{"demo",
                        {0x3baad323ac8e9b0dULL, 0x1d4a1d9f6902a0faULL, 0xc73489176314d070ULL,
                         0x995d92570ebaa188ULL}},
      ExpectedChecksums{"small-3",
                        {0x231635b44c505f8bULL, 0xc0b77605de1337e2ULL, 0xd467830bb0e9947dULL,
                         0x0957d4692a5585a9ULL}}};
  return table;
}

TEST(ScanChecksums, EveryPresetHasItsEntry) {
  std::vector<std::string> listed;
  for (const ExpectedChecksums& e : committed()) listed.push_back(e.preset);
  std::vector<std::string> presets = presetNames();
  std::sort(listed.begin(), listed.end());
  std::sort(presets.begin(), presets.end());
  EXPECT_EQ(listed, presets);
}

INSTANTIATE_TEST_SUITE_P(Presets, ScanChecksums, ::testing::ValuesIn(committed()),
                         [](const ::testing::TestParamInfo<ExpectedChecksums>& info) {
                           std::string name = info.param.preset;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

}  // namespace
}  // namespace dcl::sim
