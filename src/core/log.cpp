#include <string>

#include <spdlog/sinks/stdout_color_sinks.h>

#include <dcl/core/error.hpp>
#include <dcl/core/log.hpp>

namespace dcl::core {

void setLogLevel(std::string_view level) {
  const auto parsed = spdlog::level::from_str(std::string(level));
  // from_str answers "off" for any name it does not know.
  if (parsed == spdlog::level::off && level != "off") {
    throw Error("unknown log level '" + std::string(level) +
                "' (use trace, debug, info, warn, error or off)");
  }
  spdlog::set_level(parsed);
}

void setupLogging(std::string_view level) {
  auto logger = spdlog::stderr_color_mt("dcl");
  logger->set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
  spdlog::set_default_logger(logger);
  setLogLevel(level);
}

}  // namespace dcl::core
