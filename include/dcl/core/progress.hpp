#pragma once

#include <chrono>
#include <cstdio>
#include <span>
#include <string>
#include <string_view>

namespace dcl::core {

/// One line of progress for a long run: done/total, a bar, the rate, the time
/// left, and a free-form note. Draws over itself on a terminal, at most ten
/// times a second; stays silent when the stream is not a terminal (logs, CI).
class ProgressBar {
 public:
  /// `unit` names what is counted ("frames", "edges").
  ProgressBar(std::string label, std::size_t total, std::string unit = "items",
              std::FILE* stream = stderr);
  ~ProgressBar();
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  /// Reports `done` items finished, with an optional note shown after the figures.
  void update(std::size_t done, std::string_view note = {});

  /// Draws the final state and ends the line (called by the destructor if needed).
  void finish();

  /// Whether this bar draws at all (only on a terminal).
  [[nodiscard]] bool enabled() const { return enabled_; }

 private:
  using Clock = std::chrono::steady_clock;
  void draw();

  std::string label_;
  std::string unit_;
  std::size_t total_;
  std::size_t done_ = 0;
  std::string note_;
  std::FILE* stream_;
  bool enabled_;
  bool finished_ = false;
  Clock::time_point start_;
  Clock::time_point last_draw_;
};

/// Several lines of progress drawn over themselves (one per robot of a swarm
/// run) on a terminal, at most five times a second: more would cost the run
/// time and flicker. Silent when the stream is not a terminal, like
/// ProgressBar. Lines longer than the terminal is wide are cut, since a
/// wrapped line would throw off the redraw.
class ProgressBoard {
 public:
  explicit ProgressBoard(std::FILE* stream = stderr);
  ProgressBoard(const ProgressBoard&) = delete;
  ProgressBoard& operator=(const ProgressBoard&) = delete;

  /// Whether draw() would draw now: on a terminal, unfinished, and a fifth of
  /// a second after the last draw. Callers build their lines only then.
  [[nodiscard]] bool due() const;

  /// Draws `lines` over the ones drawn before (when due()).
  void draw(std::span<const std::string> lines);

  /// Draws `lines` as the final state and leaves them on screen.
  void finish(std::span<const std::string> lines);

  /// Whether this board draws at all (only on a terminal).
  [[nodiscard]] bool enabled() const { return enabled_; }

  /// Seconds since the board was made (for rates and times left).
  [[nodiscard]] double elapsed() const;

 private:
  using Clock = std::chrono::steady_clock;
  void write(std::span<const std::string> lines);

  std::FILE* stream_;
  bool enabled_;
  bool finished_ = false;
  std::size_t drawn_ = 0;  ///< lines on screen from the last draw
  Clock::time_point start_;
  Clock::time_point last_draw_;
};

/// The bytes that replace `previous` lines just drawn (the cursor at the start
/// of the line below them) by `lines`: cursor up, each line cut to `width`
/// characters (0: uncut) and cleared to its end, then everything below cleared.
std::string redrawText(std::size_t previous, std::span<const std::string> lines, std::size_t width);

/// The text of one progress line, without terminal control characters:
/// "label [#####.....]  50/100 frames  12.5 frames/s  eta 0:04  note".
std::string formatProgress(std::string_view label, std::size_t done, std::size_t total,
                           std::string_view unit, double elapsed_s, std::string_view note,
                           int bar_width = 24);

/// "1:02:03" or "2:03" for a duration in seconds; "--:--" when unknown (negative or not finite).
std::string formatDuration(double seconds);

}  // namespace dcl::core
