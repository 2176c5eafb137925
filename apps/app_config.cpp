#include "app_config.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <utility>

#include <dcl/core/error.hpp>
#include <dcl/core/log.hpp>
#include <dcl/eval/alignment.hpp>
#include <dcl/eval/rpe.hpp>

#include "commands.hpp"

namespace dcl::apps {

namespace {

/// Runs `check`; a core::Error it raises is raised again naming the source and the key.
void checkField(const std::string& source, const char* key, const std::function<void()>& check) {
  try {
    check();
  } catch (const core::Error& e) {
    throw core::FileError({.path = source, .field = key}, e.what());
  }
}

}  // namespace

std::string defaultDataDir() {
  if (const char* env = std::getenv("DCL_DATA_DIR")) return env;
  return DCL_DEFAULT_DATA_DIR;
}

robot::RobotConfig robotConfig(const AppConfig& c) {
  robot::RobotConfig r;
  r.odometry = c.odometry;
  r.mapper = c.mapper;
  r.descriptor = c.place.descriptor;
  r.index = c.place.evaluation.index;
  r.verification = c.verification;
  r.pcm = c.pcm;
  r.loop_check = c.loop_check;
  r.messenger = c.messenger;
  r.dgs = c.dgs;
  r.dgs.max_rotation_iterations = std::min(r.dgs.max_rotation_iterations, c.robot.dgs_steps);
  r.dgs.max_pose_iterations = std::min(r.dgs.max_pose_iterations, c.robot.dgs_steps);
  r.refine = c.refine;
  r.refine.max_rounds = c.robot.refine_steps;
  r.candidate_spacing = static_cast<std::uint64_t>(std::max(c.robot.candidate_spacing, 1));
  r.loop_sigma_translation = c.robot.loop_sigma_translation;
  r.loop_sigma_rotation = c.robot.loop_sigma_rotation;
  r.loop_sigma_tilt = c.robot.loop_sigma_tilt;
  r.optimise_period = c.robot.optimise_period;
  r.round_timeout = c.robot.round_timeout;
  r.announce_period = c.robot.announce_period;
  r.solve_alone = c.robot.solve_alone;
  r.hold_absent = c.robot.hold_absent;
  return r;
}

void validate(const AppConfig& config, const std::string& source) {
  checkField(source, "log_level", [&] { core::setLogLevel(config.log_level); });
  const EvalSection& e = config.eval;
  checkField(source, "eval.alignment", [&] { eval::parseAlignment(e.alignment); });
  checkField(source, "eval.rpe_delta_unit", [&] { eval::parseDeltaUnit(e.rpe_delta_unit); });
  checkField(source, "eval.max_time_diff", [&] {
    if (!(e.max_time_diff >= 0.0)) throw core::Error("must be zero or positive");
  });
  checkField(source, "eval.rpe_delta", [&] {
    if (!(e.rpe_delta > 0.0)) throw core::Error("must be positive");
  });
  checkField(source, "eval.kitti_step", [&] {
    if (e.kitti_step < 1) throw core::Error("must be at least 1");
  });
  checkField(source, "eval.kitti_lengths", [&] {
    for (double length : e.kitti_lengths) {
      if (!(length > 0.0)) throw core::Error("every length must be positive");
    }
  });
  checkField(source, "verification", [&] { registration::validate(config.verification); });
  checkField(source, "refine", [&] { backend::validate(config.refine); });
  checkField(source, "messenger", [&] { comm::validate(config.messenger); });
  checkField(source, "radio", [&] { comm::validate(config.radio); });
  checkField(source, "dds", [&] { comm::validate(config.dds); });
  checkField(source, "map", [&] { swarm::validate(config.map); });
  checkField(source, "robot.candidate_spacing", [&] {
    if (config.robot.candidate_spacing < 1) throw core::Error("must be at least 1");
  });
  checkField(source, "robot.dgs_steps", [&] {
    if (config.robot.dgs_steps < 1) throw core::Error("must be at least 1");
  });
  checkField(source, "robot.refine_steps", [&] {
    if (config.robot.refine_steps < 0) throw core::Error("must be at least 0");
  });
  for (const auto& [key, value] :
       {std::pair{"robot.loop_sigma_translation", config.robot.loop_sigma_translation},
        std::pair{"robot.loop_sigma_rotation", config.robot.loop_sigma_rotation},
        std::pair{"robot.loop_sigma_tilt", config.robot.loop_sigma_tilt}}) {
    checkField(source, key, [value] {
      if (!(value >= 0.0) || !std::isfinite(value)) throw core::Error("must be finite and >= 0");
    });
  }
  for (const auto& [key, value] :
       {std::pair{"robot.optimise_period", config.robot.optimise_period},
        std::pair{"robot.round_timeout", config.robot.round_timeout},
        std::pair{"robot.announce_period", config.robot.announce_period}}) {
    checkField(source, key, [value] {
      if (!(value > 0.0) || !std::isfinite(value)) throw core::Error("must be a finite number > 0");
    });
  }
  checkField(source, "place.evaluation.index.distinct_ratio", [&] {
    const double r = config.place.evaluation.index.distinct_ratio;
    if (!(r > 0.0 && r <= 1.0)) throw core::Error("must be in (0, 1] (1: off)");
  });
  checkField(source, "place.evaluation.index.distinct_separation", [&] {
    const double d = config.place.evaluation.index.distinct_separation;
    if (!(d >= 0.0) || !std::isfinite(d)) throw core::Error("must be finite and >= 0");
  });
  checkField(source, "pcm.threshold", [&] {
    if (!(config.pcm.threshold > 0.0)) throw core::Error("must be positive");
  });
  checkField(source, "pcm.min_loops", [&] {
    if (config.pcm.min_loops == 0) throw core::Error("must be at least 1");
  });
  checkField(source, "loop_check.threshold", [&] {
    if (!(config.loop_check.threshold > 0.0)) throw core::Error("must be positive");
  });
}

io::DatasetReadOptions& datasetReadOptions() {
  static io::DatasetReadOptions options;
  return options;
}

}  // namespace dcl::apps
