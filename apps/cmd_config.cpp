// `dcl-slam config --dump` and `dcl-slam version`.
#include <Eigen/Core>

#include <fmt/format.h>
#include <spdlog/version.h>

#include <dcl/io/config.hpp>
#include <dcl/version.hpp>

#include "commands.hpp"

namespace dcl::apps {

void addConfigCommand(CLI::App& app, const AppConfig& config) {
  auto* cmd = app.add_subcommand("config", "show the configuration");
  auto dump = std::make_shared<bool>(false);
  cmd->add_flag("--dump", *dump, "print the effective configuration (defaults + --config) as YAML");
  cmd->callback([dump, &config] {
    if (!*dump) {
      fmt::print("use `dcl-slam config --dump [--config FILE]` to print the configuration\n");
      return;
    }
    fmt::print("{}", io::dumpConfig(config));
  });
}

void addVersionCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("version", "print the version of dcl-slam and its libraries");
  cmd->callback([] {
    fmt::print("dcl-slam {}\n", kVersion);
    fmt::print("  Eigen {}.{}.{}, spdlog {}.{}.{}, fmt {}\n", EIGEN_WORLD_VERSION,
               EIGEN_MAJOR_VERSION, EIGEN_MINOR_VERSION, SPDLOG_VER_MAJOR, SPDLOG_VER_MINOR,
               SPDLOG_VER_PATCH, FMT_VERSION);
  });
}

}  // namespace dcl::apps
