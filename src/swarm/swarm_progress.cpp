#include <algorithm>
#include <numeric>

#include <fmt/format.h>

#include <dcl/core/progress.hpp>
#include <dcl/swarm/swarm_progress.hpp>

namespace dcl::swarm {
namespace {

constexpr int kRobotBarWidth = 10;

double fraction(const RobotProgress& r) {
  return r.total_frames > 0 ? static_cast<double>(r.frames) / static_cast<double>(r.total_frames)
                            : 1.0;
}

std::string bar(double done, int width) {
  const int filled = std::clamp(static_cast<int>(done * width), 0, width);
  return std::string(filled, '#') + std::string(width - filled, '.');
}

std::string summaryLine(std::string_view label, const SwarmStatus& s, double elapsed_s) {
  std::size_t frames = 0;
  std::size_t total = 0;
  for (const RobotProgress& r : s.robots) {
    frames += r.frames;
    total += r.total_frames;
  }
  const double done = s.end > 0.0 ? std::min(1.0, s.time / s.end) : 1.0;
  const double eta = done > 0.0 ? elapsed_s * (1.0 - done) / done : -1.0;
  return fmt::format("{} [{}] t {:.0f}/{:.0f} s  {}/{} frames  eta {}", label, bar(done, 24),
                     s.time, s.end, frames, total, core::formatDuration(eta));
}

std::string robotLine(const RobotProgress& r, std::size_t name_width) {
  return fmt::format("  {:<{}} [{}] {:>11} frames {:>5} kf {:>4} loops {:>9} sent{}", r.name,
                     name_width, bar(fraction(r), kRobotBarWidth),
                     fmt::format("{}/{}", r.frames, r.total_frames), r.keyframes, r.inter_loops,
                     formatBytes(r.bytes_sent), r.left ? "  (left)" : "");
}

/// One line for the robots not shown: how many, how many finished, and their sums.
std::string othersLine(const std::vector<const RobotProgress*>& others) {
  std::size_t finished = 0, keyframes = 0, loops = 0, bytes = 0;
  for (const RobotProgress* r : others) {
    finished += r->frames >= r->total_frames || r->left ? 1 : 0;
    keyframes += r->keyframes;
    loops += r->inter_loops;
    bytes += r->bytes_sent;
  }
  return fmt::format("  + {} more robots ({} done): {} kf {} loops {} sent", others.size(),
                     finished, keyframes, loops, formatBytes(bytes));
}

}  // namespace

std::string formatBytes(std::size_t bytes) {
  const auto b = static_cast<double>(bytes);
  if (bytes < 1000) return fmt::format("{} B", bytes);
  if (b < 1e6) return fmt::format("{:.1f} kB", b / 1e3);
  if (b < 1e9) return fmt::format("{:.2f} MB", b / 1e6);
  return fmt::format("{:.2f} GB", b / 1e9);
}

std::vector<std::string> progressLines(std::string_view label, const SwarmStatus& status,
                                       double elapsed_s, std::size_t max_robot_lines) {
  std::vector<std::string> lines{summaryLine(label, status, elapsed_s)};
  std::size_t name_width = 1;
  for (const RobotProgress& r : status.robots) name_width = std::max(name_width, r.name.size());
  std::vector<const RobotProgress*> shown;
  for (const RobotProgress& r : status.robots) shown.push_back(&r);
  std::vector<const RobotProgress*> others;
  if (shown.size() > std::max<std::size_t>(max_robot_lines, 1)) {
    // The slowest first (a robot that left counts as done), member order among equals.
    std::stable_sort(shown.begin(), shown.end(),
                     [](const RobotProgress* a, const RobotProgress* b) {
                       return (a->left ? 1.0 : fraction(*a)) < (b->left ? 1.0 : fraction(*b));
                     });
    const std::size_t keep = std::max<std::size_t>(max_robot_lines, 2) - 1;
    others.assign(shown.begin() + static_cast<std::ptrdiff_t>(keep), shown.end());
    shown.resize(keep);
    std::sort(shown.begin(), shown.end());  // back to member order: lines do not jump around
  }
  for (const RobotProgress* r : shown) lines.push_back(robotLine(*r, name_width));
  if (!others.empty()) lines.push_back(othersLine(others));
  return lines;
}

}  // namespace dcl::swarm
