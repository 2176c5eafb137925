#pragma once

/// Logging: the project logs through spdlog (`spdlog::info(...)` and friends);
/// this header only sets it up the same way for every program.

#include <string_view>

#include <spdlog/spdlog.h>

namespace dcl::core {

/// Sets the global log level from a name: trace, debug, info, warn, error, off.
/// Throws dcl::core::Error naming the accepted names for anything else.
void setLogLevel(std::string_view level);

/// Logs to stderr with a compact pattern ("[12:00:01.234] [warn] text") at `level`.
void setupLogging(std::string_view level = "info");

}  // namespace dcl::core
