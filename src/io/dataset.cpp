// dataset.yaml is read with yaml-cpp directly: it holds a list of robots, which
// the flat ConfigVisitor of config.hpp does not describe. Every error names the
// file, the line (from YAML::Mark) and the dotted key.
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <dcl/core/error.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/pose_file.hpp>

namespace dcl::io {

namespace {

namespace fs = std::filesystem;

constexpr std::size_t kMaxRobotName = 64;
constexpr double kMostStartTime = 86400.0;  ///< s, a day

/// The fixed conventions: key, the only accepted value, and what it means.
struct Convention {
  std::string_view key;
  std::string_view value;
  std::string_view doc;
};
constexpr std::array<Convention, 5> kConventions = {{
    {"ground_truth", "T_world_sensor", "TUM poses map sensor points into the shared world frame"},
    {"ground_truth_format", "tum", "t x y z qx qy qz qw, one pose a line"},
    {"stamps", "since_robot_start", "s since the robot's own start (start_time: swarm clock)"},
    {"points", "sensor_frame_at_firing", "each point in the sensor frame when it was fired"},
    {"units", "metres_seconds_radians", "SI units everywhere"},
}};

/// A YAML mapping being read: remembers which keys were used to reject the others.
class MapReader {
 public:
  MapReader(const std::string& source, std::string prefix, YAML::Node node, YAML::Mark mark)
      : source_(source), prefix_(std::move(prefix)), node_(std::move(node)), mark_(mark) {
    if (!node_.IsMap()) fail(mark_, prefix_, "expected a mapping");
  }

  /// The value of `key`; none if absent.
  std::optional<YAML::Node> optional(const std::string& key) {
    used_.insert(key);
    const YAML::Node& map = node_;  // const: operator[] must not insert the key
    const YAML::Node value = map[key];
    if (!value) return std::nullopt;
    return value;
  }

  /// The value of `key`; a FileError if absent.
  YAML::Node required(const std::string& key) {
    if (auto value = optional(key)) return *value;
    fail(mark_, keyOf(key), "missing (required)");
  }

  /// A nested mapping under `key`.
  MapReader map(const std::string& key, const YAML::Node& node) const {
    return {source_, keyOf(key), node, node.Mark()};
  }

  std::string string(const std::string& key, const YAML::Node& node) const {
    if (!node.IsScalar()) fail(node.Mark(), keyOf(key), "expected a string");
    return node.Scalar();
  }

  double number(const std::string& key, const YAML::Node& node) const {
    const auto value = node.IsScalar() ? parseNumber<double>(node.Scalar()) : std::nullopt;
    if (!value || !std::isfinite(*value)) fail(node.Mark(), keyOf(key), "expected a number");
    return *value;
  }

  template <class Int>
  Int integer(const std::string& key, const YAML::Node& node) const {
    const auto value = node.IsScalar() ? parseNumber<Int>(node.Scalar()) : std::nullopt;
    if (!value) fail(node.Mark(), keyOf(key), "expected an integer");
    return *value;
  }

  bool boolean(const std::string& key, const YAML::Node& node) const {
    const std::string text = node.IsScalar() ? node.Scalar() : "";
    if (text == "true" || text == "false") return text == "true";
    fail(node.Mark(), keyOf(key), "expected true or false");
  }

  /// Throws for keys nobody asked for, listing the known ones.
  void finish() const {
    for (const auto& item : node_) {
      const std::string key = item.first.Scalar();
      if (used_.count(key)) continue;
      std::string known;
      for (const auto& k : used_) known.append(known.empty() ? "" : ", ").append(k);
      fail(item.first.Mark(), keyOf(key), "unknown key (known: " + known + ")");
    }
  }

  [[nodiscard]] std::string keyOf(const std::string& key) const {
    return prefix_.empty() ? key : prefix_ + "." + key;
  }

  [[noreturn]] void fail(const YAML::Mark& mark, const std::string& key,
                         const std::string& what) const {
    core::FileLocation location{source_};
    if (!mark.is_null()) location.line = static_cast<std::size_t>(mark.line) + 1;
    if (!key.empty()) location.field = key;
    throw core::FileError(location, what);
  }

  [[nodiscard]] const YAML::Mark& mark() const { return mark_; }

 private:
  const std::string& source_;
  std::string prefix_;
  YAML::Node node_;
  YAML::Mark mark_;
  std::set<std::string> used_;
};

// ---- reading ----

void readSensor(MapReader sensor, DatasetSpec& spec) {
  spec.sensor = sensor.string("model", sensor.required("model"));
  if (auto h = sensor.optional("mount_height"))
    spec.mount_height = sensor.number("mount_height", *h);
  sensor.finish();
}

void readConventions(MapReader conventions) {
  for (const auto& c : kConventions) {
    const auto node = conventions.optional(std::string(c.key));
    if (!node) continue;
    const std::string value = conventions.string(std::string(c.key), *node);
    if (value != c.value) {
      conventions.fail(node->Mark(), conventions.keyOf(std::string(c.key)),
                       fmt::format("'{}' is not supported (only '{}': {})", value, c.value, c.doc));
    }
  }
  conventions.finish();
}

SimSpec readSim(MapReader sim) {
  SimSpec out;
  const YAML::Node world = sim.required("world");
  const auto kind = parseWorldKind(sim.string("world", world));
  if (!kind) sim.fail(world.Mark(), sim.keyOf("world"), "expected city, campus or aliasing");
  out.world = *kind;
  out.seed = sim.integer<std::uint64_t>("seed", sim.required("seed"));
  if (auto n = sim.optional("motion_distortion")) {
    out.motion_distortion = sim.boolean("motion_distortion", *n);
  }
  if (auto n = sim.optional("noise")) out.noise = sim.boolean("noise", *n);
  if (auto n = sim.optional("calibration_error")) {
    out.calibration_error = sim.boolean("calibration_error", *n);
  }
  if (auto n = sim.optional("shared_unit")) out.shared_unit = sim.boolean("shared_unit", *n);
  if (auto n = sim.optional("imu")) out.imu = sim.boolean("imu", *n);
  if (auto n = sim.optional("traffic")) {
    out.traffic = sim.number("traffic", *n);
    if (!(out.traffic >= 0.0 && out.traffic <= kMaxTraffic)) {
      sim.fail(n->Mark(), sim.keyOf("traffic"),
               fmt::format("{} is outside [0, {}] (times the world's own traffic)", out.traffic,
                           kMaxTraffic));
    }
  }
  sim.finish();
  return out;
}

/// Checks that the path in field `key` (at `node`) stays inside the dataset
/// folder: relative, and not climbing out of it, unless `options` allow it.
void checkInside(const MapReader& reader, const std::string& key, const YAML::Node& node,
                 const std::string& path, const DatasetReadOptions& options) {
  if (options.allow_outside_paths) return;
  const fs::path p = fs::path(path).lexically_normal();
  const bool climbs = !p.empty() && *p.begin() == "..";
  if (p.is_absolute() || p.has_root_name() || p.has_root_directory() || climbs)
    reader.fail(node.Mark(), reader.keyOf(key),
                fmt::format("'{}' is outside the dataset folder (give paths relative to it, or "
                            "pass --allow-outside-paths to read files elsewhere)",
                            path));
}

/// A string field the scan source type `type` needs.
std::string requiredPath(MapReader& scans, const std::string& key, std::string_view type,
                         const DatasetReadOptions& options) {
  const auto node = scans.optional(key);
  if (!node)
    scans.fail(scans.mark(), scans.keyOf(key), fmt::format("missing (a {} source needs it)", type));
  std::string path = scans.string(key, *node);
  checkInside(scans, key, *node, path, options);
  return path;
}

ScanSourceSpec readScans(MapReader scans, const DatasetReadOptions& options) {
  ScanSourceSpec out;
  const YAML::Node type = scans.required("type");
  const auto parsed = parseScanSourceType(scans.string("type", type));
  if (!parsed) scans.fail(type.Mark(), scans.keyOf("type"), "expected sim, kitti, bag or mcap");
  out.type = *parsed;
  if (out.type == ScanSourceType::kitti) {
    out.folder = requiredPath(scans, "folder", "kitti", options);
    out.times = requiredPath(scans, "times", "kitti", options);
  } else if (out.type == ScanSourceType::bag || out.type == ScanSourceType::mcap) {
    const std::string name(toString(out.type));
    out.file = requiredPath(scans, "file", name, options);
    const auto topic = scans.optional("topic");
    if (!topic) {
      scans.fail(scans.mark(), scans.keyOf("topic"),
                 fmt::format("missing (a {} source needs it)", name));
    }
    out.topic = scans.string("topic", *topic);
    if (const auto imu = scans.optional("imu_topic"))
      out.imu_topic = scans.string("imu_topic", *imu);
    if (const auto rpy = scans.optional("imu_rpy")) {
      if (!rpy->IsSequence() || rpy->size() != 3)
        scans.fail(rpy->Mark(), scans.keyOf("imu_rpy"), "expected [roll, pitch, yaw] in deg");
      for (std::size_t k = 0; k < 3; ++k) {
        out.imu_rpy[k] = scans.number("imu_rpy", (*rpy)[k]);
        if (std::abs(out.imu_rpy[k]) > 360.0)
          scans.fail((*rpy)[k].Mark(), scans.keyOf("imu_rpy"), "an angle beyond 360 deg");
      }
    }
  }
  scans.finish();
  return out;
}

FrontEndSpec readFrontEnd(MapReader odometry, const DatasetReadOptions& options) {
  FrontEndSpec out;
  out.file = requiredPath(odometry, "file", "front-end", options);
  if (auto f = odometry.optional("format")) {
    out.format = odometry.string("format", *f);
    if (out.format != "tum" && out.format != "kitti" && out.format != "bag" &&
        out.format != "mcap" && out.format != "auto")
      odometry.fail(f->Mark(), odometry.keyOf("format"), "expected tum, kitti, bag, mcap or auto");
  }
  const bool bag =
      out.format == "bag" || out.format == "mcap" ||
      (out.format == "auto" && (out.file.ends_with(".bag") || out.file.ends_with(".mcap")));
  if (bag) {
    const auto topic = odometry.optional("topic");
    if (!topic) {
      odometry.fail(odometry.mark(), odometry.keyOf("topic"),
                    "missing (poses from a bag need their topic)");
    }
    out.topic = odometry.string("topic", *topic);
  }
  if (out.format == "kitti") out.times = requiredPath(odometry, "times", "kitti", options);
  odometry.finish();
  return out;
}

RobotSpec readRobot(MapReader robot, const DatasetReadOptions& options) {
  RobotSpec out;
  const YAML::Node name = robot.required("name");
  out.name = robot.string("name", name);
  if (out.name.empty()) robot.fail(name.Mark(), robot.keyOf("name"), "must not be empty");
  // A robot's name is its output folder and file prefix: a path ("..",
  // "../x", "/x") would write outside the output folder the user named.
  const bool plain =
      out.name.size() <= kMaxRobotName && std::all_of(out.name.begin(), out.name.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_' || c == '-';
      });
  if (!plain)
    robot.fail(name.Mark(), robot.keyOf("name"),
               fmt::format("'{}' is not a plain name: letters, digits, '_' and '-' only, at most "
                           "{} characters (it names the robot's output folder)",
                           out.name, kMaxRobotName));
  const YAML::Node scans = robot.required("scans");
  out.scans = readScans(robot.map("scans", scans), options);
  if (auto gt = robot.optional("ground_truth")) {
    out.ground_truth = robot.string("ground_truth", *gt);
    checkInside(robot, "ground_truth", *gt, out.ground_truth, options);
  }
  if (auto f = robot.optional("odometry"))
    out.odometry = readFrontEnd(robot.map("odometry", *f), options);
  if (auto t = robot.optional("start_time")) {
    out.start_time = robot.number("start_time", *t);
    // Seconds on the swarm clock, not a Unix time: a run would wait that long.
    if (std::abs(out.start_time) > kMostStartTime)
      robot.fail(t->Mark(), robot.keyOf("start_time"),
                 fmt::format("{:g} s is more than a day from the swarm clock's zero (it is "
                             "seconds on the swarm clock, not a Unix time)",
                             out.start_time));
  }
  robot.finish();
  return out;
}

void readRobots(const MapReader& top, const YAML::Node& list, DatasetSpec& spec,
                const DatasetReadOptions& options) {
  if (!list.IsSequence() || list.size() == 0) {
    top.fail(list.Mark(), "robots", "expected a non-empty sequence of robots");
  }
  std::set<std::string> names;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string key = fmt::format("robots[{}]", i);
    spec.robots.push_back(readRobot(top.map(key, list[i]), options));
    if (!names.insert(spec.robots.back().name).second) {
      top.fail(list[i].Mark(), key + ".name",
               "duplicate robot name '" + spec.robots.back().name + "'");
    }
  }
}

void readTop(MapReader top, DatasetSpec& spec, const DatasetReadOptions& options) {
  const YAML::Node version = top.required("format_version");
  spec.format_version = top.integer<int>("format_version", version);
  if (spec.format_version != kDatasetFormatVersion) {
    top.fail(version.Mark(), "format_version",
             fmt::format("version {} is not supported (this program reads version {})",
                         spec.format_version, kDatasetFormatVersion));
  }
  spec.name = top.string("name", top.required("name"));
  if (auto d = top.optional("description")) spec.description = top.string("description", *d);
  const YAML::Node sensor = top.required("sensor");
  readSensor(top.map("sensor", sensor), spec);
  if (auto c = top.optional("conventions")) readConventions(top.map("conventions", *c));
  if (auto s = top.optional("sim")) spec.sim = readSim(top.map("sim", *s));
  readRobots(top, top.required("robots"), spec, options);
  top.finish();
}

YAML::Node parseYaml(std::string_view text, const std::string& path) {
  try {
    return YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    core::FileLocation location{path};
    if (!e.mark.is_null()) location.line = static_cast<std::size_t>(e.mark.line) + 1;
    throw core::FileError(location, "malformed YAML: " + e.msg);
  }
}

// ---- writing ----

/// A scalar as YAML writes it (quoted when it must be).
std::string scalar(const std::string& text) {
  YAML::Emitter emitter;
  emitter << text;
  return emitter.c_str();
}

void writeHeader(std::ostream& out, const DatasetSpec& spec) {
  out << "# dcl-slam dataset. Paths are relative to this folder.\n";
  out << "format_version: " << spec.format_version << "\n";
  out << "name: " << scalar(spec.name) << "\n";
  if (!spec.description.empty()) out << "description: " << scalar(spec.description) << "\n";
  out << "sensor:\n";
  out << "  model: " << scalar(spec.sensor) << "  # hdl64 | vlp16 | another recorded sensor\n";
  out << "  mount_height: " << fmt::format("{}", spec.mount_height)
      << "  # m, sensor above the ground\n";
  out << "conventions:  # fixed; a reader refuses other values\n";
  for (const auto& c : kConventions) {
    out << "  " << c.key << ": " << c.value << "  # " << c.doc << "\n";
  }
}

void writeSim(std::ostream& out, const SimSpec& sim) {
  out << "sim:  # scans are regenerated from this, the sensor and the ground truth\n";
  out << "  world: " << toString(sim.world) << "  # city | campus | aliasing\n";
  out << "  seed: " << sim.seed << "  # world and scan noise derive from it\n";
  out << "  motion_distortion: " << (sim.motion_distortion ? "true" : "false") << "\n";
  out << "  noise: " << (sim.noise ? "true" : "false") << "  # range noise and dropout\n";
  out << "  calibration_error: " << (sim.calibration_error ? "true" : "false")
      << "  # with noise: each robot's lasers off the published table\n";
  out << "  shared_unit: " << (sim.shared_unit ? "true" : "false")
      << "  # with calibration_error: every robot carries the first robot's unit\n";
  if (sim.imu) out << "  imu: true  # every scan comes with the robot's IMU reading of up\n";
  if (sim.traffic > 0.0) {
    out << "  traffic: " << fmt::format("{}", sim.traffic)
        << "  # moving actors, times the world's own traffic\n";
  }
}

void writeRobot(std::ostream& out, const RobotSpec& robot) {
  out << "  - name: " << scalar(robot.name) << "\n";
  out << "    start_time: " << fmt::format("{}", robot.start_time) << "  # s on the swarm clock\n";
  if (!robot.ground_truth.empty())
    out << "    ground_truth: " << scalar(robot.ground_truth) << "\n";
  if (!robot.odometry.empty()) {
    out << "    odometry:  # an external front-end's poses, instead of the built-in odometry\n";
    out << "      file: " << scalar(robot.odometry.file) << "\n";
    out << "      format: " << scalar(robot.odometry.format)
        << "  # tum | kitti | bag | mcap | auto\n";
    if (!robot.odometry.topic.empty())
      out << "      topic: " << scalar(robot.odometry.topic) << "\n";
    if (!robot.odometry.times.empty())
      out << "      times: " << scalar(robot.odometry.times) << "\n";
  }
  out << "    scans:\n";
  out << "      type: " << toString(robot.scans.type) << "  # sim | kitti | bag | mcap\n";
  if (robot.scans.type == ScanSourceType::kitti) {
    out << "      folder: " << scalar(robot.scans.folder) << "\n";
    out << "      times: " << scalar(robot.scans.times) << "\n";
  } else if (robot.scans.type == ScanSourceType::bag || robot.scans.type == ScanSourceType::mcap) {
    out << "      file: " << scalar(robot.scans.file) << "\n";
    out << "      topic: " << scalar(robot.scans.topic) << "\n";
    if (!robot.scans.imu_topic.empty()) {
      out << "      imu_topic: " << scalar(robot.scans.imu_topic) << "\n";
      const auto& rpy = robot.scans.imu_rpy;
      if (rpy != std::array<double, 3>{0.0, 0.0, 0.0})
        out << "      imu_rpy: [" << exactText(rpy[0]) << ", " << exactText(rpy[1]) << ", "
            << exactText(rpy[2]) << "]\n";
    }
  }
}

}  // namespace

std::string_view toString(ScanSourceType type) {
  switch (type) {
    case ScanSourceType::kitti:
      return "kitti";
    case ScanSourceType::bag:
      return "bag";
    case ScanSourceType::mcap:
      return "mcap";
    default:
      return "sim";
  }
}

std::optional<ScanSourceType> parseScanSourceType(std::string_view name) {
  for (auto type :
       {ScanSourceType::sim, ScanSourceType::kitti, ScanSourceType::bag, ScanSourceType::mcap}) {
    if (toString(type) == name) return type;
  }
  return std::nullopt;
}

std::string_view toString(WorldKind kind) {
  switch (kind) {
    case WorldKind::campus:
      return "campus";
    case WorldKind::aliasing:
      return "aliasing";
    default:
      return "city";
  }
}

std::optional<WorldKind> parseWorldKind(std::string_view name) {
  for (auto kind : {WorldKind::city, WorldKind::campus, WorldKind::aliasing}) {
    if (toString(kind) == name) return kind;
  }
  return std::nullopt;
}

std::string DatasetSpec::resolve(const std::string& relative) const {
  const fs::path p(relative);
  if (p.is_absolute() || folder.empty()) return p.string();
  return (fs::path(folder) / p).string();
}

std::optional<std::size_t> DatasetSpec::robotIndex(std::string_view robot_name) const {
  for (std::size_t i = 0; i < robots.size(); ++i) {
    if (robots[i].name == robot_name) return i;
  }
  return std::nullopt;
}

DatasetSpec readDataset(const std::string& path, const DatasetReadOptions& options) {
  const bool is_folder = fs::is_directory(path);
  const std::string file = is_folder ? (fs::path(path) / kDatasetFileName).string() : path;
  const std::vector<char> bytes = readFile(file);
  return parseDataset(std::string_view(bytes.data(), bytes.size()), file, options);
}

DatasetSpec parseDataset(std::string_view text, const std::string& file,
                         const DatasetReadOptions& options) {
  const YAML::Node root = parseYaml(text, file);
  if (!root.IsMap()) throw core::FileError({file}, "expected a mapping of dataset keys");
  DatasetSpec spec;
  readTop(MapReader(file, "", root, root.Mark()), spec, options);
  spec.folder = fs::path(file).parent_path().string();
  return spec;
}

std::string datasetYaml(const DatasetSpec& spec) {
  std::ostringstream out;
  writeHeader(out, spec);
  if (spec.sim) writeSim(out, *spec.sim);
  out << "robots:\n";
  for (const auto& robot : spec.robots) writeRobot(out, robot);
  return out.str();
}

void writeDataset(const std::string& folder, const DatasetSpec& spec) {
  const std::string text = datasetYaml(spec);
  writeFileAtomic((fs::path(folder) / kDatasetFileName).string(),
                  [&](std::ostream& out) { out << text; });
}

core::Trajectory readGroundTruth(const DatasetSpec& spec, std::size_t robot) {
  const RobotSpec& r = spec.robots.at(robot);
  if (r.ground_truth.empty()) {
    throw core::Error(
        fmt::format("dataset '{}': robot '{}' has no ground truth", spec.name, r.name));
  }
  return readTumPoses(spec.resolve(r.ground_truth));
}

}  // namespace dcl::io
