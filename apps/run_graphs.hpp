#pragma once

// The outputs of a run that `bench bound`, `bench noise` and `bench system`
// evaluate (eval/bound.hpp, eval/factor_noise.hpp): every robot's
// graph.g2o and trajectory.tum, the dataset's ground truth, and which robots
// the run's metrics.json says left mid-run.

#include <string>
#include <vector>

#include <dcl/eval/run_graph.hpp>

namespace dcl::apps {

/// Every robot of the run in folder `run` (outputs of `dcl-slam run`) of the
/// dataset in folder `dataset`: its own keyframes from graph.g2o with every
/// factor, their stamps from trajectory.tum, the ground truth at each. Throws
/// core::Error naming the file for a missing or inconsistent output.
std::vector<eval::RobotGraph> readRunGraphs(const std::string& run, const std::string& dataset);

/// Marks the robots the run's metrics.json says left mid-run (`left_at_s`);
/// none when the run has no metrics.json (the outputs of `dcl-slam robot`).
/// Throws core::FileError for a metrics.json that is not a run's.
void readRobotsThatLeft(const std::string& run, std::vector<eval::RobotGraph>& robots);

}  // namespace dcl::apps
