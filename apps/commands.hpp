#pragma once

/// The subcommands of `dcl-slam`. Each `add*Command` registers one subcommand
/// (with its options and its callback) on the main CLI11 app.

#include <CLI/CLI.hpp>

#include <dcl/io/dataset.hpp>

#include "app_config.hpp"

namespace dcl::apps {

/// What a dataset may name, for every command of this process: set once from
/// `--allow-outside-paths` before the commands run.
io::DatasetReadOptions& datasetReadOptions();

/// `eval ate`, `eval rpe`: trajectory metrics, evo-compatible.
void addEvalCommand(CLI::App& app, const AppConfig& config);

/// `convert`: between the scan formats (KITTI .bin, PCD, PLY, ROS1 bag and MCAP
/// topics) and the pose formats (KITTI, TUM, ROS1 bag and MCAP topics).
void addConvertCommand(CLI::App& app);

/// `config --dump`: the effective configuration as YAML.
void addConfigCommand(CLI::App& app, const AppConfig& config);

/// `version`: the program's and its main libraries' versions.
void addVersionCommand(CLI::App& app);

/// `demo`: the built-in default run.
void addDemoCommand(CLI::App& app, const AppConfig& config);

/// `simulate`: a simulated dataset from a preset (`--export` kitti, bag or mcap), or `--preview` of
/// one.
void addSimulateCommand(CLI::App& app);

/// `bench sim` (on the `bench` subcommand): the scan stream of a dataset, timed.
void addBenchSimCommand(CLI::App& bench);

/// `bench sensor`: real LiDAR sweeps' statistics beside a simulated dataset's (cmd_sensor.cpp).
void addBenchSensorCommand(CLI::App& bench);

/// `odometry`: one robot's front-end alone.
void addOdometryCommand(CLI::App& app, const AppConfig& config);

/// `bench odometry`: the LiDAR odometry's time per frame over a whole sequence.
void addBenchOdometryCommand(CLI::App& bench, const AppConfig& config);

/// `bench place`: inter-robot place recognition on a dataset (precision-recall).
void addBenchPlaceCommand(CLI::App& bench, const AppConfig& config);

/// `pcm`: PCM outlier rejection of a multi-robot graph's inter-robot loops (cmd_pcm.cpp).
void addPcmCommand(CLI::App& app, const AppConfig& config);

/// `pgo`: pose-graph optimisation, distributed (DGS, refinement) or centralized (cmd_pgo.cpp).
void addPgoCommand(CLI::App& app, const AppConfig& config);

/// `ping`: joins a swarm over Cyclone DDS as one robot and checks who hears
/// whom, and that test broadcasts arrive exactly once (cmd_ping.cpp).
void addPingCommand(CLI::App& app, const AppConfig& config);

/// `run`: every robot of a dataset in one process over the simulated radio.
void addRunCommand(CLI::App& app, const AppConfig& config);

/// `bench loops`: the inter-robot loop pipeline end to end, graded by ground truth (cmd_loops.cpp).
void addBenchLoopsCommand(CLI::App& bench, const AppConfig& config);

/// `robot`: one robot of a dataset in this process over Cyclone DDS (cmd_robot.cpp).
void addRobotCommand(CLI::App& app, const AppConfig& config);

/// `dcl-slam play`: a dataset robot's scans published on ROS 2 as its LiDAR driver would.
void addPlayCommand(CLI::App& app, const AppConfig& config);

/// `swarm`: starts one `robot` process per robot of a dataset on this machine,
/// waits for them and evaluates their outputs together (cmd_swarm.cpp).
void addSwarmCommand(CLI::App& app, const AppConfig& config);

/// `bench system`: the paper's experiments (its Tables II-V and the 9-robot
/// run) on simulated datasets (cmd_system.cpp).
void addBenchSystemCommand(CLI::App& bench, const AppConfig& config);

/// `bench bound` (a run's ATE beside its joint graph's optimum and
/// that optimum with exact loops) and `bench noise` (its factors' covariances
/// against their errors), cmd_bound.cpp.
void addBenchBoundCommand(CLI::App& bench);

}  // namespace dcl::apps
