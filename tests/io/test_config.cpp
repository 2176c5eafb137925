#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/config.hpp>

#include "io_test_util.hpp"

namespace dcl::io {
namespace {

namespace fs = std::filesystem;

/// A nested section, as module configs nest theirs.
struct KeyframeConfig {
  double distance = 1.0;  // metres
  double angle = 0.2;     // radians

  template <class Visitor>
  void visit(Visitor& v) {
    v.field("distance", distance, "translation that makes a new keyframe, metres");
    v.field("angle", angle, "rotation that makes a new keyframe, radians");
  }

  bool operator==(const KeyframeConfig&) const = default;
};

/// Every supported field type once.
struct OdometryConfig {
  float voxel_size = 0.5f;                                     // metres
  int max_iterations = 30;                                     // ICP iterations
  std::int64_t offset = -7;                                    // anything signed
  std::uint32_t threads = 4;                                   // worker threads
  std::uint64_t seed = 42;                                     // random seed
  bool deskew = true;                                          // motion compensation
  double max_range = std::numeric_limits<double>::infinity();  // metres
  std::string name = "kiss";                                   // label
  std::vector<double> ranges = {1.0, 2.5};                     // metres
  std::vector<std::string> topics = {"/points"};               // ROS topics
  Eigen::Vector3d gravity = Eigen::Vector3d(0, 0, -9.81);      // m/s^2
  KeyframeConfig keyframes{};                                  // keyframe selection

  template <class Visitor>
  void visit(Visitor& v) {
    v.field("voxel_size", voxel_size, "voxel edge of the local map, metres");
    v.field("max_iterations", max_iterations, "ICP iterations at most");
    v.field("offset", offset, "a signed 64-bit value");
    v.field("threads", threads, "worker threads");
    v.field("seed", seed, "random seed");
    v.field("deskew", deskew, "compensate motion within a sweep");
    v.field("max_range", max_range, "points further away are dropped, metres");
    v.field("name", name, "a label\nover two lines");
    v.field("ranges", ranges, "range bins, metres");
    v.field("topics", topics, "topics to read");
    v.field("gravity", gravity, "gravity in the world frame, m/s^2");
    v.section("keyframes", keyframes);
  }

  bool operator==(const OdometryConfig&) const = default;
};

struct RootConfig {
  OdometryConfig odometry{};  // the front-end
  std::string dataset = "";   // dataset.yaml path

  template <class Visitor>
  void visit(Visitor& v) {
    v.section("odometry", odometry, "LiDAR odometry");
    v.field("dataset", dataset, "dataset folder");
  }

  bool operator==(const RootConfig&) const = default;
};

TEST(Config, OverridesOnlyTheKeysGiven) {
  RootConfig config;
  applyYaml("odometry:\n  voxel_size: 0.25\n  keyframes:\n    angle: 0.1\n", config, "test.yaml");
  RootConfig expected;
  expected.odometry.voxel_size = 0.25f;
  expected.odometry.keyframes.angle = 0.1;
  EXPECT_EQ(config, expected);
}

TEST(Config, ReadsEveryFieldType) {
  RootConfig config;
  applyYaml(R"(
dataset: runs/kitti
odometry:
  voxel_size: 1e-1
  max_iterations: -3
  offset: -9000000000
  threads: 4294967295
  seed: 18446744073709551615
  deskew: False
  max_range: -.inf
  name: "tab\there"
  ranges: []
  topics: [a, "b c"]
  gravity: [1, 2, 3.5]
)",
            config, "test.yaml");
  const OdometryConfig& o = config.odometry;
  EXPECT_EQ(config.dataset, "runs/kitti");
  EXPECT_EQ(o.voxel_size, 0.1f);
  EXPECT_EQ(o.max_iterations, -3);
  EXPECT_EQ(o.offset, -9000000000);
  EXPECT_EQ(o.threads, 4294967295u);
  EXPECT_EQ(o.seed, 18446744073709551615ull);
  EXPECT_FALSE(o.deskew);
  EXPECT_EQ(o.max_range, -std::numeric_limits<double>::infinity());
  EXPECT_EQ(o.name, "tab\there");
  EXPECT_TRUE(o.ranges.empty());
  EXPECT_EQ(o.topics, (std::vector<std::string>{"a", "b c"}));
  EXPECT_EQ(o.gravity, Eigen::Vector3d(1, 2, 3.5));
  EXPECT_EQ(o.keyframes, KeyframeConfig{});
}

TEST(Config, EmptySectionAndExplicitEmptyMappingMeanDefaults) {
  RootConfig config;
  applyYaml("odometry:\n", config, "a.yaml");
  applyYaml("{}", config, "b.yaml");
  applyYaml("odometry: {keyframes: {}}\n", config, "c.yaml");
  EXPECT_EQ(config, RootConfig{});
}

/// A bad document and what its error must say.
struct Bad {
  std::string name;
  std::string yaml;
  std::vector<std::string> expected;
};

std::vector<Bad> badDocuments() {
  return {
      {"unknown_key",
       "odometry:\n  voxel_sise: 1\n",
       {"test.yaml:2:", "field 'odometry.voxel_sise'", "unknown key",
        "voxel_size, max_iterations"}},
      {"unknown_nested",
       "odometry:\n  keyframes:\n    angel: 1\n",
       {":3:", "odometry.keyframes.angel"}},
      {"unknown_top", "# c\ndatset: x\n", {":2:", "field 'datset'", "unknown key"}},
      {"twice", "dataset: a\ndataset: b\n", {":2:", "field 'dataset'", "twice"}},
      {"quoted_number",
       "odometry:\n  voxel_size: \"0.5\"\n",
       {":2:", "expected a number", "quoted"}},
      {"word_for_double", "odometry:\n  max_range: far\n", {":2:", "odometry.max_range", "'far'"}},
      {"fraction_for_int",
       "odometry:\n  max_iterations: 1.5\n",
       {":2:", "expected an integer", "'1.5'"}},
      {"int_overflow", "odometry:\n  max_iterations: 3000000000\n", {":2:", "2147483647"}},
      {"negative_unsigned", "odometry:\n  threads: -1\n", {":2:", "non-negative integer", "'-1'"}},
      {"negative_u64", "odometry:\n  seed: -5\n", {":2:", "odometry.seed", "non-negative"}},
      {"float_overflow", "odometry:\n  voxel_size: 1e300\n", {":2:", "odometry.voxel_size"}},
      {"nan", "odometry:\n  keyframes:\n    angle: .nan\n", {":3:", "angle", "expected a number"}},
      {"nan_word", "odometry:\n  max_range: nan\n", {":2:", "NaN"}},
      {"sequence_for_double", "odometry:\n  max_range: [1]\n", {":2:", "found a sequence"}},
      {"mapping_for_double", "odometry:\n  max_range: {a: 1}\n", {":2:", "found a mapping"}},
      {"null_double",
       "odometry:\n  max_range:\n  deskew: true\n",
       {":2:", "odometry.max_range", "no value"}},
      {"null_string", "dataset:\n", {":1:", "field 'dataset'", "no value"}},
      {"null_list_item",
       "odometry:\n  ranges:\n    - 1\n    -\n",
       {":2:", "ranges[1]", "no value"}},
      {"yes_for_bool", "odometry:\n  deskew: yes\n", {":2:", "true or false", "'yes'"}},
      {"string_for_bool", "odometry:\n  deskew: \"true\"\n", {":2:", "quoted"}},
      {"scalar_for_list", "odometry:\n  ranges: 3\n", {":2:", "expected a sequence"}},
      {"bad_list_item", "odometry:\n  ranges: [1, x]\n", {":2:", "odometry.ranges[1]", "'x'"}},
      {"nested_list_item", "odometry:\n  topics: [a, [b]]\n", {":2:", "odometry.topics[1]"}},
      {"short_vector", "odometry:\n  gravity: [0, -9.81]\n", {":2:", "sequence of 3 numbers"}},
      {"scalar_section", "odometry: 3\n", {":1:", "field 'odometry'", "expected a mapping"}},
      {"list_top", "- a\n- b\n", {":1:", "top level"}},
      {"malformed_flow", "odometry:\n  ranges: [1, 2\n", {"malformed YAML"}},
      {"malformed_indent",
       "odometry:\n  voxel_size: 1\n keyframes: 2\n",
       {":3:", "malformed YAML"}},
      {"malformed_colon", "dataset: a: b\n", {":1:", "malformed YAML"}},
      {"empty", "", {":1:", "no settings"}},
      {"comments_only", "# all defaults\n", {":1:", "no settings"}},
  };
}

TEST(Config, RejectsBadDocumentsNamingLineAndKey) {
  for (const auto& bad : badDocuments()) {
    RootConfig config;
    config.odometry.max_iterations = 99;
    const std::string message = test::fileError([&] { applyYaml(bad.yaml, config, "test.yaml"); });
    EXPECT_EQ(message.rfind("test.yaml", 0), 0u) << bad.name << ": " << message;
    for (const auto& part : bad.expected) {
      EXPECT_NE(message.find(part), std::string::npos) << bad.name << ": " << message;
    }
    // All or nothing: a failed load leaves the config as it was.
    EXPECT_EQ(config.odometry.max_iterations, 99) << bad.name;
    EXPECT_EQ(config.odometry.voxel_size, 0.5f) << bad.name;
  }
}

RootConfig unusualConfig() {
  RootConfig config;
  OdometryConfig& o = config.odometry;
  o.voxel_size = 0.1f;
  o.max_iterations = std::numeric_limits<int>::min();
  o.offset = std::numeric_limits<std::int64_t>::max();
  o.threads = 0;
  o.seed = std::numeric_limits<std::uint64_t>::max();
  o.deskew = false;
  o.max_range = 1.0 / 3.0;
  o.name = "quote \" backslash \\ newline \n tab \t bell \a colon: hash # utf8 \xc3\xa9";
  o.ranges = {1e-300, -0.0, 123456789.125, std::numeric_limits<double>::infinity()};
  o.topics = {"", "a, b", "[x]", "null", "true", "- dash"};
  o.gravity = Eigen::Vector3d(0.1, 0.2, 0.30000000000000004);
  o.keyframes.distance = 5e-324;
  config.dataset = "";
  return config;
}

TEST(Config, DumpLoadsBackToTheSameValues) {
  for (const RootConfig& original : {RootConfig{}, unusualConfig()}) {
    const std::string text = dumpConfig(original);
    RootConfig loaded;
    loaded.odometry.threads = 77;  // must be overwritten by the dump
    applyYaml(text, loaded, "dump.yaml");
    EXPECT_EQ(loaded, original) << text;
    EXPECT_EQ(dumpConfig(loaded), text);
  }
}

TEST(Config, DumpCommentsEveryField) {
  const std::string text = dumpConfig(RootConfig{});
  EXPECT_NE(text.find("# LiDAR odometry\nodometry:\n"), std::string::npos) << text;
  EXPECT_NE(text.find("  # voxel edge of the local map, metres\n  voxel_size: 0.5\n"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("  # a label\n  # over two lines\n  name: \"kiss\"\n"), std::string::npos)
      << text;
  EXPECT_NE(text.find("  max_range: .inf\n"), std::string::npos) << text;
  EXPECT_NE(text.find("  gravity: [0, 0, -9.81]\n"), std::string::npos) << text;
  EXPECT_NE(text.find("  keyframes:\n    # translation that makes a new keyframe, metres\n"
                      "    distance: 1\n"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("\n# dataset folder\ndataset: \"\"\n"), std::string::npos) << text;
}

TEST(Config, LoadsFromFile) {
  const test::TempDir dir;
  const std::string path = dir.write("config.yaml", "odometry:\n  threads: 8\n");
  RootConfig config;
  loadConfig(path, config);
  EXPECT_EQ(config.odometry.threads, 8u);

  std::ofstream(path, std::ios::trunc) << "odometry:\n  threads: eight\n";
  const std::string message = test::fileError([&] { loadConfig(path, config); });
  EXPECT_NE(message.find(path + ":2: field 'odometry.threads'"), std::string::npos) << message;
  EXPECT_EQ(config.odometry.threads, 8u);

  const std::string missing = dir.file("missing.yaml");
  EXPECT_NE(test::fileError([&] { loadConfig(missing, config); }).find(missing), std::string::npos);
}

TEST(Config, TruncatedDumpLoadsOrFailsCleanly) {
  const std::string text = dumpConfig(unusualConfig());
  std::size_t failures = 0;
  for (std::size_t cut = 0; cut <= text.size(); ++cut) {
    RootConfig config;
    try {
      applyYaml(text.substr(0, cut), config, "cut.yaml");
    } catch (const core::FileError& e) {
      ++failures;
      ASSERT_EQ(std::string(e.what()).rfind("cut.yaml", 0), 0u) << e.what();
    }
  }
  EXPECT_GT(failures, 0u);
}

// ---- rules ----------------------------------------------------------------------

/// A section whose fields carry rules, one of each kind, and one rule across fields.
struct RangeConfig {
  double min_range = 1.0;   // metres
  double max_range = 50.0;  // metres
  int rows = 8;             // bins
  std::string kind = "a";   // one of a few names

  template <class Visitor>
  void visit(Visitor& v) {
    v.field("max_range", max_range, "farthest, metres").positive();
    v.field("min_range", min_range, "nearest, metres")
        .nonNegative()
        .lessThan(max_range, "max_range");
    v.field("rows", rows, "bins").within(1, 64).rule(rows % 2 == 0, "must be even");
    v.field("kind", kind, "a | b").oneOf({"a", "b"});
  }

  bool operator==(const RangeConfig&) const = default;
};

struct RuledConfig {
  RangeConfig range{};
  double rate = 0.5;  // a share
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();

  template <class Visitor>
  void visit(Visitor& v) {
    v.section("range", range, "a range");
    v.field("rate", rate, "a share").within(0.0, 1.0, core::Interval::open_high);
    v.field("axis", axis, "a direction").rule(axis.norm() > 0.0, "must not be zero");
  }

  bool operator==(const RuledConfig&) const = default;
};

/// The FileError of loading `yaml` into a RuledConfig.
core::FileError ruleError(const std::string& yaml) {
  RuledConfig config;
  try {
    applyYaml(yaml, config, "rules.yaml");
  } catch (const core::FileError& e) {
    EXPECT_EQ(config, RuledConfig{}) << "a refused document changed the config";
    return e;
  }
  ADD_FAILURE() << "no error for:\n" << yaml;
  return core::FileError({}, "");
}

TEST(ConfigRules, NameTheFieldItsLineTheRuleAndTheValue) {
  struct Case {
    std::string yaml;
    std::size_t line;
    std::string key;
    std::string what;
  };
  const std::vector<Case> cases = {
      {"range:\n  rows: 0\n", 2, "range.rows", "must be in [1, 64], found 0"},
      {"range:\n  rows: 7\n", 2, "range.rows", "must be even, found 7"},
      {"range:\n  kind: c\n", 2, "range.kind", "must be one of a, b, found \"c\""},
      {"range:\n  max_range: -1\n", 2, "range.max_range", "must be greater than 0, found -1"},
      {"range:\n  max_range: .inf\n", 2, "range.max_range",
       "must be finite and greater than 0, found .inf"},
      {"range:\n  min_range: 60\n", 2, "range.min_range",
       "must be less than max_range (50), found 60"},
      {"range: {min_range: 5, max_range: 4}\n", 1, "range.min_range",
       "must be less than max_range (4), found 5"},
      {"rate: 1\n", 1, "rate", "must be in [0, 1), found 1"},
      {"axis: [0, 0, 0]\n", 1, "axis", "must not be zero, found [0, 0, 0]"},
  };
  for (const Case& c : cases) {
    const core::FileError e = ruleError(c.yaml);
    EXPECT_EQ(e.location().path, "rules.yaml") << c.yaml;
    EXPECT_EQ(e.location().line, c.line) << c.yaml;
    EXPECT_EQ(e.location().field, c.key) << c.yaml;
    EXPECT_NE(std::string(e.what()).find(c.what), std::string::npos) << e.what();
  }
}

TEST(ConfigRules, ADefaultBrokenByAnotherFieldIsBlamedOnThatFieldsLine) {
  // min_range keeps its default (1); the file's max_range (0.5) breaks its rule.
  const core::FileError e = ruleError("# c\nrange:\n  rows: 4\n  max_range: 0.5\n");
  EXPECT_EQ(e.location().line, 4u);
  EXPECT_EQ(e.location().field, "range.min_range");
  EXPECT_NE(std::string(e.what()).find("must be less than max_range (0.5), found 1 (the default; "
                                       "max_range is set on line 4)"),
            std::string::npos)
      << e.what();
}

TEST(ConfigRules, TheFirstBrokenRuleInVisitingOrderWins) {
  const core::FileError e = ruleError("rate: 2\nrange:\n  kind: z\n  rows: 0\n");
  EXPECT_EQ(e.location().field, "range.rows");
  EXPECT_EQ(e.location().line, 4u);
}

TEST(ConfigRules, TheDumpWritesEachRuleBesideItsField) {
  const std::string text = dumpConfig(RuledConfig{});
  EXPECT_NE(text.find("  # nearest, metres\n"
                      "  # must be at least 0; must be less than max_range (50)\n"
                      "  min_range: 1\n"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("  # must be in [1, 64]; must be even\n  rows: 8\n"), std::string::npos)
      << text;
  EXPECT_NE(text.find("# must be in [0, 1)\nrate: 0.5\n"), std::string::npos) << text;
  RuledConfig loaded;
  loaded.rate = 0.25;
  applyYaml(text, loaded, "dump.yaml");
  EXPECT_EQ(loaded, RuledConfig{});
  EXPECT_EQ(dumpConfig(loaded), text);
}

TEST(ConfigRules, ACheckerRefusesAStructBuiltInCode) {
  EXPECT_FALSE(core::firstViolation(RuledConfig{}));
  RuledConfig config;
  config.range.min_range = 70.0;
  config.rate = -1.0;
  const auto violation = core::firstViolation(config);
  ASSERT_TRUE(violation);
  EXPECT_EQ(violation->key, "range.min_range");
  EXPECT_EQ(violation->rule, "must be less than max_range (50)");
  EXPECT_EQ(violation->value, "70");
  try {
    core::checkConfig(config, "ruled config");
    ADD_FAILURE() << "no error";
  } catch (const core::Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "ruled config: field 'range.min_range': must be less than max_range (50), found 70");
  }
}

}  // namespace
}  // namespace dcl::io
