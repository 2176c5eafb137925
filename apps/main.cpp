// dcl-slam: the one command of the project. Subcommands live in cmd_*.cpp.
#include <cstdio>
#include <exception>
#include <optional>
#include <string>
#include <string_view>

#include <dcl/core/error.hpp>
#include <dcl/core/log.hpp>
#include <dcl/io/config.hpp>

#include "app_config.hpp"
#include "commands.hpp"

namespace {

/// The value of `--name VALUE` or `--name=VALUE` in argv, if given (the last one wins).
std::optional<std::string> findOption(int argc, char** argv, std::string_view name) {
  std::optional<std::string> value;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == name && i + 1 < argc) value = argv[i + 1];
    if (arg.starts_with(name) && arg.size() > name.size() && arg[name.size()] == '=') {
      value = std::string(arg.substr(name.size() + 1));
    }
  }
  return value;
}

/// Reads `--config FILE` and `--log-level` before the subcommands parse, so that
/// their defaults come from the configuration and logging is set up first.
dcl::apps::AppConfig preloadConfig(int argc, char** argv) {
  dcl::apps::AppConfig config;
  if (const auto path = findOption(argc, argv, "--config")) {
    dcl::io::applyYaml(dcl::io::readConfigText(*path), config, *path);
  }
  if (const auto level = findOption(argc, argv, "--log-level")) config.log_level = *level;
  for (int i = 1; i < argc; ++i)
    if (std::string_view(argv[i]) == "--allow-outside-paths")
      dcl::apps::datasetReadOptions().allow_outside_paths = true;
  dcl::apps::validate(config, findOption(argc, argv, "--config").value_or("<defaults>"));
  dcl::core::setupLogging(config.log_level);
  return config;
}

int run(int argc, char** argv) {
  dcl::apps::AppConfig config = preloadConfig(argc, argv);
  CLI::App app{"dcl-slam: distributed collaborative LiDAR SLAM for robot swarms", "dcl-slam"};
  app.require_subcommand(1);
  app.fallthrough();  // global options may follow the subcommand
  // A refused option reads as every other error: one line.
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return std::string("dcl-slam: error: ") + e.what() + "\n";
  });
  std::string config_path;
  app.add_option("--config", config_path, "YAML configuration file (see `config --dump`)");
  std::string log_level = config.log_level;
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error or off");
  bool outside = false;
  app.add_flag("--allow-outside-paths", outside,
               "let datasets name ground truth and scans outside their own folder "
               "(absolute paths, or paths climbing out of it)");
  dcl::apps::addEvalCommand(app, config);
  dcl::apps::addConvertCommand(app);
  dcl::apps::addConfigCommand(app, config);
  dcl::apps::addVersionCommand(app);
  dcl::apps::addDemoCommand(app, config);
  dcl::apps::addSimulateCommand(app);
  dcl::apps::addOdometryCommand(app, config);
  dcl::apps::addPcmCommand(app, config);
  dcl::apps::addPgoCommand(app, config);
  dcl::apps::addPingCommand(app, config);
  dcl::apps::addRunCommand(app, config);
  dcl::apps::addRobotCommand(app, config);
  dcl::apps::addSwarmCommand(app, config);
  auto* bench = app.add_subcommand("bench", "benchmarks of the system's parts");
  bench->require_subcommand(1);
  dcl::apps::addBenchSimCommand(*bench);
  dcl::apps::addBenchOdometryCommand(*bench, config);
  dcl::apps::addBenchPlaceCommand(*bench, config);
  dcl::apps::addBenchLoopsCommand(*bench, config);
  dcl::apps::addBenchSystemCommand(*bench, config);
  dcl::apps::addBenchBoundCommand(*bench);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const dcl::core::Error& e) {
    std::fprintf(stderr, "dcl-slam: error: %s\n", e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dcl-slam: unexpected error: %s\n", e.what());
  }
  return 1;
}
