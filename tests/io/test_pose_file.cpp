#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/io/pose_file.hpp>

#include "io_test_util.hpp"

namespace dcl::io {
namespace {

namespace fs = std::filesystem;

const std::string kData = DCL_DATA_DIR;
const std::string kKitti00 = kData + "/trajectories/evo/KITTI_00_gt.txt";
const std::string kKitti00Times = kData + "/trajectories/evo/KITTI_00_gt_times.txt";
const std::string kKitti05 = kData + "/trajectories/kitti_gt_poses/05.txt";
const std::string kKitti08 = kData + "/trajectories/kitti_gt_poses/08.txt";
const std::string kTum = kData + "/trajectories/evo/freiburg1_xyz-groundtruth.txt";
const std::string kCalib = kData + "/lidar_scans/kitti_00/calib.txt";

std::vector<std::string> lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> out;
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

std::string head(const std::string& path, std::size_t n) {
  std::string text;
  const auto all = lines(path);
  for (std::size_t i = 0; i < n && i < all.size(); ++i) text += all[i] + "\n";
  return text;
}

std::vector<double> numbersOf(const std::string& line) {
  std::istringstream in(line);
  std::vector<double> v;
  for (double x; in >> x;) v.push_back(x);
  return v;
}

/// Same stamps and translations to 1e-12; rotations to `rotation_tol` (a TUM
/// quaternion cannot carry a KITTI block's departure from orthonormality, ~1e-7).
void expectSamePoses(const core::Trajectory& a, const core::Trajectory& b,
                     double rotation_tol = 1e-12) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.stamp(i), b.stamp(i)) << i;
    const double scale = std::max(1.0, a.pose(i).translation().norm());
    EXPECT_LE((a.pose(i).translation() - b.pose(i).translation()).norm(), 1e-12 * scale) << i;
    EXPECT_LE((a.pose(i).linear() - b.pose(i).linear()).norm(), rotation_tol) << i;
  }
}

TEST(PoseFormat, ParsesNamesAndRejectsOthers) {
  EXPECT_EQ(parsePoseFormat("kitti"), PoseFormat::kitti);
  EXPECT_EQ(parsePoseFormat("tum"), PoseFormat::tum);
  EXPECT_EQ(toString(PoseFormat::kitti), "kitti");
  EXPECT_EQ(toString(PoseFormat::tum), "tum");
  try {
    parsePoseFormat("euroc");
    FAIL() << "no error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("euroc"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("kitti or tum"), std::string::npos);
  }
  EXPECT_THROW(parsePoseFormat("KITTI"), core::Error);
}

TEST(KittiPoses, ReadsGroundTruthWithTimes) {
  const auto trajectory = readKittiPoses(kKitti00, kKitti00Times);
  ASSERT_EQ(trajectory.size(), 4541u);
  ASSERT_EQ(trajectory.size(), lines(kKitti00Times).size());
  EXPECT_EQ(trajectory.stamp(0), 0.0);
  EXPECT_EQ(trajectory.stamp(1), 1.037359e-01);
  const auto raw = numbersOf(lines(kKitti00)[1]);
  ASSERT_EQ(raw.size(), 12u);
  const Eigen::Isometry3d& T = trajectory.pose(1);
  // The 3x4 matrix exactly as written, as evo and the devkit keep it.
  EXPECT_EQ(T.translation(), Eigen::Vector3d(raw[3], raw[7], raw[11]));
  EXPECT_EQ(T.linear()(0, 1), raw[1]);
  EXPECT_EQ(T.linear()(2, 0), raw[8]);
  for (const auto& pose : trajectory.poses()) {
    // Seven printed digits: orthonormal to about 1e-7, not better.
    EXPECT_LE((pose.linear().transpose() * pose.linear() - Eigen::Matrix3d::Identity()).norm(),
              1e-6);
  }
  EXPECT_EQ(trajectory.stamps().back(), numbersOf(lines(kKitti00Times).back()).front());
}

TEST(KittiPoses, WithoutTimesStampsAreTheIndex) {
  for (const auto& [path, count] : {std::pair{kKitti05, 2761u}, std::pair{kKitti08, 4071u}}) {
    const auto trajectory = readPoses(path, PoseFormat::kitti);
    ASSERT_EQ(trajectory.size(), count) << path;
    ASSERT_EQ(trajectory.size(), lines(path).size());
    for (std::size_t i = 0; i < trajectory.size(); ++i) {
      ASSERT_EQ(trajectory.stamp(i), static_cast<double>(i));
    }
    const auto last = numbersOf(lines(path).back());
    EXPECT_EQ(trajectory.poses().back().translation(), Eigen::Vector3d(last[3], last[7], last[11]));
  }
}

TEST(PoseFiles, EveryEvoTrajectoryLoads) {
  const std::string evo = kData + "/trajectories/evo/";
  for (const char* name : {"KITTI_00_gt.txt", "KITTI_00_ORB.txt", "KITTI_00_SPTAM.txt"}) {
    EXPECT_EQ(readKittiPoses(evo + name, kKitti00Times).size(), 4541u) << name;
  }
  for (const char* name : {"freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt"}) {
    std::size_t expected = 0;
    for (const auto& line : lines(evo + name)) expected += !line.empty() && line.front() != '#';
    EXPECT_EQ(readTumPoses(evo + name).size(), expected) << name;
  }
}

TEST(KittiPoses, TimesCountMismatchNamesBothFiles) {
  test::TempDir dir;
  const std::string poses = dir.write("poses.txt", head(kKitti00, 5));
  const std::string times = dir.write("times.txt", head(kKitti00Times, 4));
  const std::string message = test::fileError([&] { readKittiPoses(poses, times); });
  EXPECT_NE(message.find(poses), std::string::npos) << message;
  EXPECT_NE(message.find(times), std::string::npos) << message;
  EXPECT_NE(message.find("4 time stamps"), std::string::npos) << message;
  EXPECT_NE(message.find("5 poses"), std::string::npos) << message;
}

TEST(KittiPoses, RoundTripWithTimes) {
  test::TempDir dir;
  const auto original = readKittiPoses(kKitti00, kKitti00Times);
  writePoses(dir.file("out.txt"), PoseFormat::kitti, original, dir.file("out_times.txt"));
  const auto back = readPoses(dir.file("out.txt"), PoseFormat::kitti, dir.file("out_times.txt"));
  expectSamePoses(original, back);
  EXPECT_FALSE(fs::exists(dir.file("out.txt.tmp")));
}

TEST(TumPoses, ReadsFreiburgGroundTruth) {
  std::size_t expected = 0;
  std::string first_data_line;
  for (const auto& line : lines(kTum)) {
    if (line.empty() || line.front() == '#') continue;
    if (expected++ == 0) first_data_line = line;
  }
  const auto trajectory = readPoses(kTum, PoseFormat::tum);
  ASSERT_EQ(trajectory.size(), expected);
  ASSERT_EQ(expected, 3000u);
  const auto v = numbersOf(first_data_line);
  EXPECT_EQ(trajectory.stamp(0), v[0]);
  EXPECT_EQ(trajectory.pose(0).translation(), Eigen::Vector3d(v[1], v[2], v[3]));
  const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
  EXPECT_LE((trajectory.pose(0).linear() - q.normalized().toRotationMatrix()).norm(), 1e-15);
  EXPECT_TRUE(trajectory.isSorted());
}

TEST(TumPoses, RoundTripAndConversionFromKitti) {
  test::TempDir dir;
  const auto tum = readTumPoses(kTum);
  writeTumPoses(dir.file("tum.txt"), tum);
  expectSamePoses(tum, readTumPoses(dir.file("tum.txt")));

  const auto kitti = readKittiPoses(kKitti00, kKitti00Times);
  writePoses(dir.file("converted.txt"), PoseFormat::tum, kitti);
  expectSamePoses(kitti, readPoses(dir.file("converted.txt"), PoseFormat::tum), 1e-6);
}

TEST(TumPoses, TimesFileIsOnlyForKitti) {
  EXPECT_THROW(readPoses(kTum, PoseFormat::tum, kKitti00Times), core::Error);
  EXPECT_THROW(writePoses("unused.txt", PoseFormat::tum, core::Trajectory{}, "times.txt"),
               core::Error);
}

/// A corrupt file and what its error must say.
struct Corrupt {
  std::string name;
  std::string content;
  std::vector<std::string> expected;  ///< substrings of the message besides the path
};

const std::string kRow0 =
    "1.000000e+00 9.043680e-12 2.326809e-11 5.551115e-17 9.043683e-12 1.000000e+00 "
    "2.392370e-10 3.330669e-16 2.326810e-11 2.392370e-10 9.999999e-01 -4.440892e-16\n";
const std::string kRow1 =
    "9.999978e-01 5.272628e-04 -2.066935e-03 -4.690294e-02 -5.296506e-04 9.999992e-01 "
    "-1.154865e-03 -2.839928e-02 2.066324e-03 1.155958e-03 9.999971e-01 8.586941e-01\n";

std::vector<Corrupt> corruptKitti() {
  return {
      {"empty", "", {":1:", "no poses"}},
      {"blank", "\n  \n", {":3:", "no poses"}},
      {"cut_mid_line", kRow0 + kRow1.substr(0, 40), {":2:", "expected 12 numbers", "found 3"}},
      {"cut_mid_number", kRow0 + kRow1.substr(0, kRow1.size() - 4) + "\n", {":2:", "'tz'"}},
      {"cut_mid_file", kRow0 + kRow1 + kRow1.substr(0, 3), {":3:", "found 1"}},
      {"non_number", kRow0 + "abc" + kRow1.substr(12), {":2:", "'r11'", "'abc'"}},
      {"too_many", kRow0 + "1 " + kRow1, {":2:", "found 13"}},
      {"nan", kRow0 + kRow1.substr(0, 39) + " nan" + kRow1.substr(53), {":2:", "'tx'", "finite"}},
      {"inf", kRow0 + "inf" + kRow1.substr(12), {":2:", "'r11'", "not finite"}},
      {"not_rotation", "2 0 0 0 0 1 0 0 0 0 1 0\n", {":1:", "not orthonormal"}},
      {"reflection", "-1 0 0 0 0 1 0 0 0 0 1 0\n", {":1:", "reflection"}},
      {"overflowing_rotation",  // R^T R is inf - inf: NaN, which passed every comparison
       "1e200 0 1e200 0 1e200 0 -1e200 0 0 1 0 0\n",
       {":1:", "not orthonormal", "nan)"}},
  };
}

TEST(KittiPoses, CorruptFilesNameFileLineAndField) {
  test::TempDir dir;
  for (const auto& c : corruptKitti()) {
    const std::string path = dir.write(c.name + ".txt", c.content);
    const std::string message = test::fileError([&] { readKittiPoses(path); });
    EXPECT_NE(message.find(path), std::string::npos) << c.name << ": " << message;
    for (const auto& part : c.expected) {
      EXPECT_NE(message.find(part), std::string::npos) << c.name << ": " << message;
    }
  }
}

TEST(KittiPoses, CorruptTimesFile) {
  test::TempDir dir;
  const std::string poses = dir.write("poses.txt", kRow0 + kRow1);
  const std::vector<Corrupt> cases = {
      {"empty", "", {":1:", "no time stamps"}},
      {"word", "0\nabc\n", {":2:", "field 't'", "'abc'"}},
      {"two_numbers", "0\n1 2\n", {":2:", "found 2"}},
      {"nan", "nan\n1\n", {":1:", "not finite"}},
      {"nan_later", "0\nnan\n", {":2:", "field 't'", "'nan' is not finite"}},
      {"repeated", "0\n\n0\n", {":3:", "field 't'", "repeats the stamp 0 of line 1"}},
      {"decreasing",
       "0\n0.2\n0.1\n",
       {":3:", "field 't'", "goes back before the stamp 0.2 of line 2"}},
  };
  for (const auto& c : cases) {
    const std::string times = dir.write(c.name + ".txt", c.content);
    const std::string message = test::fileError([&] { readKittiPoses(poses, times); });
    EXPECT_NE(message.find(times), std::string::npos) << c.name << ": " << message;
    for (const auto& part : c.expected) {
      EXPECT_NE(message.find(part), std::string::npos) << c.name << ": " << message;
    }
  }
}

TEST(TumPoses, CorruptFilesNameFileLineAndField) {
  test::TempDir dir;
  const std::string good = "1305031098.6659 1.3563 0.6305 1.6380 0.6132 0.5962 -0.3311 -0.3986\n";
  const std::vector<Corrupt> cases = {
      {"empty", "", {":1:", "no poses"}},
      {"comments_only", "# t x y z qx qy qz qw\n\n", {":3:", "no poses"}},
      {"cut_mid_line", good + good.substr(0, 37), {":2:", "expected 8 numbers", "found 4"}},
      {"cut_mid_number", good + good.substr(0, 63) + "e\n", {":2:", "'qw'", "'-0.3e'"}},
      {"too_many", "# header\n" + good + "1 " + good, {":3:", "found 9"}},
      {"word_stamp", "t 1 2 3 0 0 0 1\n", {":1:", "field 't'"}},
      {"nan", "0 nan 0 0 0 0 0 1\n", {":1:", "field 'x'", "not finite"}},
      {"inf", "0 0 0 -inf 0 0 0 1\n", {":1:", "field 'z'", "not finite"}},
      {"zero_quaternion", good + "0 0 0 0 0 0 0 0\n", {":2:", "quaternion norm 0"}},
      {"trailing_comment", "0 0 0 0 0 0 0 1 # note\n", {":1:", "found 10"}},
  };
  for (const auto& c : cases) {
    const std::string path = dir.write(c.name + ".txt", c.content);
    const std::string message = test::fileError([&] { readTumPoses(path); });
    EXPECT_NE(message.find(path), std::string::npos) << c.name << ": " << message;
    for (const auto& part : c.expected) {
      EXPECT_NE(message.find(part), std::string::npos) << c.name << ": " << message;
    }
  }
}

TEST(PoseFiles, MissingFileIsAFileError) {
  const std::string path = kData + "/trajectories/no_such_file.txt";
  EXPECT_NE(test::fileError([&] { readKittiPoses(path); }).find(path), std::string::npos);
  EXPECT_NE(test::fileError([&] { readTumPoses(path); }).find(path), std::string::npos);
  EXPECT_NE(test::fileError([&] { readKittiCalib(path); }).find(path), std::string::npos);
}

/// Every cut and every one-byte corruption of a small file either loads or throws a
/// FileError that names the file and a line -- never anything else.
template <class Read>
void fuzzText(const test::TempDir& dir, const std::string& text, Read&& read) {
  const std::string path = dir.file("fuzz.txt");
  const auto check = [&](const std::string& content) {
    { std::ofstream(path, std::ios::binary | std::ios::trunc) << content; }
    try {
      read(path);
    } catch (const core::FileError& e) {
      const std::string message = e.what();
      ASSERT_EQ(message.rfind(path + ":", 0), 0u) << message;
      ASSERT_TRUE(e.location().line.has_value()) << message;
    }
  };
  // Cut and corrupt the last line only (file writes are slow on some machines).
  const std::size_t last_line = text.rfind('\n', text.size() - 2) + 1;
  check("");
  for (std::size_t cut = last_line; cut <= text.size(); ++cut) check(text.substr(0, cut));
  for (std::size_t i = last_line; i < text.size(); ++i) {
    for (const char c : {'x', '\n'}) {
      std::string corrupted = text;
      corrupted[i] = c;
      check(corrupted);
    }
  }
}

TEST(PoseFiles, TruncatedOrCorruptedAnywhereNeverCrashes) {
  test::TempDir dir;
  fuzzText(dir, head(kKitti00, 2), [](const std::string& p) { readKittiPoses(p); });
  fuzzText(dir, head(kTum, 5), [](const std::string& p) { readTumPoses(p); });
}

TEST(KittiCalib, ReadsSequenceCalibration) {
  const auto calib = readKittiCalib(kCalib);
  ASSERT_EQ(calib.matrices.size(), 5u);
  for (const char* name : {"P0", "P1", "P2", "P3", "Tr"})
    EXPECT_TRUE(calib.matrices.contains(name));
  EXPECT_EQ(calib.matrix("P2")(0, 3), 4.538225e+01);
  EXPECT_EQ(calib.matrix("P1")(0, 3), -3.861448e+02);
  const Matrix34d& Tr = calib.matrix("Tr");
  EXPECT_EQ(calib.T_cam_velo.translation(), Tr.col(3));
  EXPECT_EQ(Tr(2, 3), -2.921968648686e-01);
  EXPECT_LE((calib.T_cam_velo.linear() - Tr.leftCols<3>()).norm(), 1e-6);
  const Eigen::Matrix3d R = calib.T_cam_velo.linear();
  EXPECT_LE((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_THROW(static_cast<void>(calib.matrix("P4")), core::Error);
}

TEST(KittiCalib, CorruptFiles) {
  test::TempDir dir;
  const std::string p0 = "P0: 1 0 0 0 0 1 0 0 0 0 1 0\n";
  const std::string tr = "Tr: 0 -1 0 0.1 0 0 -1 0.2 1 0 0 0.3\n";
  const std::vector<Corrupt> cases = {
      {"empty", "", {":1:", "no calibration matrices"}},
      {"no_tr", p0, {"no 'Tr:' line"}},
      {"no_label", "1 0 0 0 0 1 0 0 0 0 1 0 0\n", {":1:", "field 'name'", "NAME: 12 numbers"}},
      {"cut_mid_line", p0 + tr.substr(0, 18), {":2:", "expected 12 numbers", "found 6"}},
      {"word", p0 + "Tr: 0 -1 0 x 0 0 -1 0.2 1 0 0 0.3\n", {":2:", "field 'tx'", "'x'"}},
      {"repeated", p0 + p0 + tr, {":2:", "field 'P0'", "repeated"}},
      {"bad_tr", p0 + "Tr: 3 0 0 0 0 1 0 0 0 0 1 0\n", {"field 'Tr'", "not orthonormal"}},
  };
  for (const auto& c : cases) {
    const std::string path = dir.write(c.name + ".txt", c.content);
    const std::string message = test::fileError([&] { readKittiCalib(path); });
    EXPECT_NE(message.find(path), std::string::npos) << c.name << ": " << message;
    for (const auto& part : c.expected) {
      EXPECT_NE(message.find(part), std::string::npos) << c.name << ": " << message;
    }
  }
}

}  // namespace
}  // namespace dcl::io
