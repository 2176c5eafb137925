#pragma once

// A whole swarm run over the simulated radio and its outputs, shared by
// `dcl-slam run` and `dcl-slam demo` (cmd_run.cpp).

#include <cstddef>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app_config.hpp"

namespace dcl::apps {

/// Runs every robot of the dataset in `dataset` over the simulated radio
/// (scans per robot at most `max_frames`, 0: all; `threads` 0: every core;
/// on for `settle` s at most after the data while robots still optimise;
/// `leave` as `dcl-slam run --leave`: NAME@SECONDS, a robot that leaves the
/// swarm for good), writes the outputs into `out` and returns metrics.json.
nlohmann::ordered_json runSwarmDataset(const std::string& dataset, const std::string& out,
                                       std::size_t max_frames, int threads, double settle,
                                       const AppConfig& config,
                                       const std::vector<std::string>& leave = {});

/// The per-robot table of a run's metrics.
void printRunTable(const nlohmann::ordered_json& metrics, const std::string& out);

}  // namespace dcl::apps
