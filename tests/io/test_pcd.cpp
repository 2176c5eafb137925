// PCD: the real fast_gicp scans, round trips in every encoding, hand-made
// files with every field type, and every way a file can be cut or corrupted.

#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include <dcl/io/pcd.hpp>

#include "cloud_test_util.hpp"

namespace dcl::io {
namespace {

using test::append;
using test::contains;
using test::fileError;

const std::string kPcdPairDir = test::dataDir() + "/lidar_scans/hdl_outdoor_pair_fast_gicp";

/// A PCD header; the data lines of an ASCII body start at line 12.
std::string header(const std::string& fields, const std::string& sizes, const std::string& types,
                   const std::string& counts, std::size_t width, std::size_t height,
                   const std::string& data) {
  const std::string n = std::to_string(width * height);
  return "# .PCD v0.7\nVERSION 0.7\nFIELDS " + fields + "\nSIZE " + sizes + "\nTYPE " + types +
         "\nCOUNT " + counts + "\nWIDTH " + std::to_string(width) + "\nHEIGHT " +
         std::to_string(height) + "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + n + "\nDATA " + data +
         "\n";
}

/// A valid LZF stream of literal runs only (at most 32 bytes each, prefixed by length - 1).
std::string lzfLiterals(const std::string& raw) {
  std::string out;
  for (std::size_t i = 0; i < raw.size(); i += 32) {
    const std::size_t n = std::min<std::size_t>(32, raw.size() - i);
    out.push_back(static_cast<char>(n - 1));
    out.append(raw, i, n);
  }
  return out;
}

std::string compressedBlock(const std::string& raw) {
  const std::string lzf = lzfLiterals(raw);
  std::string out;
  append<std::uint32_t>(out, static_cast<std::uint32_t>(lzf.size()));
  append<std::uint32_t>(out, static_cast<std::uint32_t>(raw.size()));
  return out + lzf;
}

class PcdTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::freshDir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  /// Writes `bytes` to a file of the test's folder and returns its path.
  std::string file(const std::string& bytes, const std::string& name = "t.pcd") {
    const std::string path = (dir_ / name).string();
    test::writeBytes(path, bytes);
    return path;
  }
  std::filesystem::path dir_;
};

TEST_F(PcdTest, ReadsTheRealScans) {
  const core::PointCloud target = readPcd(kPcdPairDir + "/251370668.pcd");
  const core::PointCloud source = readPcd(kPcdPairDir + "/251371071.pcd");
  EXPECT_EQ(target.size(), 69088u);  // POINTS of the headers
  EXPECT_EQ(source.size(), 69792u);
  ASSERT_TRUE(target.hasIntensity());
  EXPECT_FALSE(target.hasTime() || target.hasRing());
  EXPECT_FLOAT_EQ(target.points[0].x(), 0.0031398917f);
  EXPECT_FLOAT_EQ(target.points[0].y(), 2.5700350f);
  EXPECT_FLOAT_EQ(target.points[0].z(), -1.5241568f);
  EXPECT_FLOAT_EQ(target.intensity[0], 68.0f);
  Eigen::Vector3f lo = target.points[0], hi = target.points[0];
  for (const auto& p : target.points) {
    ASSERT_TRUE(p.allFinite());
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  EXPECT_TRUE(lo.isApprox(Eigen::Vector3f(-23.337479f, -74.68161f, -2.957336f)));
  EXPECT_TRUE(hi.isApprox(Eigen::Vector3f(19.024696f, 8.91951f, 10.795936f)));
}

TEST_F(PcdTest, RoundTripsInEveryEncoding) {
  const core::PointCloud real = readPcd(kPcdPairDir + "/251371071.pcd");
  core::PointCloud xyz;
  xyz.points = {{1, 2, 3}, {-4.5f, 0, 1e-7f}};
  for (auto encoding :
       {PcdEncoding::kAscii, PcdEncoding::kBinary, PcdEncoding::kBinaryCompressed}) {
    SCOPED_TRACE(static_cast<int>(encoding));
    for (const auto& cloud : {test::fullCloud(100), xyz, core::PointCloud{}, real}) {
      const std::string path = (dir_ / "round.pcd").string();
      writePcd(path, cloud, {encoding});
      EXPECT_TRUE(test::sameCloud(readPcd(path), cloud));
    }
  }
}

TEST_F(PcdTest, DecodesBytesInMemoryAsItReadsTheFile) {
  for (auto encoding :
       {PcdEncoding::kAscii, PcdEncoding::kBinary, PcdEncoding::kBinaryCompressed}) {
    const std::string path = (dir_ / "memory.pcd").string();
    writePcd(path, test::fullCloud(50), {encoding});
    const std::string bytes = test::readBytes(path);
    EXPECT_TRUE(test::sameCloud(decodePcd(bytes, "memory"), readPcd(path)));
  }
  const std::string cut = test::readBytes(kPcdPairDir + "/251370668.pcd").substr(0, 400);
  EXPECT_TRUE(contains(fileError([&] { decodePcd(cut, "cut.pcd"); }), "cut.pcd: byte "));
  EXPECT_TRUE(contains(fileError([&] { decodePcd({}, "none.pcd"); }), "none.pcd"));
}

TEST_F(PcdTest, BinaryWriterReproducesTheRealFileData) {
  const std::string original = test::readBytes(kPcdPairDir + "/251370668.pcd");
  const std::string path = (dir_ / "copy.pcd").string();
  writePcd(path, readPcd(kPcdPairDir + "/251370668.pcd"));
  const std::string copy = test::readBytes(path);
  const std::string marker = "DATA binary\n";
  EXPECT_EQ(copy.substr(copy.find(marker)), original.substr(original.find(marker)));
}

TEST_F(PcdTest, WritesAPlainHeader) {
  const std::string path = (dir_ / "h.pcd").string();
  writePcd(path, test::fullCloud(2), {PcdEncoding::kAscii});
  const std::string text = test::readBytes(path);
  EXPECT_TRUE(contains(text,
                       "FIELDS x y z intensity time ring\nSIZE 4 4 4 4 4 2\n"
                       "TYPE F F F F F U\nCOUNT 1 1 1 1 1 1\nWIDTH 2\nHEIGHT 1\n"));
  EXPECT_TRUE(contains(text, "POINTS 2\nDATA ascii\n0 -0 3 0 0 0\n0.25 -0.125 3.0625 2"));
}

TEST_F(PcdTest, AsciiOfEveryTypeWithSkippedFieldsAndAliases) {
  const std::string path = file(header("x y z rgb normal i t ring", "8 4 4 4 4 1 4 1",
                                       "F F F U F U U U", "1 1 1 1 3 1 1 1", 2, 1, "ascii") +
                                "1.5 -2 3 4278190080 0.1 0.2 0.3 200 1000000 5\r\n"
                                "\n"
                                "nan 0 +0.5 0 0 0 0 0 2000000 63\n");
  const core::PointCloud cloud = readPcd(path);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.points[0], Eigen::Vector3f(1.5f, -2, 3));
  EXPECT_TRUE(std::isnan(cloud.points[1].x()));
  EXPECT_EQ(cloud.points[1].z(), 0.5f);
  EXPECT_EQ(cloud.intensity, (std::vector<float>{200, 0}));
  EXPECT_EQ(cloud.time, (std::vector<float>{static_cast<float>(1000000 * 1e-9),
                                            static_cast<float>(2000000 * 1e-9)}));
  EXPECT_EQ(cloud.ring, (std::vector<std::uint16_t>{5, 63}));
  const core::PointCloud dropped = readPcd(path, {.drop_nan = true});
  ASSERT_EQ(dropped.size(), 1u);
  EXPECT_EQ(dropped.ring, (std::vector<std::uint16_t>{5}));
}

TEST_F(PcdTest, BinaryOfMixedTypesWithAbsoluteTimestamps) {
  std::string data;
  for (int j = 0; j < 4; ++j) {
    append<float>(data, static_cast<float>(j));                         // x
    append<double>(data, -0.5 * j);                                     // y (F8)
    append<std::int16_t>(data, static_cast<std::int16_t>(-j));          // z (I2)
    append<std::uint16_t>(data, static_cast<std::uint16_t>(1000 + j));  // intensity (U2)
    append<double>(data, 1.6e9 + 0.001 * j);                            // timestamp (F8, absolute)
    append<std::int32_t>(data, 7);                                      // extra (I4), skipped
    append<std::uint8_t>(data, static_cast<std::uint8_t>(j + 1));       // ring (U1)
  }
  const std::string path = file(header("x y z intensity timestamp extra ring", "4 8 2 2 8 4 1",
                                       "F F I U F I U", "1 1 1 1 1 1 1", 2, 2, "binary") +
                                data);
  const core::PointCloud cloud = readPcd(path);
  ASSERT_EQ(cloud.size(), 4u);
  for (int j = 0; j < 4; ++j) {
    EXPECT_EQ(cloud.points[j], Eigen::Vector3f(j, -0.5f * j, -j));
    EXPECT_EQ(cloud.intensity[j], 1000.0f + j);
    EXPECT_NEAR(cloud.time[j], 0.001 * j, 1e-6);  // relative to the earliest point
    EXPECT_EQ(cloud.ring[j], j + 1);
  }
}

TEST_F(PcdTest, BinaryCompressedIsReadFieldByField) {
  std::string raw;  // fields one after another: x x x, y y y, z z z, intensity ...
  for (int f = 0; f < 4; ++f) {
    for (int j = 0; j < 3; ++j) append<float>(raw, static_cast<float>(10 * f + j));
  }
  const std::string path =
      file(header("x y z intensity", "4 4 4 4", "F F F F", "1 1 1 1", 3, 1, "binary_compressed") +
           compressedBlock(raw));
  const core::PointCloud cloud = readPcd(path);
  ASSERT_EQ(cloud.size(), 3u);
  for (int j = 0; j < 3; ++j) {
    EXPECT_EQ(cloud.points[j], Eigen::Vector3f(j, 10 + j, 20 + j));
    EXPECT_EQ(cloud.intensity[j], 30.0f + j);
  }
}

TEST_F(PcdTest, EmptyFileIsAnError) {
  const std::string path = file("");
  const std::string msg = fileError([&] { readPcd(path); });
  EXPECT_TRUE(contains(msg, path + ": byte 0: empty file"));
}

TEST_F(PcdTest, TruncatedHeaderNamesTheLine) {
  const std::string bytes = test::readBytes(kPcdPairDir + "/251370668.pcd");
  struct Cut {
    std::string until;  // cut right after this text
    std::string expected;
  };
  for (const Cut& cut : {Cut{"# .PCD", ":1: header ends before the DATA line"},
                         Cut{"FIELDS x y", ":3: header ends before the DATA line"},
                         Cut{"POINTS 69088\n", ":10: header ends before the DATA line"},
                         Cut{"DATA bin", ":11: field 'DATA': expected ascii, binary"}}) {
    SCOPED_TRACE(cut.until);
    const std::string path = file(bytes.substr(0, bytes.find(cut.until) + cut.until.size()));
    EXPECT_TRUE(contains(fileError([&] { readPcd(path); }), path + cut.expected));
  }
}

TEST_F(PcdTest, TruncatedBinaryDataNamesTheByteAndPoint) {
  const std::string bytes = test::readBytes(kPcdPairDir + "/251370668.pcd");
  const std::size_t data = bytes.find("DATA binary\n") + 12;
  for (std::size_t points : {std::size_t{0}, std::size_t{100}, std::size_t{69087}}) {
    SCOPED_TRACE(points);
    const std::string path = file(bytes.substr(0, data + points * 16 + 5));
    const std::string msg = fileError([&] { readPcd(path); });
    EXPECT_TRUE(contains(msg, path + ": byte " + std::to_string(data + points * 16) + ":"));
    EXPECT_TRUE(contains(
        msg, "POINTS says 69088 points of 16 bytes, file ends in point " + std::to_string(points)));
  }
}

TEST_F(PcdTest, TruncatedAsciiDataNamesTheLine) {
  const std::string path = (dir_ / "a.pcd").string();
  writePcd(path, test::fullCloud(10), {PcdEncoding::kAscii});
  const std::string bytes = test::readBytes(path);
  const std::size_t line5 = bytes.find("1 -0.5 3.25");  // point 4, line 16
  const std::string mid = file(bytes.substr(0, line5 + 6), "mid.pcd");
  EXPECT_TRUE(contains(fileError([&] { readPcd(mid); }), mid + ":16: expected 6 values, found 2"));
  const std::string end = file(bytes.substr(0, line5), "end.pcd");
  EXPECT_TRUE(contains(fileError([&] { readPcd(end); }),
                       end + ":15: truncated data: expected 10 points, found 4"));
}

TEST_F(PcdTest, TruncatedCompressedDataNamesTheByte) {
  const std::string path = (dir_ / "c.pcd").string();
  writePcd(path, test::fullCloud(500), {PcdEncoding::kBinaryCompressed});
  const std::string bytes = test::readBytes(path);
  const std::size_t data = bytes.find("DATA binary_compressed\n") + 23;
  const std::string sizes = file(bytes.substr(0, data + 6), "sizes.pcd");
  EXPECT_TRUE(contains(fileError([&] { readPcd(sizes); }),
                       sizes + ": byte " + std::to_string(data + 4) +
                           ": truncated: uncompressed size needs 4 bytes, 2 left"));
  const std::string block = file(bytes.substr(0, bytes.size() - 10), "block.pcd");
  EXPECT_TRUE(contains(
      fileError([&] { readPcd(block); }),
      block + ": byte " + std::to_string(data + 8) + ": truncated: compressed data needs"));
}

TEST_F(PcdTest, CorruptHeaderValuesNameLineAndField) {
  const std::string good =
      header("x y z intensity", "4 4 4 4", "F F F F", "1 1 1 1", 1, 1, "ascii") + "1 2 3 4\n";
  struct Corruption {
    std::string from, to, expected;
  };
  for (const Corruption& c : {
           Corruption{"SIZE 4 4 4 4", "SIZE 4 4 3 4", ":5: field 'TYPE': type 'F' of size 3"},
           Corruption{"TYPE F F F F", "TYPE F F Q F", ":5: field 'TYPE': type 'Q' of size 4"},
           Corruption{"COUNT 1 1 1 1", "COUNT 1 1 1", ":6: 3 values for 4 FIELDS"},
           Corruption{"COUNT 1 1 1 1", "COUNT 1 1 3 1", ":3: field 'z': COUNT must be 1"},
           Corruption{"COUNT 1 1 1 1", "COUNT 1 1 1 0", ":6: field 'COUNT': a COUNT of 0"},
           Corruption{"COUNT 1 1 1 1", "COUNT 1 1 1 99999999999999999",
                      ":6: field 'COUNT': a COUNT of 99999999999999999"},
           Corruption{"WIDTH 1", "WIDTH 5", ":10: field 'POINTS': 1 differs from WIDTH"},
           Corruption{"WIDTH 1", "WIDTH abc", ":7: field 'WIDTH': 'abc' is not a count"},
           Corruption{"WIDTH 1", "WIDTH 1 2", ":7: field 'WIDTH': expected one value"},
           Corruption{"SIZE 4 4 4 4", "", ":11: field 'SIZE': missing from the header"},
           Corruption{"FIELDS x y", "FIELDS a y", ":3: field 'x': missing"},
           Corruption{"VERSION", "VERSON", ":2: field 'VERSON': unknown PCD header key"},
           Corruption{"HEIGHT 1", "WIDTH 1", ":8: field 'WIDTH': header key repeated"},
           Corruption{"DATA ascii", "DATA zip", ":11: field 'DATA': expected ascii"},
           Corruption{"1 2 3 4", "1 2 three 4", ":12: field 'z': 'three' is not a value"},
           Corruption{"1 2 3 4", "1 2 3 4 5", ":12: expected 4 values, found 5"},
       }) {
    SCOPED_TRACE(c.to);
    std::string text = good;
    text.replace(text.find(c.from), c.from.size(), c.to);
    const std::string path = file(text);
    EXPECT_TRUE(contains(fileError([&] { readPcd(path); }), path + c.expected));
  }
}

TEST_F(PcdTest, CorruptTypedValuesAreRejected) {
  const std::string path =
      file(header("x y z intensity ring", "4 4 4 1 4", "F F F U F", "1 1 1 1 1", 2, 1, "ascii") +
           "1 2 3 255 7\n1 2 3 300 7\n");
  EXPECT_TRUE(contains(fileError([&] { readPcd(path); }),
                       path + ":13: field 'intensity': '300' is not a value"));
  const std::string ring = file(
      header("x y z ring", "4 4 4 4", "F F F F", "1 1 1 1", 1, 1, "ascii") + "1 2 3 -1\n", "r.pcd");
  EXPECT_TRUE(contains(fileError([&] { readPcd(ring); }),
                       ring + ":12: field 'ring': ring -1 is not an integer in 0..65535"));
}

TEST_F(PcdTest, CorruptCompressedBlocksAreRejected) {
  const std::string head = header("x y z", "4 4 4", "F F F", "1 1 1", 2, 1, "binary_compressed");
  std::string raw(24, '\0');
  std::string wrong_size = compressedBlock(raw);
  wrong_size[4] = 25;  // uncompressed size 25, not 2 x 12
  const std::string a = file(head + wrong_size, "a.pcd");
  EXPECT_TRUE(contains(fileError([&] { readPcd(a); }),
                       a + ": byte " + std::to_string(head.size() + 4) +
                           ": uncompressed size 25 differs from POINTS x record size = 24"));
  std::string bad_lzf;  // a back reference before the start of the output
  append<std::uint32_t>(bad_lzf, 2);
  append<std::uint32_t>(bad_lzf, 24);
  bad_lzf += "\x20\x10";
  const std::string b = file(head + bad_lzf, "b.pcd");
  EXPECT_TRUE(contains(fileError([&] { readPcd(b); }),
                       b + ": byte " + std::to_string(head.size() + 8) + ": corrupt LZF data"));
  std::string inflated;  // claims 24 bytes from 0
  append<std::uint32_t>(inflated, 0);
  append<std::uint32_t>(inflated, 24);
  const std::string c = file(head + inflated, "c.pcd");
  EXPECT_TRUE(contains(fileError([&] { readPcd(c); }), c + ": byte "));
}

TEST_F(PcdTest, HugePointCountsFailWithoutAllocating) {
  const std::string path =
      file(header("x y z", "4 4 4", "F F F", "1 1 1", std::size_t{1} << 40, 1, "binary") + "abc");
  EXPECT_TRUE(contains(fileError([&] { readPcd(path); }), "file ends in point 0"));
  const std::string ascii =
      file(header("x y z", "4 4 4", "F F F", "1 1 1", std::size_t{1} << 40, 1, "ascii") + "1 2 3\n",
           "b.pcd");
  EXPECT_TRUE(contains(fileError([&] { readPcd(ascii); }), "found 1"));
}

TEST_F(PcdTest, WriterRejectsInconsistentClouds) {
  core::PointCloud bad = test::fullCloud(4);
  bad.ring.pop_back();
  const std::string path = (dir_ / "bad.pcd").string();
  EXPECT_TRUE(contains(fileError([&] { writePcd(path, bad); }), path));
  EXPECT_FALSE(std::filesystem::exists(path));
}

}  // namespace
}  // namespace dcl::io
