#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include <dcl/core/base64.hpp>
#include <dcl/core/colour.hpp>
#include <dcl/core/error.hpp>
#include <dcl/eval/ate.hpp>
#include <dcl/eval/run_report.hpp>
#include <dcl/io/image.hpp>

namespace dcl::eval {

namespace {

// ------------------------------------------------------------------------------------------------
// Evaluation

// Umeyama needs three pairs; a robot with fewer keyframes has no defined ATE.
constexpr std::size_t kMinPairs = 3;

// Every robot's keyframes paired with its ground truth (none without ground truth or with
// too few keyframes), and the one rigid alignment of the whole swarm fitted on all of them.
struct RunPairs {
  std::vector<std::optional<Association>> estimate;
  std::vector<std::optional<Association>> odometry;
  std::vector<std::optional<Sim3>> S_gt_common;  // per robot, its frame's
};

// Runs `f`, prefixing any core::Error with the robot it was about.
template <typename F>
auto forRobot(const RobotRun& robot, std::string_view what, F&& f) {
  try {
    return f();
  } catch (const core::Error& e) {
    throw core::Error(fmt::format("run report: robot '{}', {}: {}", robot.name, what, e.what()));
  }
}

std::optional<Association> pairsOf(const RobotRun& robot, const core::Trajectory& keyframes,
                                   std::string_view what) {
  if (robot.ground_truth.empty() || keyframes.empty()) return std::nullopt;
  Association pairs =
      forRobot(robot, what, [&] { return associate(keyframes, robot.ground_truth); });
  if (pairs.size() < kMinPairs) return std::nullopt;
  return pairs;
}

// The SE(3) alignment fitted on the pairs of all robots in `frame` together: the full system
// claims one common frame, so one rigid motion must fit them all.
std::optional<Sim3> commonAlignment(const RunSummary& run,
                                    const std::vector<std::optional<Association>>& robots,
                                    const std::string& frame) {
  Association all;
  for (std::size_t r = 0; r < robots.size(); ++r) {
    const std::optional<Association>& pairs = robots[r];
    if (!pairs || run.robots[r].frame != frame) continue;
    for (std::size_t i = 0; i < pairs->size(); ++i) {
      all.estimate.push_back(pairs->estimate.stamp(i), pairs->estimate.pose(i));
      all.ground_truth.push_back(pairs->ground_truth.stamp(i), pairs->ground_truth.pose(i));
    }
  }
  if (all.size() < kMinPairs) return std::nullopt;
  try {
    return computeAlignment(all, Alignment::se3);
  } catch (const core::Error& e) {
    throw core::Error(fmt::format("run report: joint alignment of the robots{}: {}",
                                  frame.empty() ? "" : " in frame '" + frame + "'", e.what()));
  }
}

RunPairs pairRun(const RunSummary& run) {
  RunPairs out;
  for (const RobotRun& robot : run.robots) {
    out.estimate.push_back(pairsOf(robot, robot.estimate, "full-system estimate"));
    out.odometry.push_back(pairsOf(robot, robot.odometry, "odometry"));
  }
  std::map<std::string, std::optional<Sim3>> by_frame;
  for (const RobotRun& robot : run.robots) {
    if (!by_frame.contains(robot.frame))
      by_frame[robot.frame] = commonAlignment(run, out.estimate, robot.frame);
    out.S_gt_common.push_back(by_frame.at(robot.frame));
  }
  return out;
}

void checkRun(const RunSummary& run) {
  if (!std::isfinite(run.duration) || run.duration < 0.0) {
    throw core::Error(
        fmt::format("run report: duration {} s is not a finite non-negative number", run.duration));
  }
}

double kiloBytesPerSecond(std::size_t bytes, double duration) {
  return duration > 0.0 ? static_cast<double>(bytes) / 1000.0 / duration : 0.0;
}

// ATE (m) and ARE (deg) RMSE of `pairs` aligned on themselves.
std::pair<double, double> perRobotAte(const RobotRun& robot, const Association& pairs,
                                      std::string_view what) {
  const AteResult r = forRobot(robot, what, [&] { return computeAte(pairs, Alignment::se3); });
  return {r.translation_m.rmse, r.rotation_deg.rmse};
}

RobotMetrics robotMetrics(const RunSummary& run, const RunPairs& pairs, std::size_t i) {
  const RobotRun& robot = run.robots[i];
  RobotMetrics m;
  m.transmit_kBps = kiloBytesPerSecond(robot.bytes_sent, run.duration);
  m.receive_kBps = kiloBytesPerSecond(robot.bytes_received, run.duration);
  if (pairs.estimate[i]) {
    std::tie(m.ate_rmse, m.are_rmse_deg) = perRobotAte(robot, *pairs.estimate[i], "estimate");
    if (const std::optional<Sim3>& S = pairs.S_gt_common[i]) {
      m.ate_rmse_joint = computeAte(*pairs.estimate[i], *S, Alignment::se3).translation_m.rmse;
    }
  }
  if (pairs.odometry[i]) {
    std::tie(m.ate_rmse_odometry_only, m.are_rmse_deg_odometry_only) =
        perRobotAte(robot, *pairs.odometry[i], "odometry");
  }
  return m;
}

// ------------------------------------------------------------------------------------------------
// Text and numbers

constexpr std::string_view kAccepted = "#2ca02c";
constexpr std::string_view kRejected = "#d62728";
// Longer polylines are thinned to this many points: the page stays small for long runs.
constexpr std::size_t kMaxLinePoints = 2000;

std::string colour(std::size_t i) {
  const std::array<std::uint8_t, 3> c = core::robotColour(i);
  return fmt::format("#{:02x}{:02x}{:02x}", c[0], c[1], c[2]);
}

// Message kind `i`'s colour in the traffic plot: apart from the robots' (a
// kind is not a robot), one of eight that colour-blind readers tell apart
// (Okabe and Ito's), then again darker.
std::string kindColour(std::size_t i) {
  static constexpr std::array<std::string_view, 8> kKinds = {
      "#e69f00", "#56b4e9", "#009e73", "#f0e442", "#0072b2", "#d55e00", "#cc79a7", "#000000"};
  if (i < kKinds.size()) return std::string(kKinds[i]);
  const std::string_view c = kKinds[i % kKinds.size()];
  const auto darker = [&](std::size_t at) {
    return std::stoi(std::string(c.substr(at, 2)), nullptr, 16) * 2 / 3;
  };
  return fmt::format("#{:02x}{:02x}{:02x}", darker(1), darker(3), darker(5));
}

// HTML-escaped text; control characters (invalid in HTML) become U+FFFD.
std::string escape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '&')
      out += "&amp;";
    else if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '"')
      out += "&quot;";
    else if (c == '\'')
      out += "&#39;";
    else if ((u < 0x20 && c != '\n' && c != '\t') || u == 0x7F)
      out += "\xEF\xBF\xBD";
    else
      out += c;
  }
  return out;
}

// Fixed-point text of `v` with `decimals` digits, never "-0".
std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
  const double scale = std::pow(10.0, decimals);
  double r = std::round(v * scale) / scale;
  if (r == 0.0) r = 0.0;
  return fmt::format("{:.{}f}", r, decimals);
}

std::string optionalFixed(const std::optional<double>& v, int decimals) {
  return v ? fixed(*v, decimals) : "&ndash;";
}

// A counter as an integer when it is one, else with three decimals.
std::string counterText(double v) {
  return std::isfinite(v) && v == std::round(v) && std::abs(v) < 1e15 ? fixed(v, 0) : fixed(v, 3);
}

// ------------------------------------------------------------------------------------------------
// Plot geometry

using Point = Eigen::Vector2d;
using Line = std::vector<Point>;

struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();

  void add(double v) {
    if (!std::isfinite(v)) return;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  [[nodiscard]] bool valid() const { return lo <= hi; }
  [[nodiscard]] double span() const { return hi - lo; }
};

// Maps data coordinates (metres, seconds) into the pixels of a plot area (y up on screen).
struct Axes {
  double left = 0, top = 0, width = 0, height = 0;  // plot area, px
  Range x, y;                                       // data shown

  [[nodiscard]] double px(double v) const { return left + (v - x.lo) / x.span() * width; }
  [[nodiscard]] double py(double v) const { return top + height - (v - y.lo) / y.span() * height; }
};

// A 1-2-5 tick step giving about `target` ticks over `span`.
double tickStep(double span, double target) {
  const double raw = span / target;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0}) {
    if (m * decade >= raw) return m * decade;
  }
  return 10.0 * decade;
}

int tickDecimals(double step) {
  return std::max(0, -static_cast<int>(std::floor(std::log10(step))));
}

// Widens a range that is empty or a single value to a visible one.
Range padded(Range r, double fraction) {
  if (!r.valid()) r = {0.0, 1.0};
  const double pad = r.span() > 0.0 ? fraction * r.span() : std::max(1.0, std::abs(r.lo) * 0.1);
  return {r.lo - pad, r.hi + pad};
}

// Legend rows are this far apart, px.
constexpr double kLegendRow = 18.0;

// The svg element of a plot area `a` with a legend of `legend_rows` on its right: tall enough
// for both.
std::string svgOpen(const Axes& a, std::size_t legend_rows, std::string_view label) {
  const double width = a.left + a.width + 220.0;
  const double height = std::max(a.top + a.height + 45.0,
                                 a.top + 20.0 + kLegendRow * static_cast<double>(legend_rows));
  return fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"0 0 {0} {1}\" width=\"{0}\" "
      "height=\"{1}\" role=\"img\" aria-label=\"{2}\">\n",
      fixed(width, 0), fixed(height, 0), escape(label));
}

std::string text(double x, double y, std::string_view anchor, std::string_view content,
                 std::string_view extra = "") {
  return fmt::format("<text x=\"{}\" y=\"{}\" text-anchor=\"{}\"{}>{}</text>\n", fixed(x, 1),
                     fixed(y, 1), anchor, extra, content);
}

std::string xTicks(const Axes& a, std::string_view unit) {
  const double step = tickStep(a.x.span(), 6.0);
  const int decimals = tickDecimals(step);
  std::string out;
  for (double v = std::ceil(a.x.lo / step) * step; v <= a.x.hi; v += step) {
    const double x = a.px(v);
    out += fmt::format("<line class=\"grid\" x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\"/>\n",
                       fixed(x, 1), fixed(a.top, 1), fixed(a.top + a.height, 1));
    out += text(x, a.top + a.height + 16, "middle", fixed(v, decimals) + " " + std::string(unit));
  }
  return out;
}

std::string yTicks(const Axes& a, std::string_view unit) {
  const double step = tickStep(a.y.span(), 6.0);
  const int decimals = tickDecimals(step);
  std::string out;
  for (double v = std::ceil(a.y.lo / step) * step; v <= a.y.hi; v += step) {
    const double y = a.py(v);
    out += fmt::format("<line class=\"grid\" x1=\"{0}\" y1=\"{1}\" x2=\"{2}\" y2=\"{1}\"/>\n",
                       fixed(a.left, 1), fixed(y, 1), fixed(a.left + a.width, 1));
    out += text(a.left - 6, y + 4, "end", fixed(v, decimals) + " " + std::string(unit));
  }
  return out;
}

// Grid, tick labels with units, the frame and the axis titles.
std::string axesSvg(const Axes& a, std::string_view x_unit, std::string_view y_unit,
                    std::string_view x_title, std::string_view y_title) {
  std::string out = xTicks(a, x_unit) + yTicks(a, y_unit);
  out += fmt::format("<rect class=\"frame\" x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\"/>\n",
                     fixed(a.left, 1), fixed(a.top, 1), fixed(a.width, 1), fixed(a.height, 1));
  out += text(a.left + a.width / 2, a.top + a.height + 34, "middle", x_title);
  out += fmt::format(
      "<text x=\"{0}\" y=\"{1}\" text-anchor=\"middle\" transform=\"rotate(-90 {0} {1})\">{2}"
      "</text>\n",
      fixed(a.left - 58, 1), fixed(a.top + a.height / 2, 1), y_title);
  return out;
}

// At most kMaxLinePoints of `line`, evenly strided, the last one always kept.
Line thinned(const Line& line) {
  if (line.size() <= kMaxLinePoints) return line;
  const std::size_t stride = (line.size() + kMaxLinePoints - 2) / (kMaxLinePoints - 1);
  Line out;
  for (std::size_t i = 0; i < line.size(); i += stride) out.push_back(line[i]);
  if (out.back() != line.back()) out.push_back(line.back());
  return out;
}

std::string polyline(const Axes& a, const Line& line, std::string_view cls,
                     std::string_view stroke) {
  std::string points;
  for (const Point& p : thinned(line)) {
    if (!p.allFinite()) continue;
    if (!points.empty()) points += ' ';
    points += fixed(a.px(p.x()), 1) + "," + fixed(a.py(p.y()), 1);
  }
  if (points.empty()) return {};
  return fmt::format("<polyline class=\"{}\" stroke=\"{}\" points=\"{}\"/>\n", cls, stroke, points);
}

// Small dots on the ends of a loop: after optimisation its two keyframes are close together
// and the line between them alone would hardly show.
std::string endpoints(const Axes& a, const Line& segment, std::string_view fill) {
  std::string out;
  for (const Point& p : segment) {
    if (!p.allFinite()) continue;
    out += fmt::format("<circle class=\"end\" cx=\"{}\" cy=\"{}\" r=\"2.2\" fill=\"{}\"/>\n",
                       fixed(a.px(p.x()), 1), fixed(a.py(p.y()), 1), fill);
  }
  return out;
}

// One legend entry: a sample of a line (dashed or not) or a filled box, then its label.
struct LegendEntry {
  std::string label;     // escaped
  std::string stroke;    // a colour
  std::string_view cls;  // line class, or "box" / "box-light"
};

std::string legendSvg(double x, double y, const std::vector<LegendEntry>& entries) {
  std::string out;
  for (const LegendEntry& e : entries) {
    if (e.cls.starts_with("box")) {
      out += fmt::format(
          "<rect class=\"{}\" x=\"{}\" y=\"{}\" width=\"22\" height=\"10\" "
          "fill=\"{}\" stroke=\"{}\"/>\n",
          e.cls, fixed(x, 1), fixed(y - 5, 1), e.stroke, e.stroke);
    } else {
      out += fmt::format(
          "<line class=\"{}\" stroke=\"{}\" x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\"/>\n", e.cls,
          e.stroke, fixed(x, 1), fixed(y, 1), fixed(x + 22, 1), fixed(y, 1));
    }
    out += text(x + 28, y + 4, "start", e.label);
    y += kLegendRow;
  }
  return out;
}

// ------------------------------------------------------------------------------------------------
// Trajectory plot

// What the trajectory plot draws, in the ground truth's frame when there is one.
struct TopView {
  std::vector<Line> ground_truth, estimate, odometry;  // per robot
  std::vector<std::pair<Line, bool>> loops;            // segment, accepted
};

Line xy(const core::Trajectory& trajectory, const Sim3& S) {
  Line out;
  out.reserve(trajectory.size());
  for (const auto& T : trajectory.poses()) {
    const Eigen::Vector3d p = S * T.translation();
    out.emplace_back(p.x(), p.y());
  }
  return out;
}

TopView topView(const RunSummary& run, const RunPairs& pairs) {
  const auto S_common = [&](std::size_t i) { return pairs.S_gt_common[i].value_or(Sim3{}); };
  TopView view;
  for (std::size_t i = 0; i < run.robots.size(); ++i) {
    const RobotRun& robot = run.robots[i];
    const Sim3 S_odometry =
        pairs.odometry[i] ? computeAlignment(*pairs.odometry[i], Alignment::se3) : Sim3{};
    view.ground_truth.push_back(xy(robot.ground_truth, Sim3{}));
    view.estimate.push_back(xy(robot.estimate, S_common(i)));
    view.odometry.push_back(xy(robot.odometry, S_odometry));
  }
  for (const RunLoop& loop : run.loops) {
    const Eigen::Vector3d a = S_common(loop.robot_a) * loop.p_a;
    const Eigen::Vector3d b = S_common(loop.robot_b) * loop.p_b;
    view.loops.push_back({Line{Point(a.x(), a.y()), Point(b.x(), b.y())}, loop.accepted});
  }
  return view;
}

void addAll(Range& x, Range& y, const std::vector<Line>& lines) {
  for (const Line& line : lines) {
    for (const Point& p : line) {
      x.add(p.x());
      y.add(p.y());
    }
  }
}

// Plot area with one scale for x and y (metres look like metres), its height following the
// data's aspect within limits, the ranges widened to fill it.
Axes equalScaleAxes(Range x, Range y) {
  Axes a{80.0, 20.0, 640.0, std::clamp(640.0 * y.span() / x.span(), 240.0, 800.0), x, y};
  const double metres_per_px = std::max(x.span() / a.width, y.span() / a.height);
  const double cx = 0.5 * (x.lo + x.hi), cy = 0.5 * (y.lo + y.hi);
  a.x = {cx - 0.5 * a.width * metres_per_px, cx + 0.5 * a.width * metres_per_px};
  a.y = {cy - 0.5 * a.height * metres_per_px, cy + 0.5 * a.height * metres_per_px};
  return a;
}

// The trajectory plot's area: everything it draws, 4 % around.
Axes topViewAxes(const TopView& view) {
  Range x, y;
  addAll(x, y, view.ground_truth);
  addAll(x, y, view.estimate);
  addAll(x, y, view.odometry);
  for (const auto& loop : view.loops) addAll(x, y, {loop.first});
  x = padded(x, 0.04);
  y = padded(y, 0.04);
  return equalScaleAxes(x, y);
}

std::string trajectoryLegend(const RunSummary& run, double x, double y) {
  std::vector<LegendEntry> entries;
  for (std::size_t i = 0; i < run.robots.size(); ++i)
    entries.push_back({escape(run.robots[i].name), colour(i), "est"});
  entries.push_back({"full system", "#000", "est"});
  entries.push_back({"odometry only", "#000", "odo"});
  entries.push_back({"ground truth", "#999", "gt"});
  entries.push_back({"loop, accepted", std::string(kAccepted), "loop"});
  entries.push_back({"loop, rejected", std::string(kRejected), "loop"});
  return legendSvg(x, y, entries);
}

std::string trajectoryCaption(const RunPairs& pairs) {
  const bool aligned = std::any_of(pairs.S_gt_common.begin(), pairs.S_gt_common.end(),
                                   [](const std::optional<Sim3>& S) { return S.has_value(); });
  return aligned
             ? "<p>Ground truth (grey); the full system aligned to it by one rigid motion for all "
               "robots in one frame; the odometry alone (dashed) aligned robot by robot; "
               "inter-robot loops "
               "accepted (green) and rejected (red).</p>\n"
             : "<p>Not aligned to ground truth (there is none, or too few keyframes): the full "
               "system in its common frame, the odometry alone (dashed) in each robot's own "
               "frame; inter-robot loops accepted (green) and rejected (red).</p>\n";
}

std::string trajectoryPlot(const RunSummary& run, const RunPairs& pairs) {
  const TopView view = topView(run, pairs);
  const Axes a = topViewAxes(view);
  std::string out = trajectoryCaption(pairs) + svgOpen(a, run.robots.size() + 5, "trajectories");
  out += axesSvg(a, "m", "m", "x", "y");
  for (std::size_t i = 0; i < run.robots.size(); ++i)
    out += polyline(a, view.ground_truth[i], "gt", "#999");
  for (std::size_t i = 0; i < run.robots.size(); ++i) {
    out += polyline(a, view.odometry[i], "odo", colour(i));
    out += polyline(a, view.estimate[i], "est", colour(i));
  }
  for (const auto& [segment, accepted] : view.loops) {
    out += polyline(a, segment, "loop", accepted ? kAccepted : kRejected);
    out += endpoints(a, segment, accepted ? kAccepted : kRejected);
  }
  out += trajectoryLegend(run, a.left + a.width + 16, a.top + 10);
  return out + "</svg>\n";
}

// ------------------------------------------------------------------------------------------------
// The merged map from above

// The map's plot area: the robots' estimates (the map's points when there are
// none), with a margin of 15 % (at least 20 m) for what they saw around them;
// one scale for x and y.
Axes mapAxes(const RunSummary& run) {
  Range x, y;
  for (const RobotRun& robot : run.robots) {
    for (const auto& T : robot.estimate.poses()) {
      x.add(T.translation().x());
      y.add(T.translation().y());
    }
  }
  if (!x.valid()) {
    for (const Eigen::Vector3f& p : run.map_points) {
      x.add(p.x());
      y.add(p.y());
    }
  }
  const double margin = std::max(20.0, 0.15 * std::max(x.span(), y.span()));
  x = {x.lo - margin, x.hi + margin};
  y = {y.lo - margin, y.hi + margin};
  return equalScaleAxes(x, y);
}

// Every map point in its robot's colour on white, a pixel of the plot area each
// (solid colours, whatever the screen).
std::vector<char> mapRaster(const RunSummary& run, const Axes& a) {
  const int width = static_cast<int>(std::lround(a.width));
  const int height = static_cast<int>(std::lround(a.height));
  std::vector<std::array<std::uint8_t, 3>> colours;
  for (std::size_t i = 0; i < run.robots.size(); ++i) colours.push_back(core::robotColour(i));
  io::Image image(width, height, {255, 255, 255});
  for (std::size_t i = 0; i < run.map_points.size(); ++i) {
    const Eigen::Vector3f& p = run.map_points[i];
    const double u = (p.x() - a.x.lo) / a.x.span() * width;
    const double v = (a.y.hi - p.y()) / a.y.span() * height;
    if (!(u >= 0.0 && u < width && v >= 0.0 && v < height)) continue;
    const auto& c = colours[run.map_robots[i]];
    image.set(static_cast<int>(u), static_cast<int>(v), {c[0], c[1], c[2]});
  }
  return io::encodePng(image);
}

std::string mapPlot(const RunSummary& run) {
  const Axes a = mapAxes(run);
  const std::vector<char> png = mapRaster(run, a);
  std::string out =
      "<p>Every robot's keyframe clouds at the full system's estimates, in the robots' common "
      "frame (map.ply), coloured by robot; the accepted inter-robot loops in green.</p>\n";
  out += svgOpen(a, run.robots.size() + 1, "merged map");
  out += axesSvg(a, "m", "m", "x", "y");
  out += fmt::format(
      "<image class=\"map\" x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" "
      "preserveAspectRatio=\"none\" href=\"data:image/png;base64,{}\"/>\n",
      fixed(a.left, 1), fixed(a.top, 1), fixed(a.width, 1), fixed(a.height, 1),
      core::base64(std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(png.data()),
                                                 png.size())));
  for (const RunLoop& loop : run.loops) {
    if (!loop.accepted) continue;
    const Line segment{Point(loop.p_a.x(), loop.p_a.y()), Point(loop.p_b.x(), loop.p_b.y())};
    out += polyline(a, segment, "loop", kAccepted);
    out += endpoints(a, segment, kAccepted);
  }
  std::vector<LegendEntry> entries;
  for (std::size_t i = 0; i < run.robots.size(); ++i)
    entries.push_back({escape(run.robots[i].name), colour(i), "box"});
  entries.push_back({"loop, accepted", std::string(kAccepted), "loop"});
  out += legendSvg(a.left + a.width + 16, a.top + 10, entries);
  return out + "</svg>\n";
}

// ------------------------------------------------------------------------------------------------
// ATE bars

std::string bar(const Axes& a, double x, double w, double v, std::string_view cls,
                std::string_view fill, int decimals) {
  const double top = a.py(v);
  return fmt::format(
             "<rect class=\"{}\" x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\" "
             "stroke=\"{}\"/>\n",
             cls, fixed(x, 1), fixed(top, 1), fixed(w, 1), fixed(a.py(0.0) - top, 1), fill, fill) +
         text(x + w / 2, top - 4, "middle", fixed(v, decimals), " class=\"small\"");
}

// Decimals that show `values` to three significant digits of the smallest
// (0.0121 and 0.0127, not 0.01 twice), 2 to 5 of them.
int significantDecimals(const std::vector<double>& values) {
  double smallest = std::numeric_limits<double>::infinity();
  for (const double v : values) {
    if (v > 0.0 && std::isfinite(v)) smallest = std::min(smallest, v);
  }
  if (!std::isfinite(smallest)) return 2;
  return std::clamp(2 - static_cast<int>(std::floor(std::log10(smallest))), 2, 5);
}

std::string atePlot(const RunSummary& run, const std::vector<RobotMetrics>& metrics) {
  Range y{0.0, 0.0};
  for (const RobotMetrics& m : metrics) {
    y.add(m.ate_rmse.value_or(0.0));
    y.add(m.ate_rmse_odometry_only.value_or(0.0));
  }
  const double group = std::clamp(560.0 / static_cast<double>(run.robots.size()), 60.0, 140.0);
  Axes a{80.0,  20.0,       group * static_cast<double>(run.robots.size()),
         260.0, {0.0, 1.0}, {0.0, y.hi > 0.0 ? 1.15 * y.hi : 1.0}};
  std::string out = svgOpen(a, 2, "ATE per robot");
  out += yTicks(a, "m");
  out += fmt::format("<rect class=\"frame\" x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\"/>\n",
                     fixed(a.left, 1), fixed(a.top, 1), fixed(a.width, 1), fixed(a.height, 1));
  std::vector<double> values;
  for (const RobotMetrics& m : metrics) {
    for (const auto& v : {m.ate_rmse, m.ate_rmse_odometry_only}) {
      if (v) values.push_back(*v);
    }
  }
  const int decimals = significantDecimals(values);
  for (std::size_t i = 0; i < run.robots.size(); ++i) {
    const double x0 = a.left + group * static_cast<double>(i), w = 0.32 * group;
    if (metrics[i].ate_rmse_odometry_only)
      out += bar(a, x0 + 0.16 * group, w, *metrics[i].ate_rmse_odometry_only, "box-light",
                 colour(i), decimals);
    if (metrics[i].ate_rmse)
      out += bar(a, x0 + 0.52 * group, w, *metrics[i].ate_rmse, "box", colour(i), decimals);
    out += text(x0 + group / 2, a.top + a.height + 18, "middle", escape(run.robots[i].name));
  }
  out += legendSvg(a.left + a.width + 16, a.top + 10,
                   {{"odometry only", "#555", "box-light"}, {"full system", "#555", "box"}});
  return out + "</svg>\n";
}

// ------------------------------------------------------------------------------------------------
// Traffic over time

// Bytes sent per message kind (summed over robots) per bin.
std::map<std::string, std::vector<double>> trafficByKind(const RunSummary& run) {
  std::map<std::string, std::vector<double>> out;
  for (const RobotRun& robot : run.robots) {
    for (const auto& [kind, bins] : robot.sent_over_time) {
      std::vector<double>& sum = out[kind];
      if (sum.size() < bins.size()) sum.resize(bins.size(), 0.0);
      for (std::size_t k = 0; k < bins.size(); ++k) sum[k] += static_cast<double>(bins[k]);
    }
  }
  return out;
}

// Bins merged by `factor` (sums), so that no line has more than kMaxLinePoints points.
std::vector<double> merged(const std::vector<double>& bins, std::size_t factor) {
  std::vector<double> out((bins.size() + factor - 1) / factor, 0.0);
  for (std::size_t k = 0; k < bins.size(); ++k) out[k / factor] += bins[k];
  return out;
}

std::string trafficPlot(const RunSummary& run) {
  const auto kinds = trafficByKind(run);
  std::size_t bins = 0;
  for (const auto& [kind, sums] : kinds) bins = std::max(bins, sums.size());
  const std::size_t factor = (bins + kMaxLinePoints - 1) / kMaxLinePoints;
  const double width = run.meter_interval * static_cast<double>(factor);
  std::map<std::string, Line> lines;
  Range y{0.0, 0.0};
  for (const auto& [kind, sums] : kinds) {
    const std::vector<double> kb = merged(sums, factor);
    for (std::size_t k = 0; k < kb.size(); ++k) {
      lines[kind].emplace_back((static_cast<double>(k) + 0.5) * width, kb[k] / 1000.0);
      y.add(kb[k] / 1000.0);
    }
  }
  Axes a{80.0,
         20.0,
         640.0,
         260.0,
         {0.0, std::max(static_cast<double>(bins) * run.meter_interval, 1e-9)},
         {0.0, y.hi > 0.0 ? 1.1 * y.hi : 1.0}};
  std::string out = svgOpen(a, lines.size(), "traffic over time");
  out += axesSvg(a, "s", "kB", "time", fmt::format("sent per {} s (all robots)", fixed(width, 2)));
  std::vector<LegendEntry> legend;
  for (const auto& [kind, line] : lines) {
    out += polyline(a, line, "traffic", kindColour(legend.size()));
    legend.push_back({escape(kind), kindColour(legend.size()), "traffic"});
  }
  out += legendSvg(a.left + a.width + 16, a.top + 10, legend);
  return out + "</svg>\n";
}

// ------------------------------------------------------------------------------------------------
// Tables and page

std::string improvement(const RobotMetrics& m) {
  if (!m.ate_rmse || !m.ate_rmse_odometry_only || *m.ate_rmse_odometry_only <= 0.0)
    return "&ndash;";
  return fixed(100.0 * (1.0 - *m.ate_rmse / *m.ate_rmse_odometry_only), 1) + " %";
}

std::string robotName(const RunSummary& run, std::size_t i) {
  return fmt::format("<span class=\"swatch\" style=\"background:{}\"></span>{}", colour(i),
                     escape(run.robots[i].name));
}

std::string row(const std::vector<std::string>& cells) {
  std::string out = "<tr>";
  for (const std::string& c : cells) out += "<td>" + c + "</td>";
  return out + "</tr>\n";
}

std::string accuracyTable(const RunSummary& run, const std::vector<RobotMetrics>& metrics) {
  std::string out =
      "<table>\n<tr><th>robot</th><th>keyframes</th><th>ATE full system [m]</th>"
      "<th>ATE odometry only [m]</th><th>ATE reduction</th><th>ATE joint alignment [m]</th>"
      "<th>ARE full system [deg]</th><th>ARE odometry only [deg]</th></tr>\n";
  for (std::size_t i = 0; i < run.robots.size(); ++i) {
    const RobotMetrics& m = metrics[i];
    out += row({robotName(run, i), std::to_string(run.robots[i].keyframes),
                optionalFixed(m.ate_rmse, 3), optionalFixed(m.ate_rmse_odometry_only, 3),
                improvement(m), optionalFixed(m.ate_rmse_joint, 3),
                optionalFixed(m.are_rmse_deg, 3), optionalFixed(m.are_rmse_deg_odometry_only, 3)});
  }
  return out + "</table>\n";
}

std::string exchangeTable(const RunSummary& run, const std::vector<RobotMetrics>& metrics) {
  std::string out =
      "<table>\n<tr><th>robot</th><th>frames</th><th>intra loops</th>"
      "<th>inter loops accepted</th><th>inter loops rejected</th><th>bytes sent</th>"
      "<th>bytes received</th><th>transmit [kB/s]</th><th>receive [kB/s]</th></tr>\n";
  for (std::size_t i = 0; i < run.robots.size(); ++i) {
    const RobotRun& r = run.robots[i];
    out += row({robotName(run, i), std::to_string(r.frames), std::to_string(r.intra_loops),
                std::to_string(r.inter_loops_accepted), std::to_string(r.inter_loops_rejected),
                std::to_string(r.bytes_sent), std::to_string(r.bytes_received),
                fixed(metrics[i].transmit_kBps, 3), fixed(metrics[i].receive_kBps, 3)});
  }
  return out + "</table>\n";
}

// A table with one row per key and one column per robot; `value(robot, key)` fills the cells.
std::string keyTable(const RunSummary& run, std::string_view key_title,
                     const std::set<std::string>& keys,
                     const std::function<std::string(const RobotRun&, const std::string&)>& value) {
  std::string out = fmt::format("<table>\n<tr><th>{}</th>", key_title);
  for (std::size_t i = 0; i < run.robots.size(); ++i) out += "<th>" + robotName(run, i) + "</th>";
  out += "</tr>\n";
  for (const std::string& key : keys) {
    out += "<tr><td>" + escape(key) + "</td>";
    for (const RobotRun& robot : run.robots) out += "<td>" + value(robot, key) + "</td>";
    out += "</tr>\n";
  }
  return out + "</table>\n";
}

std::string kindTable(const RunSummary& run) {
  std::set<std::string> kinds;
  for (const RobotRun& robot : run.robots)
    for (const auto& [kind, bins] : robot.sent_over_time) kinds.insert(kind);
  if (kinds.empty()) return {};
  return keyTable(run, "bytes sent by kind", kinds,
                  [](const RobotRun& robot, const std::string& k) {
                    const auto it = robot.sent_over_time.find(k);
                    std::size_t sum = 0;
                    if (it != robot.sent_over_time.end())
                      for (const std::size_t b : it->second) sum += b;
                    return std::to_string(sum);
                  });
}

std::string counterTable(const RunSummary& run) {
  std::set<std::string> names;
  for (const RobotRun& robot : run.robots)
    for (const auto& [name, value] : robot.counters) names.insert(name);
  if (names.empty()) return "<p>No counters recorded.</p>\n";
  return keyTable(run, "counter", names, [](const RobotRun& robot, const std::string& name) {
    const auto it = robot.counters.find(name);
    return it == robot.counters.end() ? std::string("&ndash;") : counterText(it->second);
  });
}

constexpr std::string_view kStyle =
    "body{font-family:sans-serif;margin:24px;color:#222}"
    "table{border-collapse:collapse;margin:8px 0 24px}"
    "td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}"
    "td:first-child,th:first-child{text-align:left}"
    ".swatch{display:inline-block;width:10px;height:10px;margin-right:6px}"
    "svg{display:block;margin:8px 0 24px;font-size:12px}"
    "svg text{fill:#222}svg text.small{font-size:10px}"
    ".grid{stroke:#e4e4e4;stroke-width:1}.frame{fill:none;stroke:#444;stroke-width:1}"
    ".gt{fill:none;stroke-width:1}.est{fill:none;stroke-width:1.6}"
    ".odo{fill:none;stroke-width:1.2;stroke-dasharray:6 4}.loop{fill:none;stroke-width:0.8}"
    ".traffic{fill:none;stroke-width:1.4}.box-light{fill-opacity:0.3}";

std::string summaryLine(const RunSummary& run) {
  const auto accepted = std::count_if(run.loops.begin(), run.loops.end(),
                                      [](const RunLoop& l) { return l.accepted; });
  return fmt::format(
      "<p>{} robots, {} s of data, {} inter-robot loops ({} accepted by PCM, {} "
      "rejected).</p>\n",
      run.robots.size(), fixed(run.duration, 1), run.loops.size(), accepted,
      static_cast<std::ptrdiff_t>(run.loops.size()) - accepted);
}

bool anyAte(const std::vector<RobotMetrics>& metrics) {
  return std::any_of(metrics.begin(), metrics.end(), [](const RobotMetrics& m) {
    return m.ate_rmse.has_value() || m.ate_rmse_odometry_only.has_value();
  });
}

bool anyTraffic(const RunSummary& run) {
  return std::any_of(run.robots.begin(), run.robots.end(), [](const RobotRun& r) {
    return std::any_of(r.sent_over_time.begin(), r.sent_over_time.end(),
                       [](const auto& kind) { return !kind.second.empty(); });
  });
}

void checkReportInput(const RunSummary& run, const std::vector<RobotMetrics>& metrics) {
  checkRun(run);
  if (metrics.size() != run.robots.size()) {
    throw core::Error(
        fmt::format("run report: {} metrics for {} robots", metrics.size(), run.robots.size()));
  }
  for (std::size_t k = 0; k < run.loops.size(); ++k) {
    const RunLoop& loop = run.loops[k];
    if (loop.robot_a >= run.robots.size() || loop.robot_b >= run.robots.size()) {
      throw core::Error(fmt::format("run report: loop {} joins robots {} and {} but the run has {}",
                                    k, loop.robot_a, loop.robot_b, run.robots.size()));
    }
  }
  if (anyTraffic(run) && !(std::isfinite(run.meter_interval) && run.meter_interval > 0.0)) {
    throw core::Error(fmt::format("run report: meter_interval {} s is not a positive number",
                                  run.meter_interval));
  }
  if (run.map_robots.size() != run.map_points.size()) {
    throw core::Error(fmt::format("run report: {} map points but {} robots of map points",
                                  run.map_points.size(), run.map_robots.size()));
  }
  for (const std::uint8_t r : run.map_robots) {
    if (r >= run.robots.size()) {
      throw core::Error(fmt::format("run report: a map point of robot {} but the run has {}", r,
                                    run.robots.size()));
    }
  }
}

}  // namespace

std::vector<RobotMetrics> evaluateRun(const RunSummary& run) {
  checkRun(run);
  const RunPairs pairs = pairRun(run);
  std::vector<RobotMetrics> out;
  for (std::size_t i = 0; i < run.robots.size(); ++i) out.push_back(robotMetrics(run, pairs, i));
  return out;
}

std::string reportHtml(const RunSummary& run, const std::vector<RobotMetrics>& metrics) {
  checkReportInput(run, metrics);
  const std::string title = "dcl-slam run: " + escape(run.dataset);
  std::string html = fmt::format(
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      "<title>{0}</title>\n<style>{1}</style>\n</head>\n<body>\n<h1>{0}</h1>\n",
      title, kStyle);
  html += summaryLine(run) + "<h2>Accuracy</h2>\n" + accuracyTable(run, metrics);
  html += "<h2>Loops and traffic</h2>\n" + exchangeTable(run, metrics);
  if (!run.robots.empty()) {
    html += "<h2>Trajectories seen from above</h2>\n" + trajectoryPlot(run, pairRun(run));
  }
  if (!run.map_points.empty()) html += "<h2>The merged map seen from above</h2>\n" + mapPlot(run);
  if (anyAte(metrics)) html += "<h2>ATE per robot</h2>\n" + atePlot(run, metrics);
  html += "<h2>Traffic over time</h2>\n";
  html += anyTraffic(run) ? trafficPlot(run) : std::string("<p>No traffic recorded.</p>\n");
  html += kindTable(run) + "<h2>Counters</h2>\n" + counterTable(run);
  return html + "</body>\n</html>\n";
}

}  // namespace dcl::eval
