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
                        {0x833a60dfdb668ef3ULL, 0xfe6a7b5e156e4af8ULL, 0x67801eff61e7b19dULL,
                         0x941995f175e88227ULL}},
      ExpectedChecksums{"kitti05-3",
                        {0x19062e7058a053e7ULL, 0xc85fc735034d0a13ULL, 0x064c953b5a8131bbULL,
                         0x53fff1faea69a628ULL}},
      ExpectedChecksums{"kitti08-2",
                        {0x8419fcfcff21f67aULL, 0x5646143c71a1c216ULL, 0x7aaafd9c1ad968dfULL,
                         0x927b1dcced8b7f3dULL}},
      ExpectedChecksums{"campus-3",
                        {0xae45b6cb6eeb90a8ULL, 0x6b6d8538a3c33123ULL, 0x5cea7d98829aafb0ULL,
                         0xc3632d91060098ffULL}},
      ExpectedChecksums{"campus-9",
                        {0x13a1d5a792ea18edULL, 0xbb5c20de06202837ULL, 0xe0d579d08740a64dULL,
                         0x6a634062d60a97cfULL}},
      ExpectedChecksums{"aliasing-3",
                        {0x12b7605f99424cd7ULL, 0xb499f044e889137dULL, 0xf295b15fc37a031dULL,
                         0x9c0faa723937f5bfULL}},
      ExpectedChecksums{"crossing-2",
                        {0x6f33828a36efe1eeULL, 0xf2b99d6d183dc076ULL, 0x4daa901ec65f186dULL,
                         0xdc1ffdb770651b46ULL}},
      ExpectedChecksums{"demo",
                        {0xae4696216b4f7920ULL, 0xc44ce16dfa181033ULL, 0xeb37924c5db6766dULL,
                         0xa06d8e4e28a1b262ULL}},
      ExpectedChecksums{"small-3",
                        {0x30869213abbb57f7ULL, 0x48a099596f9ae075ULL, 0xfdae54642f44c9c7ULL,
                         0xa9b1ff884ec482baULL}}};
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
