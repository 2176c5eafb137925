#include <cmath>
#include <cstdlib>
#include <cstring>

#include <fmt/format.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <dcl/core/progress.hpp>

namespace dcl::core {

namespace {
bool isTerminal(std::FILE* stream) {
  const char* term = std::getenv("TERM");
  if (term != nullptr && std::strcmp(term, "dumb") == 0) return false;
  return ::isatty(::fileno(stream)) == 1;
}

constexpr auto kRedrawInterval = std::chrono::milliseconds(100);
constexpr auto kBoardInterval = std::chrono::milliseconds(200);

/// Columns of the terminal behind `stream`, 0 when unknown.
std::size_t terminalWidth(std::FILE* stream) {
  winsize size{};
  if (::ioctl(::fileno(stream), TIOCGWINSZ, &size) != 0) return 0;
  return size.ws_col;
}
}  // namespace

std::string formatDuration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0.0) return "--:--";
  const auto s = static_cast<long long>(std::llround(seconds));
  if (s >= 3600) return fmt::format("{}:{:02}:{:02}", s / 3600, (s / 60) % 60, s % 60);
  return fmt::format("{}:{:02}", s / 60, s % 60);
}

std::string formatProgress(std::string_view label, std::size_t done, std::size_t total,
                           std::string_view unit, double elapsed_s, std::string_view note,
                           int bar_width) {
  const double fraction = total > 0 ? std::min(1.0, static_cast<double>(done) / total) : 0.0;
  const int filled = static_cast<int>(fraction * bar_width);
  const double rate = elapsed_s > 0.0 ? static_cast<double>(done) / elapsed_s : 0.0;
  const double eta = rate > 0.0 && total >= done ? static_cast<double>(total - done) / rate : -1.0;
  std::string line = fmt::format("{} [{}{}] {}/{} {} {:.1f} {}/s eta {}", label,
                                 std::string(filled, '#'), std::string(bar_width - filled, '.'),
                                 done, total, unit, rate, unit, formatDuration(eta));
  if (!note.empty()) line += fmt::format("  {}", note);
  return line;
}

ProgressBar::ProgressBar(std::string label, std::size_t total, std::string unit, std::FILE* stream)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(total),
      stream_(stream),
      enabled_(isTerminal(stream)),
      start_(Clock::now()),
      last_draw_(start_ - kRedrawInterval) {}

ProgressBar::~ProgressBar() {
  finish();
}

void ProgressBar::update(std::size_t done, std::string_view note) {
  done_ = done;
  note_ = note;
  if (!enabled_ || finished_) return;
  const auto now = Clock::now();
  if (now - last_draw_ < kRedrawInterval) return;
  last_draw_ = now;
  draw();
}

void ProgressBar::finish() {
  if (finished_) return;
  finished_ = true;
  if (!enabled_) return;
  draw();
  std::fputc('\n', stream_);
  std::fflush(stream_);
}

void ProgressBar::draw() {
  const double elapsed = std::chrono::duration<double>(Clock::now() - start_).count();
  const std::string line = formatProgress(label_, done_, total_, unit_, elapsed, note_);
  // \r returns to the line start, \x1b[K clears what a longer previous line left.
  std::fprintf(stream_, "\r%s\x1b[K", line.c_str());
  std::fflush(stream_);
}

std::string redrawText(std::size_t previous, std::span<const std::string> lines,
                       std::size_t width) {
  // \r and CSI n A return to the first line drawn; CSI K clears what a longer
  // line left, CSI J what more lines left below.
  std::string out = "\r";
  if (previous > 0) out += fmt::format("\x1b[{}A", previous);
  for (const std::string& line : lines) {
    out += width > 0 && line.size() >= width ? line.substr(0, width - 1) : line;
    out += "\x1b[K\n";
  }
  out += "\x1b[J";
  return out;
}

ProgressBoard::ProgressBoard(std::FILE* stream)
    : stream_(stream),
      enabled_(isTerminal(stream)),
      start_(Clock::now()),
      last_draw_(start_ - kBoardInterval) {}

bool ProgressBoard::due() const {
  return enabled_ && !finished_ && Clock::now() - last_draw_ >= kBoardInterval;
}

void ProgressBoard::draw(std::span<const std::string> lines) {
  if (!due()) return;
  last_draw_ = Clock::now();
  write(lines);
}

void ProgressBoard::finish(std::span<const std::string> lines) {
  if (!enabled_ || finished_) return;
  finished_ = true;
  write(lines);
}

double ProgressBoard::elapsed() const {
  return std::chrono::duration<double>(Clock::now() - start_).count();
}

void ProgressBoard::write(std::span<const std::string> lines) {
  const std::string text = redrawText(drawn_, lines, terminalWidth(stream_));
  std::fwrite(text.data(), 1, text.size(), stream_);
  std::fflush(stream_);
  drawn_ = lines.size();
}

}  // namespace dcl::core
