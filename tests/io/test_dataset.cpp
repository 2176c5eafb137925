// dataset.yaml: round trip through the writer, the conventions written into the
// file, and the reader's errors on broken files (file, line and key named).

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/pose_file.hpp>

#include "io_test_util.hpp"

namespace dcl::io {
namespace {

using test::contains;
using test::fileError;

/// A dataset with one robot of each scan source type.
DatasetSpec mixedSpec() {
  DatasetSpec spec;
  spec.name = "mixed: four robots";  // a colon forces quoting
  spec.description = "one of each: sim, kitti, bag, mcap";
  spec.sensor = "vlp16";
  spec.mount_height = 0.8125;
  spec.sim = SimSpec{.world = WorldKind::aliasing,
                     .seed = 18446744073709551615u,
                     .motion_distortion = false,
                     .noise = true,
                     .calibration_error = false,
                     .shared_unit = true,
                     .traffic = 1.5,
                     .imu = true};
  RobotSpec a{.name = "a", .scans = {}, .ground_truth = "a/gt.tum", .start_time = 0.0};
  RobotSpec b{
      .name = "b",
      .scans = {.type = ScanSourceType::kitti, .folder = "b/velodyne", .times = "b/times.txt"},
      .ground_truth = "b/gt.tum",
      .start_time = 12.300000000000001,
      .odometry = {.file = "b/lio.txt", .format = "kitti", .times = "b/times.txt"}};
  RobotSpec c{.name = "c",
              .scans = {.type = ScanSourceType::bag, .file = "c.bag", .topic = "/points"},
              .ground_truth = "",
              .start_time = 1.0 / 3.0,
              .odometry = {.file = "c.bag", .format = "auto", .topic = "/lio/odom"}};
  RobotSpec d{.name = "d",
              .scans = {.type = ScanSourceType::mcap, .file = "d/scans.mcap", .topic = "/points"},
              .ground_truth = "d/gt.tum",
              .start_time = 2.0,
              .odometry = {.file = "d/lio.mcap", .format = "auto", .topic = "/odom"}};
  spec.robots = {a, b, c, d};
  return spec;
}

/// A valid file, to be broken line by line in the tests below.
constexpr const char* kGood =
    "format_version: 1\n"          // 1
    "name: kitti05\n"              // 2
    "sensor:\n"                    // 3
    "  model: hdl64\n"             // 4
    "  mount_height: 1.73\n"       // 5
    "robots:\n"                    // 6
    "  - name: a\n"                // 7
    "    ground_truth: a.tum\n"    // 8
    "    scans:\n"                 // 9
    "      type: kitti\n"          // 10
    "      folder: a/velodyne\n"   // 11
    "      times: a/times.txt\n";  // 12

/// kGood with the text `from` replaced by `to`.
std::string edited(const std::string& from, const std::string& to) {
  std::string text = kGood;
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST(Dataset, RoundTripKeepsEveryField) {
  test::TempDir dir;
  const DatasetSpec spec = mixedSpec();
  writeDataset(dir.file("ds"), spec);
  const DatasetSpec back = readDataset(dir.file("ds"));
  EXPECT_EQ(back.name, spec.name);
  EXPECT_EQ(back.description, spec.description);
  EXPECT_EQ(back.sensor, "vlp16");
  EXPECT_EQ(back.mount_height, 0.8125);
  ASSERT_TRUE(back.sim);
  EXPECT_EQ(back.sim->world, WorldKind::aliasing);
  EXPECT_EQ(back.sim->seed, 18446744073709551615u);
  EXPECT_FALSE(back.sim->motion_distortion);
  EXPECT_TRUE(back.sim->noise);
  EXPECT_FALSE(back.sim->calibration_error);
  EXPECT_TRUE(back.sim->shared_unit);
  EXPECT_EQ(back.sim->traffic, 1.5);
  EXPECT_TRUE(back.sim->imu);
  ASSERT_EQ(back.robots.size(), 4u);
  EXPECT_EQ(back.robots[0].scans.type, ScanSourceType::sim);
  EXPECT_EQ(back.robots[1].scans.type, ScanSourceType::kitti);
  EXPECT_EQ(back.robots[1].scans.folder, "b/velodyne");
  EXPECT_EQ(back.robots[1].scans.times, "b/times.txt");
  EXPECT_EQ(back.robots[1].start_time, 12.300000000000001);  // full precision
  EXPECT_EQ(back.robots[2].scans.type, ScanSourceType::bag);
  EXPECT_EQ(back.robots[2].scans.topic, "/points");
  EXPECT_EQ(back.robots[2].start_time, 1.0 / 3.0);
  EXPECT_EQ(back.robots[2].ground_truth, "");
  EXPECT_TRUE(back.robots[0].odometry.empty());
  EXPECT_EQ(back.robots[1].odometry.file, "b/lio.txt");
  EXPECT_EQ(back.robots[1].odometry.format, "kitti");
  EXPECT_EQ(back.robots[1].odometry.times, "b/times.txt");
  EXPECT_EQ(back.robots[2].odometry.file, "c.bag");
  EXPECT_EQ(back.robots[2].odometry.format, "auto");
  EXPECT_EQ(back.robots[2].odometry.topic, "/lio/odom");
  EXPECT_EQ(back.robots[3].scans.type, ScanSourceType::mcap);
  EXPECT_EQ(back.robots[3].scans.file, "d/scans.mcap");
  EXPECT_EQ(back.robots[3].scans.topic, "/points");
  EXPECT_EQ(back.robots[3].odometry.topic, "/odom");  // an .mcap file's topic, as a bag's
  EXPECT_EQ(back.folder, dir.file("ds"));
  EXPECT_EQ(back.resolve("b/gt.tum"), dir.file("ds") + "/b/gt.tum");
  EXPECT_EQ(back.robotIndex("c"), 2u);
  EXPECT_FALSE(back.robotIndex("e"));
}

TEST(Dataset, ReadsTheYamlFileItselfAndWithoutSimSection) {
  test::TempDir dir;
  const DatasetSpec spec = readDataset(dir.write("other.yaml", kGood));
  EXPECT_FALSE(spec.sim);
  EXPECT_EQ(spec.name, "kitti05");
  EXPECT_EQ(spec.robots[0].start_time, 0.0);
  EXPECT_EQ(spec.resolve(spec.robots[0].ground_truth), dir.file("a.tum"));
}

TEST(Dataset, ParsesTextAsTheFileItNames) {
  const DatasetSpec spec = parseDataset(kGood, "data/kitti05/dataset.yaml");
  EXPECT_EQ(spec.name, "kitti05");
  EXPECT_EQ(spec.folder, "data/kitti05");
  EXPECT_EQ(spec.resolve(spec.robots[0].ground_truth), "data/kitti05/a.tum");
  EXPECT_TRUE(contains(
      fileError([] { (void)parseDataset(edited("type: kitti", "type: lidar"), "d/dataset.yaml"); }),
      "d/dataset.yaml:10: field 'robots[0].scans.type'"));
}

TEST(Dataset, FileStatesTheConventions) {
  const std::string text = datasetYaml(mixedSpec());
  EXPECT_TRUE(contains(text, "ground_truth: T_world_sensor"));
  EXPECT_TRUE(contains(text, "ground_truth_format: tum"));
  EXPECT_TRUE(contains(text, "stamps: since_robot_start"));
  EXPECT_TRUE(contains(text, "points: sensor_frame_at_firing"));
  EXPECT_TRUE(contains(text, "units: metres_seconds_radians"));
  EXPECT_TRUE(contains(text, "name: \"mixed: four robots\""));
}

TEST(Dataset, ReadsGroundTruthRelativeToTheFolder) {
  test::TempDir dir;
  core::Trajectory gt;
  gt.push_back(0.0, Eigen::Isometry3d::Identity());
  gt.push_back(0.1, core::makePose2d(1.0, 2.0, 0.5));
  writeTumPoses(dir.file("ds/a/gt.tum"), gt);
  writeDataset(dir.file("ds"), mixedSpec());
  const DatasetSpec spec = readDataset(dir.file("ds"));
  const core::Trajectory back = readGroundTruth(spec, 0);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_TRUE(back.pose(1).isApprox(gt.pose(1), 1e-12));
  EXPECT_THROW((void)readGroundTruth(spec, 2), core::Error);  // robot c has none
}

struct BadCase {
  const char* what;
  std::string text;
  std::vector<std::string> message;  // parts the error must contain
};

TEST(Dataset, RejectsBrokenFilesNamingLineAndKey) {
  const std::vector<BadCase> cases = {
      {"missing key", edited("name: kitti05\n", ""), {":1:", "field 'name'", "missing"}},
      {"unknown top key",
       edited("name: kitti05\n", "name: x\nnmae: y\n"),
       {":3:", "field 'nmae'", "unknown key", "robots"}},
      {"unknown nested key",
       edited("  mount_height: 1.73\n", "  mount_hieght: 1.73\n"),
       {":5:", "field 'sensor.mount_hieght'", "unknown"}},
      {"wrong type",
       edited("mount_height: 1.73", "mount_height: tall"),
       {":5:", "field 'sensor.mount_height'", "expected a number"}},
      {"version",
       edited("format_version: 1", "format_version: 2"),
       {":1:", "field 'format_version'", "not supported"}},
      {"source type",
       edited("type: kitti", "type: rosbag"),
       {":10:", "field 'robots[0].scans.type'", "sim, kitti, bag or mcap"}},
      {"kitti needs times",
       edited("      times: a/times.txt\n", ""),
       {":10:", "field 'robots[0].scans.times'", "kitti source needs it"}},
      {"bag needs a topic",
       edited("type: kitti\n      folder: a/velodyne\n      times: a/times.txt",
              "type: bag\n      file: a.bag"),
       {"field 'robots[0].scans.topic'", "bag source needs it"}},
      {"robots not a list", edited("robots:\n", "robots: 3\nx:\n"), {"field 'robots'", "sequence"}},
      {"convention",
       edited("robots:\n", "conventions:\n  ground_truth: T_sensor_world\nrobots:\n"),
       {":7:", "field 'conventions.ground_truth'", "only 'T_world_sensor'"}},
      {"duplicate robot",
       std::string(kGood) + "  - name: a\n    scans: {type: sim}\n",
       {":13:", "duplicate robot name 'a'"}},
      {"robot name climbing out",
       edited("- name: a\n", "- name: ../../evil\n"),
       {":7:", "field 'robots[0].name'", "'../../evil' is not a plain name"}},
      {"robot name a dot",
       edited("- name: a\n", "- name: \".\"\n"),
       {":7:", "field 'robots[0].name'", "not a plain name"}},
      {"robot name a dot dot",
       edited("- name: a\n", "- name: \"..\"\n"),
       {":7:", "field 'robots[0].name'", "not a plain name"}},
      {"robot name absolute",
       edited("- name: a\n", "- name: /tmp/x\n"),
       {":7:", "field 'robots[0].name'", "not a plain name"}},
      {"robot name with a space",
       edited("- name: a\n", "- name: \"robot a\"\n"),
       {":7:", "field 'robots[0].name'", "not a plain name"}},
      {"robot name too long",
       edited("- name: a\n", "- name: " + std::string(65, 'r') + "\n"),
       {":7:", "field 'robots[0].name'", "at most 64 characters"}},
      {"robot name empty",
       edited("- name: a\n", "- name: \"\"\n"),
       {":7:", "field 'robots[0].name'", "must not be empty"}},
      {"start time a Unix time",
       edited("    ground_truth: a.tum\n", "    ground_truth: a.tum\n    start_time: 1700000000\n"),
       {":9:", "field 'robots[0].start_time'", "more than a day", "not a Unix time"}},
      {"start time huge",
       edited("    ground_truth: a.tum\n", "    ground_truth: a.tum\n    start_time: 1e300\n"),
       {":9:", "field 'robots[0].start_time'", "more than a day"}},
      {"ground truth climbing out",
       edited("ground_truth: a.tum", "ground_truth: ../../etc/passwd"),
       {":8:", "field 'robots[0].ground_truth'", "'../../etc/passwd' is outside the dataset folder",
        "--allow-outside-paths"}},
      {"ground truth absolute",
       edited("ground_truth: a.tum", "ground_truth: /etc/passwd"),
       {":8:", "field 'robots[0].ground_truth'", "outside the dataset folder"}},
      {"scans climbing out after a detour",
       edited("folder: a/velodyne", "folder: a/../../b"),
       {":11:", "field 'robots[0].scans.folder'", "outside the dataset folder"}},
      {"times absolute",
       edited("times: a/times.txt", "times: /data/times.txt"),
       {":12:", "field 'robots[0].scans.times'", "outside the dataset folder"}},
      {"bag climbing out",
       edited("type: kitti\n      folder: a/velodyne\n      times: a/times.txt",
              "type: bag\n      file: ../x.bag\n      topic: /points"),
       {":11:", "field 'robots[0].scans.file'", "outside the dataset folder"}},
      {"front-end format",
       edited("    scans:\n", "    odometry: {file: a.tum, format: csv}\n    scans:\n"),
       {":9:", "field 'robots[0].odometry.format'", "tum, kitti, bag, mcap or auto"}},
      {"front-end bag without its topic",
       edited("    scans:\n", "    odometry: {file: lio.bag}\n    scans:\n"),
       {":9:", "field 'robots[0].odometry.topic'", "need their topic"}},
      {"front-end mcap without its topic",
       edited("    scans:\n", "    odometry: {file: lio.mcap}\n    scans:\n"),
       {":9:", "field 'robots[0].odometry.topic'", "need their topic"}},
      {"front-end kitti without times",
       edited("    scans:\n", "    odometry: {file: lio.txt, format: kitti}\n    scans:\n"),
       {":9:", "field 'robots[0].odometry.times'", "missing"}},
      {"front-end climbing out",
       edited("    scans:\n", "    odometry: {file: ../lio.tum}\n    scans:\n"),
       {":9:", "field 'robots[0].odometry.file'", "outside the dataset folder"}},
      {"front-end without a file",
       edited("    scans:\n", "    odometry: {format: tum}\n    scans:\n"),
       {":9:", "field 'robots[0].odometry.file'", "missing"}},
      {"front-end unknown key",
       edited("    scans:\n", "    odometry: {file: a.tum, topik: /x}\n    scans:\n"),
       {":9:", "field 'robots[0].odometry.topik'", "unknown key"}},
      {"traffic below zero",
       edited("robots:\n", "sim:\n  world: city\n  seed: 1\n  traffic: -0.5\nrobots:\n"),
       {":9:", "field 'sim.traffic'", "outside [0, 10]"}},
      {"traffic too dense",
       edited("robots:\n", "sim:\n  world: city\n  seed: 1\n  traffic: 1e9\nrobots:\n"),
       {":9:", "field 'sim.traffic'", "outside [0, 10]"}},
      {"imu not a boolean",
       edited("robots:\n", "sim:\n  world: city\n  seed: 1\n  imu: sometimes\nrobots:\n"),
       {":9:", "field 'sim.imu'"}},
      {"sim seed",
       edited("robots:\n", "sim:\n  world: city\n  seed: -1\nrobots:\n"),
       {":8:", "field 'sim.seed'", "integer"}},
      {"sim world",
       edited("robots:\n", "sim:\n  world: moon\n  seed: 1\nrobots:\n"),
       {":7:", "field 'sim.world'", "city, campus or aliasing"}},
      {"bool",
       edited("robots:\n", "sim:\n  world: city\n  seed: 1\n  noise: maybe\nrobots:\n"),
       {":9:", "field 'sim.noise'", "true or false"}},
      {"malformed", edited("  model: hdl64\n", "  model: [hdl64\n"), {"malformed YAML"}},
      {"empty", "", {"expected a mapping"}},
  };
  test::TempDir dir;
  for (const auto& c : cases) {
    SCOPED_TRACE(c.what);
    const std::string path = dir.write("dataset.yaml", c.text);
    const std::string message = fileError([&] { (void)readDataset(path); });
    EXPECT_TRUE(contains(message, path));
    for (const auto& part : c.message) EXPECT_TRUE(contains(message, part));
  }
}

TEST(Dataset, PathsOutsideItsFolderOnlyWhenAllowed) {
  test::TempDir dir;
  const std::string path =
      dir.write("dataset.yaml", edited("folder: a/velodyne", "folder: /data/kitti/00/velodyne")
                                    .replace(std::string(kGood).find("ground_truth: a.tum"),
                                             std::string("ground_truth: a.tum").size(),
                                             "ground_truth: ../poses/00.tum"));
  EXPECT_THROW((void)readDataset(path), core::FileError);
  const DatasetSpec spec = readDataset(path, {.allow_outside_paths = true});
  EXPECT_EQ(spec.robots[0].scans.folder, "/data/kitti/00/velodyne");
  EXPECT_EQ(spec.resolve(spec.robots[0].scans.folder), "/data/kitti/00/velodyne");
  EXPECT_EQ(spec.robots[0].ground_truth, "../poses/00.tum");
  // Inside, a path may wander as long as it stays in: a/./b/../velodyne.
  const std::string inside =
      dir.write("dataset.yaml", edited("folder: a/velodyne", "folder: a/./b/../velodyne"));
  EXPECT_EQ(readDataset(inside).robots[0].scans.folder, "a/./b/../velodyne");
}

TEST(Dataset, MissingFileIsNamed) {
  test::TempDir dir;
  const std::string message = fileError([&] { (void)readDataset(dir.file("nowhere")); });
  EXPECT_TRUE(contains(message, "nowhere"));
}

TEST(Dataset, NamesParseBothWays) {
  for (auto kind : {WorldKind::city, WorldKind::campus, WorldKind::aliasing}) {
    EXPECT_EQ(parseWorldKind(toString(kind)), kind);
  }
  for (auto type :
       {ScanSourceType::sim, ScanSourceType::kitti, ScanSourceType::bag, ScanSourceType::mcap}) {
    EXPECT_EQ(parseScanSourceType(toString(type)), type);
  }
  EXPECT_FALSE(parseWorldKind("town"));
  EXPECT_FALSE(parseScanSourceType("pcd"));
}

}  // namespace
}  // namespace dcl::io
