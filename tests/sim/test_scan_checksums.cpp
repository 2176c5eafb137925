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
  // Cast here, on this CPU, never read back from a scan cache (DCL_SCAN_CACHE).
  const SimWorld world(writeSimDataset(folder.string(), makePreset(expected.preset, options)),
                       {.scan_cache = false});
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
                        {0x0e39aad14b6f0e4fULL, 0xcad127a1988c4709ULL, 0x2913bfb903efa7b9ULL,
                         0x94bbd443c0d991faULL}},
      ExpectedChecksums{"kitti05-3",
                        {0x9df9694b0e8d5dccULL, 0xf1ffde601314a51aULL, 0xb3bb810d140b3dedULL,
                         0x4dbc004b5d187eacULL}},
      ExpectedChecksums{"kitti08-2",
                        {0x16750203e6da4a6bULL, 0x903ca88f63e34208ULL, 0x9b9d4a8ad38a9741ULL,
                         0x67634ade44d262e8ULL}},
      ExpectedChecksums{"campus-3",
                        {0x23f570cae6b606eaULL, 0x1b5347319ac593bbULL, 0xb513533c05ed07e0ULL,
                         0x045ba6d924b6ec91ULL}},
      ExpectedChecksums{"campus-9",
                        {0x2fe8355d193560fbULL, 0xe2992703654af1e1ULL, 0x3fd154b07df38f1aULL,
                         0xcb4fddb26d023f50ULL}},
      ExpectedChecksums{"aliasing-3",
                        {0x6d5154738872472fULL, 0xa5151da7b8418c25ULL, 0x852c78aefcbb9f43ULL,
                         0xcc53d4dfccb144e1ULL}},
      ExpectedChecksums{"crossing-2",
                        {0xb8bfe3c9c26812caULL, 0x02bcce3a9cb1e174ULL, 0x9735a79d99c72a8fULL,
                         0x58a1312b431c1107ULL}},
      ExpectedChecksums{"demo",
                        {0x7f778007fba88d6aULL, 0xa5a433f8bc7c0de1ULL, 0x1869df091a022baaULL,
                         0x6e4951b6e4e682e8ULL}},
      ExpectedChecksums{"small-3",
                        {0x007ee122f05a256dULL, 0xa5be3f67ecdba8f4ULL, 0xeac93834cca971d0ULL,
                         0x5024f50ef78356b3ULL}}};
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
