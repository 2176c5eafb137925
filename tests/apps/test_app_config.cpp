// The whole program's configuration: every module's rules, read from YAML as
// `dcl-slam --config FILE` reads them, and the same rules where each module
// checks the config it is given in code.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/config.hpp>
#include <dcl/place/descriptor_codec.hpp>
#include <dcl/registration/cloud_codec.hpp>
#include <dcl/registration/gicp.hpp>

#include "app_config.hpp"

namespace dcl::apps {
namespace {

/// A document with one bad value, and what the error must say of it.
struct BadValue {
  std::string name;
  std::string yaml;
  std::size_t line;
  std::string key;
  std::string rule;
  std::string value;
};

/// One bad value of each class of rule.
std::vector<BadValue> badValues() {
  return {
      {"count_zero", "place:\n  descriptor:\n    iris:\n      rows: 0\n", 4,
       "place.descriptor.iris.rows", "must be in [1, 1024]", "0"},
      {"count_odd", "place:\n  descriptor:\n    iris:\n      columns: 361\n", 4,
       "place.descriptor.iris.columns", "must be even", "361"},
      {"unknown_kind", "place:\n  descriptor:\n    kind: sift\n", 3, "place.descriptor.kind",
       "must be one of iris, scancontext", "\"sift\""},
      {"negative_iterations", "dgs:\n  max_rotation_iterations: -5\n", 2,
       "dgs.max_rotation_iterations", "must be at least 1", "-5"},
      {"zero_icp_iterations", "odometry:\n  icp:\n    max_iterations: 0\n", 3,
       "odometry.icp.max_iterations", "must be at least 1", "0"},
      {"zero_voxel", "verification:\n  voxel_size: 0\n", 2, "verification.voxel_size",
       "must be in [0.01, 100]", "0"},
      {"negative_voxel", "mapper:\n  keyframes:\n    voxel_size: -0.5\n", 3,
       "mapper.keyframes.voxel_size", "must be in [0.01, 100]", "-0.5"},
      {"map_voxel", "map:\n  voxel: 0.01\n", 2, "map.voxel", "must be 0 (no map) or in [0.05, 20]",
       "0.01"},
      {"negative_range", "radio:\n  range: -1\n", 2, "radio.range", "must be at least 0", "-1"},
      {"ranges_out_of_order", "odometry:\n  min_range: 150\n  max_range: 120\n", 2,
       "odometry.min_range", "must be less than max_range (120)", "150"},
      {"default_out_of_order", "odometry:\n  max_range: 1.5\n", 2, "odometry.min_range",
       "must be less than max_range (1.5)", "2 (the default; max_range is set on line 2)"},
      {"default_above_rows", "place:\n  descriptor:\n    iris:\n      rows: 5\n", 4,
       "place.descriptor.iris.shift_bands", "must be at most rows (5)",
       "10 (the default; rows is set on line 4)"},
      {"timeout_below_period", "messenger:\n  heartbeat_period: 5\n", 2,
       "messenger.neighbour_timeout", "must be greater than heartbeat_period (5)",
       "3.5 (the default; heartbeat_period is set on line 2)"},
      {"unknown_loss", "mapper:\n  solver:\n    loop_loss: squiggle\n", 3,
       "mapper.solver.loop_loss", "must be one of none, huber, cauchy", "\"squiggle\""},
      {"unknown_initialisation", "mapper:\n  solver:\n    initialisation: psychic\n", 3,
       "mapper.solver.initialisation", "must be one of as_is, chordal", "\"psychic\""},
      {"confidence_above_one", "verification:\n  ransac:\n    confidence: 1.5\n", 3,
       "verification.ransac.confidence", "must be in (0, 1)", "1.5"},
      {"negative_threads", "mapper:\n  solver:\n    threads: -4\n", 3, "mapper.solver.threads",
       "must be in [1, 256]", "-4"},
      {"zero_quaternion", "external:\n  T_body_sensor: [0, 0, 0, 0, 0, 0, 0]\n", 2,
       "external.T_body_sensor", "must be finite, with a unit quaternion", "[0, 0, 0, 0, 0, 0, 0]"},
      {"infinite_period", "messenger:\n  heartbeat_period: .inf\n", 2, "messenger.heartbeat_period",
       "must be finite and greater than 0", ".inf"},
      {"share_above_one", "radio:\n  drop_rate: 1\n", 2, "radio.drop_rate", "must be in [0, 1)",
       "1"},
      {"unknown_log_level", "log_level: loud\n", 1, "log_level",
       "must be one of trace, debug, info, warn, error, off", "\"loud\""},
      {"unknown_alignment", "eval:\n  alignment: affine\n", 2, "eval.alignment",
       "must be one of none, se3, sim3", "\"affine\""},
      {"fractional_frames", "eval:\n  rpe_delta: 2.5\n", 2, "eval.rpe_delta",
       "must be a whole number of frames when rpe_delta_unit is frames", "2.5"},
      {"negative_length", "eval:\n  kitti_lengths: [100, -1]\n", 2, "eval.kitti_lengths",
       "must hold positive finite lengths", "[100, -1]"},
      {"no_icp_distance", "mapper:\n  loops:\n    icp_distances: []\n", 3,
       "mapper.loops.icp_distances", "must hold at least one distance", "[]"},
      {"too_many_candidates", "place:\n  evaluation:\n    index:\n      candidates: 100000000\n", 4,
       "place.evaluation.index.candidates", "must be in [1, 1000]", "100000000"},
      {"wildcard_swarm", "dds:\n  swarm: \"*\"\n", 2, "dds.swarm",
       "must be 1..64 letters, digits or", "\"*\""},
      {"bag_without_topic", "external:\n  file: run.bag\n", 2, "external.topic",
       "must be given to read a bag", "\"\" (the default; file is set on line 2)"},
      {"zero_steps", "robot:\n  dgs_steps: 0\n", 2, "robot.dgs_steps", "must be at least 1", "0"},
  };
}

TEST(AppConfig, RefusesABadValueOfEachRuleNamingFileLineKeyRuleAndValue) {
  for (const BadValue& bad : badValues()) {
    AppConfig config;
    try {
      io::applyYaml(bad.yaml, config, "bad.yaml");
      ADD_FAILURE() << bad.name << ": no error";
    } catch (const core::FileError& e) {
      const std::string expected =
          "bad.yaml:" + std::to_string(bad.line) + ": field '" + bad.key + "': " + bad.rule;
      EXPECT_EQ(std::string(e.what()).rfind(expected, 0), 0u) << bad.name << ": " << e.what();
      EXPECT_NE(std::string(e.what()).find(", found " + bad.value), std::string::npos)
          << bad.name << ": " << e.what();
      EXPECT_EQ(e.location().line, bad.line) << bad.name;
      EXPECT_EQ(e.location().field, bad.key) << bad.name;
    }
  }
}

TEST(AppConfig, DefaultsMeetEveryRule) {
  const auto violation = core::firstViolation(AppConfig{});
  EXPECT_FALSE(violation) << core::describe(*violation);
  // Module configs the program's sections do not hold.
  EXPECT_FALSE(core::firstViolation(registration::GicpConfig{}));
  EXPECT_FALSE(core::firstViolation(registration::CloudCodecConfig{}));
  EXPECT_FALSE(core::firstViolation(place::IrisCodecConfig{}));
  EXPECT_NO_THROW(robot::validate(robotConfig(AppConfig{})));
}

TEST(AppConfig, TheDumpReadsBackUnchangedAndDocumentsTheRules) {
  const std::string dump = io::dumpConfig(AppConfig{});
  EXPECT_NE(dump.find("      # radial bins (paper: 80)\n      # must be in [1, 1024]\n"
                      "      rows: 80\n"),
            std::string::npos)
      << dump;
  AppConfig loaded;
  loaded.odometry.max_range = 50.0;
  io::applyYaml(dump, loaded, "dump.yaml");
  EXPECT_EQ(io::dumpConfig(loaded), dump);
}

TEST(AppConfig, ValidateNamesTheSourceForValuesSetAfterTheFile) {
  AppConfig config;
  config.log_level = "loud";  // as --log-level sets it
  try {
    validate(config, "run.yaml");
    ADD_FAILURE() << "no error";
  } catch (const core::FileError& e) {
    EXPECT_EQ(std::string(e.what()),
              "run.yaml: field 'log_level': must be one of trace, debug, info, warn, error, off, "
              "found \"loud\"");
  }
}

TEST(AppConfig, ModulesRefuseTheSameValuesWhenGivenThemInCode) {
  backend::SolverConfig solver;
  solver.loop_loss = "squiggle";
  EXPECT_THROW(backend::validate(solver), core::Error);
  backend::PoseGraph graph;
  EXPECT_THROW(backend::solveCentralized(graph, solver), core::Error);
  registration::CloudCodecConfig codec;
  codec.zstd_level = 40;
  EXPECT_THROW(registration::validate(codec), core::Error);
  place::IrisCodecConfig iris_codec;
  iris_codec.zstd_level = 0;
  EXPECT_THROW(place::validate(iris_codec), core::Error);
  robot::RobotConfig node = robotConfig(AppConfig{});
  node.index.candidates = 0;
  try {
    robot::validate(node);
    ADD_FAILURE() << "no error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("field 'candidates': must be in [1, 1000], found 0"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace dcl::apps
