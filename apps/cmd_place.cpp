// `dcl-slam bench place`: the paper's inter-robot place-recognition evaluation
// (§IV, "Performance of Distributed Loop Closure") on a dataset, with the
// published LiDAR-Iris result of the same KITTI sequence shown beside ours.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/core/error.hpp>
#include <dcl/core/progress.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/file.hpp>
#include <dcl/place/descriptor.hpp>
#include <dcl/place/evaluation.hpp>
#include <dcl/sim/sim_source.hpp>

#include "commands.hpp"
#include "output_folder.hpp"
#include "printing.hpp"

namespace dcl::apps {

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

struct PlaceOptions {
  std::string dataset;                  ///< dataset folder
  std::string descriptor = "iris";      ///< iris | scancontext
  std::string out = "out/bench_place";  ///< output folder (pr.csv, pr.svg, metrics.json)
  std::string data;                     ///< shared data folder (published LiDAR-Iris files)
  std::size_t every = 1;                ///< keep every N-th keyframe of each robot
  std::size_t max_keyframes = 0;        ///< per robot, 0: all
  bool json = false;                    ///< print metrics.json instead of the summary
  bool force = false;                   ///< replace --out even when it holds other files
};

/// Ground-truth keyframes of one robot: the paper's selector (1 m or 0.2 rad
/// since the last keyframe, DESIGN §6) applied to the ground-truth poses.
std::vector<std::size_t> keyframeFrames(const core::Trajectory& gt, std::size_t every,
                                        std::size_t max_keyframes) {
  std::vector<std::size_t> frames;
  std::size_t selected = 0;
  std::optional<Eigen::Isometry3d> last;
  for (std::size_t i = 0; i < gt.size(); ++i) {
    if (last) {
      const Eigen::Isometry3d d = last->inverse() * gt.pose(i);
      if (d.translation().norm() <= 1.0 && Eigen::AngleAxisd(d.linear()).angle() <= 0.2) continue;
    }
    last = gt.pose(i);
    if (selected++ % every == 0) frames.push_back(i);
    if (max_keyframes > 0 && frames.size() >= max_keyframes) break;
  }
  return frames;
}

/// Every robot's keyframes described, with the description time of each.
struct Described {
  std::vector<place::EvaluationKeyframe> keyframes;
  std::vector<double> describe_ms;
};

Described describeDataset(const io::DatasetSpec& spec, const place::Descriptor& descriptor,
                          const PlaceOptions& o) {
  const auto sources = sim::openDatasetScans(spec);
  Described d;
  for (std::size_t r = 0; r < spec.robots.size(); ++r) {
    const core::Trajectory gt = io::readGroundTruth(spec, r);
    const auto frames = keyframeFrames(gt, o.every, o.max_keyframes);
    core::ProgressBar progress("describe robot " + spec.robots[r].name, frames.size(), "keyframes");
    for (std::size_t k = 0; k < frames.size(); ++k) {
      const core::PointCloud scan = sources[r]->scan(frames[k]);
      const auto start = Clock::now();
      auto description = descriptor.describe(scan);
      d.describe_ms.push_back(
          std::chrono::duration<double, std::milli>(Clock::now() - start).count());
      const core::PoseKey key{core::RobotId(static_cast<std::uint8_t>(r)), core::KeyframeId(k)};
      d.keyframes.push_back({key, gt.stamp(frames[k]), gt.pose(frames[k]), std::move(description)});
      progress.update(k + 1);
    }
    progress.finish();
  }
  return d;
}

/// The KITTI sequence a dataset was split from ("kitti05-3" -> "05"), if any.
/// Its first "kitti" followed by two digits, with one '_' or '-' between or none.
std::optional<std::string> kittiSequence(const std::string& name) {
  const auto digit = [](char c) { return c >= '0' && c <= '9'; };
  for (std::size_t at = name.find("kitti"); at != std::string::npos;
       at = name.find("kitti", at + 1)) {
    std::size_t i = at + 5;
    if (i < name.size() && (name[i] == '_' || name[i] == '-')) ++i;
    if (i + 1 < name.size() && digit(name[i]) && digit(name[i + 1])) return name.substr(i, 2);
  }
  return std::nullopt;
}

/// The published LiDAR-Iris curve of that sequence, when its files are present.
std::optional<place::PrCurve> publishedCurve(const std::string& data_dir,
                                             const std::optional<std::string>& sequence) {
  if (!sequence) return std::nullopt;
  const std::string folder = data_dir + "/trajectories/kitti_loop_closure_gt/";
  const std::string gt = folder + "gt" + *sequence + ".txt";
  const std::string result = folder + "lidar_iris_result_" + *sequence + ".txt";
  if (!fs::exists(gt) || !fs::exists(result)) return std::nullopt;
  return place::evaluatePublished(place::readLoopGroundTruth(gt),
                                  place::readPublishedMatches(result));
}

double mean(const std::vector<double>& v) {
  double sum = 0.0;
  for (double x : v) sum += x;
  return v.empty() ? 0.0 : sum / static_cast<double>(v.size());
}

Json curveSummary(const place::PrCurve& c) {
  Json j = {{"queries", c.queries},
            {"positives", c.positives},
            {"recall_at_100_precision", c.recall_at_full_precision},
            {"threshold_at_100_precision", nullptr},
            {"max_f1", c.max_f1}};
  if (c.threshold_at_full_precision)
    j["threshold_at_100_precision"] = *c.threshold_at_full_precision;
  return j;
}

Json metricsJson(const io::DatasetSpec& spec, const PlaceOptions& o, const Described& d,
                 const place::PlaceEvaluation& e, const std::optional<place::PrCurve>& published,
                 const std::optional<std::string>& sequence) {
  Json j = {
      {"dataset", spec.name},
      {"descriptor", o.descriptor},
      {"keyframes", d.keyframes.size()},
      {"robots", spec.robots.size()},
      {"curve", curveSummary(e.curve)},
      {"true_loops", e.true_loops},
      {"opposite_true_loops", e.opposite_true_loops},
      {"same_direction_at_100_precision", e.same_direction},
      {"opposite_direction_at_100_precision", e.opposite_direction},
      {"yaw_error_deg",
       {{"mean", e.yaw_error_mean_deg},
        {"max", e.yaw_error_max_deg},
        {"within_2deg", e.yaw_within_2deg}}},
      {"timing_ms", {{"describe_mean", mean(d.describe_ms)}, {"query_mean", e.query_ms_mean}}}};
  if (published) {
    j["published_lidar_iris"] = curveSummary(*published);
    j["published_lidar_iris"]["sequence"] = *sequence;
    j["published_lidar_iris"]["protocol"] =
        "single robot, every frame against frames 300 or more older (the authors' files)";
  }
  return j;
}

void writeCsv(const std::string& path, const place::PrCurve& curve) {
  io::writeFileAtomic(path, [&](std::ostream& s) {
    s << "threshold,precision,recall,true_positives,false_positives\n";
    for (const auto& p : curve.points) {
      s << fmt::format("{},{},{},{},{}\n", p.threshold, p.precision, p.recall, p.true_positives,
                       p.false_positives);
    }
  });
}

/// Every query's closest candidate and the ground truth's verdict on it.
void writeQueries(const std::string& path, const std::vector<place::QueryRecord>& queries) {
  io::writeFileAtomic(path, [&](std::ostream& s) {
    s << "robot,keyframe,match_robot,match_keyframe,distance,yaw_deg,ground_truth_m,"
         "heading_difference_deg,yaw_error_deg,true_loop,has_revisit\n";
    constexpr double kDeg = 180.0 / 3.14159265358979323846;
    for (const auto& q : queries) {
      if (!q.best) continue;
      s << fmt::format("{},{},{},{},{},{:.2f},{:.3f},{:.2f},{:.2f},{:d},{:d}\n",
                       core::robotName(q.query.robot), q.query.keyframe.value(),
                       core::robotName(q.best->keyframe.robot), q.best->keyframe.keyframe.value(),
                       q.best->match.distance, q.best->match.yaw_rad * kDeg,
                       q.ground_truth_distance, q.heading_difference * kDeg, q.yaw_error * kDeg,
                       q.true_loop, q.has_revisit);
    }
  });
}

/// One curve of the SVG plot.
struct Series {
  const place::PrCurve* curve;
  std::string label;
  std::string colour;
  bool dashed;
};

/// The polyline of a curve on a plot of `size` px with a `margin` px frame.
std::string polyline(const place::PrCurve& c, double size, double margin) {
  std::string points = fmt::format("{:.1f},{:.1f} ", margin, margin);  // recall 0, precision 1
  for (const auto& p : c.points) {
    points += fmt::format("{:.1f},{:.1f} ", margin + p.recall * size,
                          margin + (1.0 - p.precision) * size);
  }
  return points;
}

std::string svgPlot(const std::vector<Series>& series, const std::string& title) {
  constexpr double kSize = 400, kMargin = 60, kFull = kSize + 2 * kMargin;
  std::string svg = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{0}\" "
      "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" "
      "fill=\"white\"/>\n<text x=\"{1}\" y=\"30\" text-anchor=\"middle\" "
      "font-size=\"14\">{2}</text>\n"
      "<rect x=\"{3}\" y=\"{3}\" width=\"{4}\" height=\"{4}\" fill=\"none\" stroke=\"black\"/>\n",
      kFull, kFull / 2, title, kMargin, kSize);
  for (int t = 0; t <= 5; ++t) {
    const double v = t / 5.0, x = kMargin + v * kSize, y = kMargin + (1 - v) * kSize;
    svg += fmt::format(
        "<line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\" stroke=\"#ddd\"/>"
        "<line x1=\"{3}\" y1=\"{4}\" x2=\"{5}\" y2=\"{4}\" stroke=\"#ddd\"/>"
        "<text x=\"{0}\" y=\"{6}\" text-anchor=\"middle\">{7:.1f}</text>"
        "<text x=\"{8}\" y=\"{9}\" text-anchor=\"end\">{7:.1f}</text>\n",
        x, kMargin, kMargin + kSize, kMargin, y, kMargin + kSize, kMargin + kSize + 18, v,
        kMargin - 6, y + 4);
  }
  svg += fmt::format(
      "<text x=\"{0}\" y=\"{1}\" text-anchor=\"middle\">recall</text>\n<text x=\"18\" y=\"{0}\" "
      "text-anchor=\"middle\" transform=\"rotate(-90 18 {0})\">precision</text>\n",
      kFull / 2, kFull - 18);
  for (std::size_t i = 0; i < series.size(); ++i) {
    const Series& s = series[i];
    svg += fmt::format(
        "<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"2\"{} points=\"{}\"/>\n"
        "<circle cx=\"{:.1f}\" cy=\"{}\" r=\"4\" fill=\"{}\"/>\n"
        "<text x=\"{}\" y=\"{}\" fill=\"{}\">{} (recall {:.2f} at 100 % precision)</text>\n",
        s.colour, s.dashed ? " stroke-dasharray=\"6 4\"" : "", polyline(*s.curve, kSize, kMargin),
        kMargin + s.curve->recall_at_full_precision * kSize, kMargin, s.colour, kMargin + 10,
        kMargin + kSize - 12 - 16.0 * static_cast<double>(series.size() - 1 - i), s.colour, s.label,
        s.curve->recall_at_full_precision);
  }
  return svg + "</svg>\n";
}

void writeOutputs(const PlaceOptions& o, const io::DatasetSpec& spec,
                  const place::PlaceEvaluation& e, const std::optional<place::PrCurve>& published,
                  const std::optional<std::string>& sequence, const Json& metrics) {
  fs::create_directories(o.out);
  writeCsv(o.out + "/pr.csv", e.curve);
  writeQueries(o.out + "/queries.csv", e.queries);
  std::vector<Series> series = {
      {&e.curve, o.descriptor + " (ours, inter-robot)", "#1f77b4", false}};
  if (published) {
    series.push_back({&*published, "LiDAR-Iris published, KITTI " + *sequence, "#d62728", true});
  }
  const std::string svg = svgPlot(series, "place recognition on " + spec.name);
  io::writeFileAtomic(o.out + "/pr.svg", [&](std::ostream& s) { s << svg; });
  io::writeFileAtomic(o.out + "/metrics.json",
                      [&](std::ostream& s) { s << metrics.dump(2) << "\n"; });
}

std::string thresholdText(const Json& curve) {
  const Json& t = curve["threshold_at_100_precision"];
  return t.is_null() ? "none" : fmt::format("{:.3f}", t.get<double>());
}

void printPlaceSummary(const Json& m) {
  const Json& c = m["curve"];
  fmt::print("bench place '{}' ({}): {} keyframes of {} robots, {} queries, {} with a revisit\n",
             m["dataset"].get<std::string>(), m["descriptor"].get<std::string>(),
             m["keyframes"].get<std::size_t>(), m["robots"].get<std::size_t>(),
             c["queries"].get<std::size_t>(), c["positives"].get<std::size_t>());
  fmt::print("  recall at 100 % precision: {:.3f} (distance below {}), max F1 {:.3f}\n",
             c["recall_at_100_precision"].get<double>(), thresholdText(c),
             c["max_f1"].get<double>());
  fmt::print("  closest candidate a true loop: {} queries ({} opposite direction)\n",
             m["true_loops"].get<std::size_t>(), m["opposite_true_loops"].get<std::size_t>());
  fmt::print(
      "  true loops kept: {} same direction, {} opposite; yaw error mean {:.2f} deg, "
      "max {:.2f} deg\n",
      m["same_direction_at_100_precision"].get<std::size_t>(),
      m["opposite_direction_at_100_precision"].get<std::size_t>(),
      m["yaw_error_deg"]["mean"].get<double>(), m["yaw_error_deg"]["max"].get<double>());
  fmt::print("  time: describe {:.3f} ms a keyframe, query {:.3f} ms\n",
             m["timing_ms"]["describe_mean"].get<double>(),
             m["timing_ms"]["query_mean"].get<double>());
  if (!m.contains("published_lidar_iris")) return;
  const Json& p = m["published_lidar_iris"];
  fmt::print(
      "  published LiDAR-Iris, KITTI {} (single robot): recall at 100 % precision {:.3f} "
      "(distance below {})\n",
      p["sequence"].get<std::string>(), p["recall_at_100_precision"].get<double>(),
      thresholdText(p));
}

void runBenchPlace(const PlaceOptions& o, const PlaceSection& section) {
  if (o.every == 0) throw core::Error("--every must be at least 1");
  OutputFolder out(o.out, o.force);
  out.requireOutside(o.dataset, "the dataset");
  const io::DatasetSpec spec = io::readDataset(o.dataset, datasetReadOptions());
  place::DescriptorConfig config = section.descriptor;
  const auto kind = place::parseDescriptorKind(o.descriptor);
  if (!kind) throw core::Error("unknown descriptor '" + o.descriptor + "' (iris or scancontext)");
  config.kind = std::string(place::toString(*kind));
  config.iris.sensor = spec.sensor;
  std::shared_ptr<const place::Descriptor> descriptor = place::makeDescriptor(config);
  Described d = describeDataset(spec, *descriptor, o);
  const place::PlaceEvaluation e =
      place::evaluatePlaces(descriptor, d.keyframes, section.evaluation);
  const auto sequence = kittiSequence(spec.name);
  const auto published = publishedCurve(o.data.empty() ? defaultDataDir() : o.data, sequence);
  const Json metrics = metricsJson(spec, o, d, e, published, sequence);
  PlaceOptions staged = o;
  staged.out = out.path();
  writeOutputs(staged, spec, e, published, sequence, metrics);
  out.commit();
  if (o.json) return fmt::print("{}\n", metrics.dump(2));
  printPlaceSummary(metrics);
  fmt::print("wrote {}/{{pr.csv,pr.svg,queries.csv,metrics.json}}\n", o.out);
}

}  // namespace

void addBenchPlaceCommand(CLI::App& bench, const AppConfig& app_config) {
  auto* cmd = bench.add_subcommand(
      "place",
      "inter-robot place recognition on a dataset: precision-recall, recall at 100 % "
      "precision, timings, beside the published LiDAR-Iris result");
  auto o = std::make_shared<PlaceOptions>();
  cmd->add_option("--dataset", o->dataset, "dataset folder (dataset.yaml), with ground truth")
      ->required();
  cmd->add_option("--descriptor", o->descriptor, "iris or scancontext")->capture_default_str();
  cmd->add_option("--out", o->out, "output folder (pr.csv, pr.svg, metrics.json)")
      ->capture_default_str();
  cmd->add_option("--data", o->data, "shared data folder (published LiDAR-Iris files)");
  cmd->add_option("--every", o->every, "keep every N-th keyframe of each robot")
      ->capture_default_str();
  cmd->add_option("--max-keyframes", o->max_keyframes, "keyframes per robot (0: all)")
      ->capture_default_str();
  cmd->add_flag("--json", o->json, "print the result as JSON");
  addForceFlag(*cmd, o->force);
  cmd->callback([o, &app_config] { runBenchPlace(*o, app_config.place); });
}

}  // namespace dcl::apps
