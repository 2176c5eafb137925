#include "app_config.hpp"

#include <algorithm>
#include <cstdlib>

#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>

#include "commands.hpp"

namespace dcl::apps {

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
  if (const auto violation = core::firstViolation(config)) {
    throw core::FileError({.path = source, .field = violation->key},
                          violation->rule + ", found " + violation->value);
  }
}

io::DatasetReadOptions& datasetReadOptions() {
  static io::DatasetReadOptions options;
  return options;
}

std::string named(std::string name, const std::string& robot) {
  constexpr std::string_view kTag = "{robot}";
  for (std::size_t at = name.find(kTag); at != std::string::npos; at = name.find(kTag, at)) {
    name.replace(at, kTag.size(), robot);
    at += robot.size();
  }
  return name;
}

}  // namespace dcl::apps
