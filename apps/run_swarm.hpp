#pragma once

// A whole swarm run over the simulated radio and its outputs, shared by
// `dcl-slam run` and `dcl-slam demo` (cmd_run.cpp).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "app_config.hpp"

namespace dcl::apps {

/// `--viz PORT [--viz-wait S]`: the run served live to Foxglove (live_view.hpp).
struct VizOptions {
  std::optional<std::uint16_t> port;  ///< none: no live view
  double wait = 0.0;                  ///< s to wait for a first client before the run
};

/// Runs every robot of the dataset in `dataset` over the simulated radio
/// (scans per robot at most `max_frames`, 0: all; `threads` 0: every core;
/// on for `settle` s at most after the data while robots still optimise;
/// `leave` as `dcl-slam run --leave`: NAME@SECONDS, a robot that leaves the
/// swarm for good; `viz`: served live), writes the outputs into `out` and
/// returns metrics.json.
nlohmann::ordered_json runSwarmDataset(const std::string& dataset, const std::string& out,
                                       std::size_t max_frames, int threads, double settle,
                                       const AppConfig& config,
                                       const std::vector<std::string>& leave = {},
                                       const VizOptions& viz = {});

/// Adds --viz and --viz-wait to `cmd`.
void addVizOptions(CLI::App& cmd, VizOptions& viz);

/// The per-robot table of a run's metrics.
void printRunTable(const nlohmann::ordered_json& metrics, const std::string& out);

}  // namespace dcl::apps
