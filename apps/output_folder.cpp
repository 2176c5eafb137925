#include "output_folder.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>

#include <CLI/CLI.hpp>
#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <dcl/core/error.hpp>

namespace dcl::apps {

namespace fs = std::filesystem;

namespace {

/// Marks a folder as a dcl-slam output, which a later command may replace whole.
constexpr const char* kMarker = ".dcl-slam";

/// The staging folders of `name`: ".NAME.partial-PID-XXXXXX".
std::string stagingPrefix(const std::string& name) {
  return std::string(".").append(name).append(".partial-");
}

/// Removes the staging folders beside `out` that processes now gone left (killed).
void removeStaleStaging(const fs::path& parent, const std::string& name) {
  const std::string prefix = stagingPrefix(name);
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(parent, ec)) {
    const std::string file = entry.path().filename().string();
    if (file.rfind(prefix, 0) != 0) continue;
    const std::string pid =
        file.substr(prefix.size(), file.find('-', prefix.size()) - prefix.size());
    if (pid.empty() || fs::exists("/proc/" + pid)) continue;
    fs::remove_all(entry.path(), ec);
  }
}

bool holdsOtherFiles(const fs::path& folder, const std::vector<std::string>& carried) {
  std::error_code ec;
  if (fs::exists(folder / kMarker, ec)) return false;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    if (std::find(carried.begin(), carried.end(), name) == carried.end()) return true;
  }
  return false;
}

mode_t currentUmask() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("Umask:", 0) == 0) {
      return static_cast<mode_t>(std::stoul(line.substr(6), nullptr, 8));
    }
  }
  return 022;
}

// The message an interrupt prints, made before any signal can come.
std::array<char, 4096> g_interrupt_message{};
std::size_t g_interrupt_length = 0;

void setInterruptMessage(const std::string& out) {
  const std::string text =
      out.empty() ? std::string("dcl-slam: interrupted\n")
                  : fmt::format(
                        "dcl-slam: interrupted before its outputs were written; {} keeps "
                        "what it held\n",
                        out);
  g_interrupt_length = std::min(text.size(), g_interrupt_message.size());
  std::memcpy(g_interrupt_message.data(), text.data(), g_interrupt_length);
}

extern "C" void onInterrupt(int signal) {
  // Only async-signal-safe calls: the message is ready, the staging folder is
  // left for the next command to remove (it sees this process gone).
  const ssize_t ignored = ::write(STDERR_FILENO, g_interrupt_message.data(), g_interrupt_length);
  (void)ignored;
  ::_exit(128 + signal);
}

}  // namespace

OutputFolder::OutputFolder(std::string out, bool force, std::vector<std::string> carried)
    : out_(std::move(out)), carried_(std::move(carried)) {
  fs::path target(out_);
  if (!target.has_filename()) target = target.parent_path();  // "out/" names "out"
  if (target.empty() || target.filename() == "." || target.filename() == "..") {
    throw core::Error(fmt::format("--out '{}': name the output folder itself", out_));
  }
  std::error_code ec;
  const auto status = fs::status(target, ec);
  if (fs::exists(status) && !fs::is_directory(status)) {
    throw core::Error(fmt::format("--out {}: is a file, not a folder", out_));
  }
  if (fs::is_directory(status) && !force && holdsOtherFiles(target, carried_)) {
    throw core::Error(fmt::format(
        "--out {}: holds files that no dcl-slam command wrote; name a new or empty folder, or "
        "pass --force to replace them",
        out_));
  }
  const fs::path parent = target.has_parent_path() ? target.parent_path() : fs::path(".");
  fs::create_directories(parent, ec);
  if (ec) {
    throw core::Error(
        fmt::format("--out {}: cannot create {}: {}", out_, parent.string(), ec.message()));
  }
  const std::string name = target.filename().string();
  removeStaleStaging(parent, name);
  std::string staging =
      (parent / (stagingPrefix(name) + std::to_string(::getpid()) + "-XXXXXX")).string();
  if (::mkdtemp(staging.data()) == nullptr) {
    throw core::Error(fmt::format("--out {}: cannot write into {}: {}", out_, parent.string(),
                                  std::strerror(errno)));
  }
  staging_ = std::move(staging);
  out_ = target.string();
  std::ofstream(fs::path(staging_) / kMarker)
      << "This folder is the output of one dcl-slam command; the next command that writes\n"
         "here replaces it as a whole.\n";
  setInterruptMessage(out_);
}

OutputFolder::~OutputFolder() {
  if (committed_) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
}

void OutputFolder::requireOutside(const std::string& input, const std::string& what) const {
  std::error_code ec;
  const fs::path folder = fs::weakly_canonical(out_, ec);
  const fs::path inside = fs::weakly_canonical(input, ec);
  const auto [end, _] = std::mismatch(folder.begin(), folder.end(), inside.begin(), inside.end());
  if (!folder.empty() && end == folder.end()) {
    throw core::Error(
        fmt::format("{} {} lies in --out {}, which this command replaces: write the "
                    "outputs elsewhere",
                    what, input, out_));
  }
}

void OutputFolder::commit() {
  std::error_code ec;
  fs::permissions(staging_, static_cast<fs::perms>(0777 & ~currentUmask()), ec);
  for (const std::string& name : carried_) {
    const fs::path from = fs::path(out_) / name;
    const fs::path to = fs::path(staging_) / name;
    // A hard link: the same file under both names, so its writer's appends land in both.
    if (fs::is_regular_file(from, ec) && !fs::exists(to, ec)) fs::create_hard_link(from, to, ec);
  }
  if (!fs::exists(out_, ec)) {
    fs::rename(staging_, out_, ec);
    if (ec)
      throw core::Error(
          fmt::format("--out {}: cannot put the outputs in place: {}", out_, ec.message()));
  } else if (::renameat2(AT_FDCWD, staging_.c_str(), AT_FDCWD, out_.c_str(), RENAME_EXCHANGE) ==
             0) {
    fs::remove_all(staging_, ec);  // now the earlier outputs
  } else {
    // A file system without an atomic exchange: the earlier outputs go aside first.
    const std::string aside = staging_ + ".old";
    fs::rename(out_, aside, ec);
    if (!ec) fs::rename(staging_, out_, ec);
    if (ec)
      throw core::Error(
          fmt::format("--out {}: cannot put the outputs in place: {}", out_, ec.message()));
    fs::remove_all(aside, ec);
  }
  committed_ = true;
  setInterruptMessage("");
}

void addForceFlag(CLI::App& cmd, bool& force) {
  cmd.add_flag("--force", force,
               "replace --out even when it holds files that no dcl-slam command wrote");
}

void sayWhatAnInterruptDoes() {
  setInterruptMessage("");
  std::signal(SIGINT, onInterrupt);
  std::signal(SIGTERM, onInterrupt);
}

}  // namespace dcl::apps
