#include "app_config.hpp"

#include <cstdlib>
#include <functional>

#include <dcl/core/error.hpp>
#include <dcl/core/log.hpp>
#include <dcl/eval/alignment.hpp>
#include <dcl/eval/rpe.hpp>

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
  checkField(source, "pcm.threshold", [&] {
    if (!(config.pcm.threshold > 0.0)) throw core::Error("must be positive");
  });
}

}  // namespace dcl::apps
