// PLY: the real small_gicp scans, round trips, hand-made files in every
// encoding with other elements to skip, and every way a file can be cut or corrupted.

#include <algorithm>
#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include <dcl/io/ply.hpp>

#include "cloud_test_util.hpp"

namespace dcl::io {
namespace {

using test::append;
using test::contains;
using test::fileError;

const std::string kPlyPairDir = test::dataDir() + "/lidar_scans/small_gicp_pair";

/// `value` in big-endian byte order.
template <class T>
void appendBigEndian(std::string& out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  std::reverse(bytes, bytes + sizeof(T));
  out.append(bytes, sizeof(T));
}

class PlyTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::freshDir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  std::string file(const std::string& bytes, const std::string& name = "t.ply") {
    const std::string path = (dir_ / name).string();
    test::writeBytes(path, bytes);
    return path;
  }
  std::filesystem::path dir_;
};

TEST_F(PlyTest, ReadsTheRealScans) {
  const core::PointCloud source = readPly(kPlyPairDir + "/source.ply");
  const core::PointCloud target = readPly(kPlyPairDir + "/target.ply");
  EXPECT_EQ(source.size(), 69792u);  // element vertex of the headers
  EXPECT_EQ(target.size(), 69088u);
  ASSERT_TRUE(target.hasIntensity());  // from CloudCompare's scalar_intensity
  EXPECT_FLOAT_EQ(target.points[0].x(), 0.0031398917f);
  EXPECT_FLOAT_EQ(target.intensity[0], 68.0f);
  for (const auto& p : source.points) ASSERT_TRUE(p.allFinite());
}

TEST_F(PlyTest, RoundTripsInBothEncodings) {
  const core::PointCloud real = readPly(kPlyPairDir + "/target.ply");
  core::PointCloud xyz;
  xyz.points = {{1, 2, 3}, {-4.5f, 0, 1e-7f}};
  for (auto encoding : {PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian}) {
    SCOPED_TRACE(static_cast<int>(encoding));
    for (const auto& cloud : {test::fullCloud(100), xyz, core::PointCloud{}, real}) {
      const std::string path = (dir_ / "round.ply").string();
      writePly(path, cloud, {encoding});
      EXPECT_TRUE(test::sameCloud(readPly(path), cloud));
    }
  }
}

TEST_F(PlyTest, DecodesBytesInMemoryAsItReadsTheFile) {
  for (auto encoding : {PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian}) {
    const std::string path = (dir_ / "memory.ply").string();
    writePly(path, test::fullCloud(50), {encoding});
    const std::string bytes = test::readBytes(path);
    EXPECT_TRUE(test::sameCloud(decodePly(bytes, "memory"), readPly(path)));
  }
  const std::string cut = test::readBytes(kPlyPairDir + "/target.ply").substr(0, 400);
  EXPECT_TRUE(contains(fileError([&] { decodePly(cut, "cut.ply"); }), "cut.ply: byte "));
  EXPECT_TRUE(contains(fileError([&] { decodePly({}, "none.ply"); }), "none.ply"));
}

TEST_F(PlyTest, WritesAPlainHeader) {
  const std::string path = (dir_ / "h.ply").string();
  writePly(path, test::fullCloud(2), {PlyEncoding::kAscii});
  EXPECT_EQ(test::readBytes(path),
            "ply\nformat ascii 1.0\ncomment written by dcl-slam\nelement vertex 2\n"
            "property float x\nproperty float y\nproperty float z\nproperty float intensity\n"
            "property float time\nproperty ushort ring\nend_header\n"
            "0 -0 3 0 0 0\n0.25 -0.125 3.0625 2 0.0009765625 1\n");
}

TEST_F(PlyTest, BigEndianWithDoublesAndFacesToSkip) {
  std::string text =
      "ply\r\nformat binary_big_endian 1.0\r\nelement camera 1\r\nproperty float view\r\n"
      "element vertex 3\r\nproperty double x\r\nproperty double y\r\nproperty double z\r\n"
      "property uchar red\r\nproperty int16 intensity\r\nproperty uint t\r\n"
      "property uint8 ring\r\nelement face 2\r\nproperty list uchar int vertex_indices\r\n"
      "end_header\r\n";
  appendBigEndian<float>(text, 1.0f);  // the camera
  for (int j = 0; j < 3; ++j) {
    appendBigEndian<double>(text, 0.1 * j);
    appendBigEndian<double>(text, -1000.5 + j);
    appendBigEndian<double>(text, 2.0);
    appendBigEndian<std::uint8_t>(text, 255);
    appendBigEndian<std::int16_t>(text, static_cast<std::int16_t>(-300 * j));
    appendBigEndian<std::uint32_t>(text, 250000u * j);
    appendBigEndian<std::uint8_t>(text, static_cast<std::uint8_t>(40 + j));
  }
  for (int f = 0; f < 2; ++f) {
    appendBigEndian<std::uint8_t>(text, 3);
    for (int i = 0; i < 3; ++i) appendBigEndian<std::int32_t>(text, i);
  }
  const core::PointCloud cloud = readPly(file(text));
  ASSERT_EQ(cloud.size(), 3u);
  for (int j = 0; j < 3; ++j) {
    EXPECT_EQ(cloud.points[j], Eigen::Vector3f(static_cast<float>(0.1 * j), -1000.5f + j, 2));
    EXPECT_EQ(cloud.intensity[j], -300.0f * j);
    EXPECT_EQ(cloud.time[j], static_cast<float>(250000.0 * j * 1e-9));
    EXPECT_EQ(cloud.ring[j], 40 + j);
  }
}

TEST_F(PlyTest, AsciiWithFacesBeforeAndAfterTheVertices) {
  const std::string path = file(
      "ply\nformat ascii 1.0\ncomment hand made\nelement edge 1\nproperty int a\n"
      "property list uchar int b\nelement vertex 2\nproperty float nx\nproperty float x\n"
      "property float y\nproperty float z\nproperty float scalar_intensity\n"
      "element face 2\nproperty list uchar int vertex_indices\nproperty uchar flag\n"
      "end_header\n"
      "7 2 0 1\n"
      "0.5 1 2 3 9\n\n"
      "0.5 nan 5 6 10\n"
      "3 0 1 1 0\n"
      "0 1\n");
  const core::PointCloud cloud = readPly(path);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.points[0], Eigen::Vector3f(1, 2, 3));
  EXPECT_TRUE(std::isnan(cloud.points[1].x()));
  EXPECT_EQ(cloud.intensity, (std::vector<float>{9, 10}));
  const core::PointCloud dropped = readPly(path, {.drop_nan = true});
  EXPECT_EQ(dropped.size(), 1u);
  EXPECT_EQ(dropped.intensity, (std::vector<float>{9}));
}

TEST_F(PlyTest, EmptyFileIsAnError) {
  const std::string path = file("");
  EXPECT_TRUE(contains(fileError([&] { readPly(path); }), path + ": byte 0: empty file"));
}

TEST_F(PlyTest, TruncatedHeaderNamesTheLine) {
  const std::string bytes = test::readBytes(kPlyPairDir + "/target.ply");
  struct Cut {
    std::string until, expected;
  };
  for (const Cut& cut :
       {Cut{"pl", ":1: not a PLY file"}, Cut{"ply\n", ":1: header ends before end_header"},
        Cut{"element vertex 69088\n", ":6: header ends before end_header"},
        Cut{"end_hea", ":11: unknown header keyword 'end_hea'"}}) {
    SCOPED_TRACE(cut.until);
    const std::string path = file(bytes.substr(0, bytes.find(cut.until) + cut.until.size()));
    EXPECT_TRUE(contains(fileError([&] { readPly(path); }), path + cut.expected));
  }
}

TEST_F(PlyTest, TruncatedBinaryDataNamesTheByteAndVertex) {
  const std::string bytes = test::readBytes(kPlyPairDir + "/target.ply");
  const std::size_t data = bytes.find("end_header\n") + 11;
  for (std::size_t vertices : {std::size_t{0}, std::size_t{7}, std::size_t{69087}}) {
    SCOPED_TRACE(vertices);
    const std::string path = file(bytes.substr(0, data + vertices * 16 + 9));
    const std::string msg = fileError([&] { readPly(path); });
    EXPECT_TRUE(contains(msg, path + ": byte " + std::to_string(data + vertices * 16) +
                                  ": field 'vertex': truncated data: 69088 vertices of 16 bytes, "
                                  "file ends in vertex " +
                                  std::to_string(vertices)));
  }
}

TEST_F(PlyTest, TruncatedFacesAreNoticed) {
  std::string text =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
      "property float y\nproperty float z\nelement face 2\n"
      "property list uchar int vertex_indices\nend_header\n";
  const std::size_t data = text.size();
  for (int i = 0; i < 3; ++i) append<float>(text, 1.0f);
  append<std::uint8_t>(text, 3);
  for (int i = 0; i < 3; ++i) append<std::int32_t>(text, 0);
  append<std::uint8_t>(text, 3);
  append<std::int32_t>(text, 0);  // 2 of the 3 indices missing
  const std::string path = file(text);
  EXPECT_TRUE(contains(fileError([&] { readPly(path); }),
                       path + ": byte " + std::to_string(data + 12 + 13 + 1) +
                           ": truncated: vertex_indices needs 12 bytes, 4 left"));
  const std::string ascii = file(
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
      "1 2 3\n3 0 0 0\n",
      "a.ply");
  EXPECT_TRUE(contains(fileError([&] { readPly(ascii); }),
                       ascii + ":11: field 'face': truncated data: expected 2 records, found 1"));
}

TEST_F(PlyTest, TruncatedAsciiVerticesNameTheLine) {
  const std::string path = (dir_ / "a.ply").string();
  writePly(path, test::fullCloud(10), {PlyEncoding::kAscii});
  const std::string bytes = test::readBytes(path);
  const std::size_t point4 = bytes.find("1 -0.5 3.25");  // line 16
  const std::string mid = file(bytes.substr(0, point4 + 6), "mid.ply");
  EXPECT_TRUE(contains(fileError([&] { readPly(mid); }), mid + ":16: expected 6 values, found 2"));
  const std::string end = file(bytes.substr(0, point4), "end.ply");
  EXPECT_TRUE(contains(fileError([&] { readPly(end); }),
                       end + ":15: truncated data: expected 10 points, found 4"));
}

TEST_F(PlyTest, CorruptHeadersNameLineAndField) {
  const std::string good =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nproperty uchar ring\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n1 2 3 4\n3 0 1 2\n";
  struct Corruption {
    std::string from, to, expected;
  };
  for (const Corruption& c : {
           Corruption{"format ascii 1.0", "format ascii 2.0", ":2: field 'format': expected"},
           Corruption{"format ascii", "format zip", ":2: field 'format': unknown encoding 'zip'"},
           Corruption{"format ascii 1.0\n", "", ":9: field 'format': missing from the header"},
           Corruption{"vertex 1", "vertex -1", ":3: field 'vertex': '-1' is not a count"},
           Corruption{"vertex 1", "vertices 1", ":10: field 'vertex': no vertex element"},
           Corruption{"float y", "float16 y", ":5: field 'y': unknown property type 'float16'"},
           Corruption{"float y", "float", ":5: expected 'property <type> <name>'"},
           Corruption{"float x", "float nx", ":3: field 'x': vertex lacks it"},
           Corruption{"float z", "list uchar int z", ":3: field 'z': list properties of vertices"},
           Corruption{"list uchar int", "list float int",
                      ":9: field 'vertex_indices': a list count"},
           Corruption{"element vertex 1", "property float w\nelement vertex 1",
                      ":3: property before any element"},
           Corruption{"end_header", "end_head", ":10: unknown header keyword 'end_head'"},
           Corruption{"1 2 3 4", "1 2 3 256", ":11: field 'ring': '256' is not a value"},
           Corruption{"1 2 3 4", "1 2 x 4", ":11: field 'z': 'x' is not a value"},
           Corruption{"3 0 1 2", "4 0 1 2", ":12: field 'face': expected 5 values, found 4"},
           Corruption{"3 0 1 2", "9 0 1 2", ":12: field 'vertex_indices': bad list length '9'"},
           Corruption{"3 0 1 2", "2 0 1 2", ":12: field 'face': expected 3 values, found 4"},
           Corruption{"3 0 1 2", "-1 0 1 2", ":12: field 'vertex_indices': bad list length"},
       }) {
    SCOPED_TRACE(c.to);
    std::string text = good;
    text.replace(text.find(c.from), c.from.size(), c.to);
    const std::string path = file(text);
    EXPECT_TRUE(contains(fileError([&] { readPly(path); }), path + c.expected));
  }
}

TEST_F(PlyTest, CorruptBinaryListLengthsAreRejected) {
  std::string text =
      "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\n"
      "property list char int vertex_indices\nend_header\n";
  const std::size_t data = text.size();
  append<std::int8_t>(text, -3);
  const std::string path = file(text);
  EXPECT_TRUE(contains(fileError([&] { readPly(path); }),
                       path + ": byte " + std::to_string(data) +
                           ": field 'vertex_indices': negative list length -3"));
}

TEST_F(PlyTest, HugeElementCountsFailWithoutAllocating) {
  const std::string path = file(
      "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty float x\n"
      "property float y\nproperty float z\nend_header\nabc");
  EXPECT_TRUE(contains(fileError([&] { readPly(path); }), "file ends in vertex 0"));
  const std::string faces = file(
      "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n"
      "property float y\nproperty float z\nelement face 18446744073709551615\n"
      "property double a\nend_header\n",
      "f.ply");
  EXPECT_TRUE(contains(fileError([&] { readPly(faces); }), "element 'face' is too large"));
}

TEST_F(PlyTest, WriterRejectsInconsistentClouds) {
  core::PointCloud bad = test::fullCloud(4);
  bad.time.pop_back();
  const std::string path = (dir_ / "bad.ply").string();
  EXPECT_TRUE(contains(fileError([&] { writePly(path, bad); }), path));
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST_F(PlyTest, ColouredPointsInBothEncodings) {
  const std::vector<Eigen::Vector3f> points{{1, 2, 3}, {-4.5f, 0, 1e-7f}};
  const std::vector<Rgb> colours{{0x1f, 0x77, 0xb4}, {255, 0, 14}};
  const std::string ascii = (dir_ / "a.ply").string();
  writeColouredPly(ascii, points, colours, {PlyEncoding::kAscii});
  EXPECT_EQ(test::readBytes(ascii),
            "ply\nformat ascii 1.0\ncomment written by dcl-slam\nelement vertex 2\n"
            "property float x\nproperty float y\nproperty float z\nproperty uchar red\n"
            "property uchar green\nproperty uchar blue\nend_header\n"
            "1 2 3 31 119 180\n-4.5 0 1e-07 255 0 14\n");
  const std::string binary = (dir_ / "b.ply").string();
  writeColouredPly(binary, points, colours);
  const std::string bytes = test::readBytes(binary);
  const std::size_t data = bytes.find("end_header\n") + 11;
  ASSERT_EQ(bytes.size() - data, 2u * 15u);  // three floats and three bytes a point
  EXPECT_EQ(bytes.substr(data + 12, 3), "\x1f\x77\xb4");
  EXPECT_EQ(bytes.substr(data + 27, 3), std::string("\xff\x00\x0e", 3));
  // The reader takes the points and skips the colours, in either encoding.
  core::PointCloud expected;
  expected.points = points;
  EXPECT_TRUE(test::sameCloud(readPly(ascii), expected));
  EXPECT_TRUE(test::sameCloud(readPly(binary), expected));
}

TEST_F(PlyTest, ColouredWriterWantsAColourAPoint) {
  const std::vector<Eigen::Vector3f> points{{1, 2, 3}, {4, 5, 6}};
  const std::vector<Rgb> colours{{1, 2, 3}};
  const std::string path = (dir_ / "bad.ply").string();
  const std::string message = fileError([&] { writeColouredPly(path, points, colours); });
  EXPECT_TRUE(contains(message, path)) << message;
  EXPECT_TRUE(contains(message, "2 points but 1 colours")) << message;
  EXPECT_FALSE(std::filesystem::exists(path));
}

}  // namespace
}  // namespace dcl::io
