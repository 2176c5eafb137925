// dcl-slam: the one command of the project. Subcommands live in cmd_*.cpp.
#include <cstdio>
#include <exception>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include <dcl/core/error.hpp>
#include <dcl/core/log.hpp>
#include <dcl/io/config.hpp>

#include "app_config.hpp"
#include "commands.hpp"
#include "output_folder.hpp"

namespace {

/// `text` safe for a terminal on one line: control characters, and bytes that
/// are not UTF-8 (a binary file's content quoted in a message), as \xNN.
std::string printable(std::string_view text) {
  std::string out;
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    std::size_t length = c < 0x80           ? 1
                         : (c >> 5) == 0x6  ? 2
                         : (c >> 4) == 0xe  ? 3
                         : (c >> 3) == 0x1e ? 4
                                            : 0;
    for (std::size_t k = 1; k < length; ++k) {
      if (i + k >= text.size() || (static_cast<unsigned char>(text[i + k]) >> 6) != 0x2) length = 0;
    }
    if (c == '\n' || c == '\t') {  // a message of several lines reads on one
      out.push_back(' ');
      ++i;
      continue;
    }
    if (length == 0 || c < 0x20 || c == 0x7f) {
      constexpr std::string_view kHex = "0123456789abcdef";
      out.append("\\x").push_back(kHex[c >> 4]);
      out.push_back(kHex[c & 0xf]);
      ++i;
      continue;
    }
    out.append(text.substr(i, length));
    i += length;
  }
  return out;
}

/// A file system error as our own errors read: the path first, then what could
/// not be done and why ("P: directory iterator cannot open directory: Permission
/// denied"), not the library's "filesystem error: ... [P]".
std::string describe(const std::filesystem::filesystem_error& e) {
  std::string what = e.what();
  constexpr std::string_view kPrefix = "filesystem error: ";
  if (what.starts_with(kPrefix)) what.erase(0, kPrefix.size());
  if (e.path1().empty()) return what;
  // Drop the bracketed paths the library appends; the first leads instead.
  if (const auto bracket = what.find(" [" + e.path1().string() + "]");
      bracket != std::string::npos) {
    what.erase(bracket);
  }
  return e.path1().string() + ": " + what;
}

/// "run " for `dcl-slam run`, "bench loops " ...: the command the user typed.
std::string helpPath(const CLI::App& app) {
  std::string path;
  for (const CLI::App* sub = &app; sub != nullptr;) {
    const auto chosen = sub->get_subcommands();
    sub = chosen.empty() ? nullptr : chosen.front();
    if (sub != nullptr) path.append(sub->get_name()).append(" ");
  }
  return path;
}

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
  dcl::apps::sayWhatAnInterruptDoes();
  dcl::apps::AppConfig config = preloadConfig(argc, argv);
  CLI::App app{"dcl-slam: distributed collaborative LiDAR SLAM for robot swarms", "dcl-slam"};
  app.require_subcommand(1);
  app.fallthrough();  // global options may follow the subcommand
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
  dcl::apps::addPlayCommand(app, config);
  dcl::apps::addSwarmCommand(app, config);
  auto* bench = app.add_subcommand("bench", "benchmarks of the system's parts");
  bench->require_subcommand(1);
  dcl::apps::addBenchSimCommand(*bench);
  dcl::apps::addBenchSensorCommand(*bench);
  dcl::apps::addBenchOdometryCommand(*bench, config);
  dcl::apps::addBenchPlaceCommand(*bench, config);
  dcl::apps::addBenchLoopsCommand(*bench, config);
  dcl::apps::addBenchSystemCommand(*bench, config);
  dcl::apps::addBenchBoundCommand(*bench);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::RuntimeError& e) {
    return e.get_exit_code();  // a command's own exit code, its message already printed
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "dcl-slam: error: %s (see dcl-slam %s--help)\n",
                 printable(e.what()).c_str(), helpPath(app).c_str());
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const dcl::core::Error& e) {
    std::fprintf(stderr, "dcl-slam: error: %s\n", printable(e.what()).c_str());
  } catch (const std::filesystem::filesystem_error& e) {
    std::fprintf(stderr, "dcl-slam: error: %s\n", printable(describe(e)).c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dcl-slam: error: unexpected: %s\n", printable(e.what()).c_str());
  }
  return 1;
}
