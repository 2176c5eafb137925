// MCAP files: written by io::McapWriter and read back by io::McapReader in
// every layout (the three compressions, unchunked, without summary), and
// damaged files (cut at every record boundary, bytes changed at random,
// lengths and sizes past the end) refused with a core::FileError naming the
// file, never a crash. Foxglove's own implementation reads and writes them in
// tests/ros (test_ros2_bag.cpp).
#include <cstring>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/io/mcap.hpp>

#include "io_test_util.hpp"

namespace dcl::io {
namespace {

using test::contains;
using test::fileError;

/// A message as written, to compare with what is read.
struct Written {
  std::string topic;
  std::uint64_t time = 0;
  std::vector<std::uint8_t> data;
};

std::vector<Written> sampleMessages() {
  std::mt19937 random(7);
  std::vector<Written> out;
  for (std::size_t i = 0; i < 240; ++i) {
    Written w;
    w.topic = i % 3 == 0 ? "/odom" : "/points";
    w.time = 1'000'000'000ULL + 50'000'000ULL * (i / 2);  // pairs share a time
    w.data.resize(1 + random() % 700);
    for (auto& b : w.data) b = static_cast<std::uint8_t>(i % 5 == 0 ? 0 : random());
    out.push_back(std::move(w));
  }
  return out;
}

void writeSample(const std::string& path, const McapWriteOptions& options) {
  McapWriter writer(path, options);
  const std::uint16_t cloud =
      writer.addSchema("sensor_msgs/msg/PointCloud2", "ros2msg", "uint32 a");
  const std::uint16_t odom = writer.addSchema("nav_msgs/msg/Odometry", "ros2msg", "float64 x\n");
  const std::uint16_t points = writer.addChannel(cloud, "/points", "cdr", {{"qos", "reliable"}});
  const std::uint16_t odometry = writer.addChannel(odom, "/odom", "cdr");
  for (const Written& w : sampleMessages()) {
    writer.write(w.topic == "/odom" ? odometry : points, w.time, w.time + 1, w.data);
  }
  writer.close();
}

/// Every message of `path` as "topic time bytes..." lines, in read order.
std::string contentOf(const std::string& path) {
  McapReader reader(path);
  std::map<std::uint16_t, std::string> topics;
  for (const McapChannel& c : reader.channels()) {
    const McapSchema* schema = reader.schemaOf(c);
    topics[c.id] = c.topic + " " + (schema != nullptr ? schema->name : "-");
  }
  std::string out;
  for (const McapMessageRef& ref : reader.messages()) {
    const McapMessage m = reader.read(ref);
    out += fmt::format("{} {} {} {}:", topics[m.channel_id], m.log_time, m.publish_time,
                       m.data.size());
    for (const std::uint8_t b : m.data) out += fmt::format("{:02x}", b);
    out += "\n";
  }
  return out;
}

std::string expectedContent() {
  std::vector<Written> messages = sampleMessages();
  std::stable_sort(messages.begin(), messages.end(),
                   [](const Written& a, const Written& b) { return a.time < b.time; });
  std::string out;
  for (const Written& w : messages) {
    const std::string schema =
        w.topic == "/odom" ? "nav_msgs/msg/Odometry" : "sensor_msgs/msg/PointCloud2";
    out += fmt::format("{} {} {} {} {}:", w.topic, schema, w.time, w.time + 1, w.data.size());
    for (const std::uint8_t b : w.data) out += fmt::format("{:02x}", b);
    out += "\n";
  }
  return out;
}

class McapTest : public ::testing::Test {
 protected:
  std::string file(const std::string& name, const McapWriteOptions& options) {
    const std::string path = dir_.file(name);
    writeSample(path, options);
    return path;
  }
  /// The byte offsets of every record of `bytes`' top level, and its end.
  static std::vector<std::size_t> recordBoundaries(const std::string& bytes) {
    std::vector<std::size_t> out;
    std::size_t at = 8;
    while (at + 8 < bytes.size()) {
      out.push_back(at);
      std::uint64_t length = 0;
      std::memcpy(&length, bytes.data() + at + 1, 8);
      at += 9 + length;
    }
    out.push_back(at);
    return out;
  }
  /// The offset of the first top-level record of opcode `op`.
  static std::size_t recordOf(const std::string& bytes, std::uint8_t op) {
    for (const std::size_t at : recordBoundaries(bytes)) {
      if (at < bytes.size() && static_cast<std::uint8_t>(bytes[at]) == op) return at;
    }
    ADD_FAILURE() << "no record of opcode " << int(op);
    return 0;
  }
  /// Writes `bytes` beside the other files; returns its path.
  std::string damaged(const std::string& bytes, const std::string& name = "damaged.mcap") {
    const std::string path = dir_.file(name);
    test::writeBytes(path, bytes);
    return path;
  }

  test::TempDir dir_;
};

TEST_F(McapTest, ReadsWhatItWritesInEveryCompression) {
  const std::string expected = expectedContent();
  for (const auto compression :
       {McapCompression::none, McapCompression::zstd, McapCompression::lz4}) {
    SCOPED_TRACE(std::string(toString(compression)));
    const std::string path = file("c.mcap", {.compression = compression, .chunk_size = 8192});
    McapReader reader(path);
    EXPECT_TRUE(reader.indexed());
    EXPECT_EQ(reader.profile(), "ros2");
    ASSERT_EQ(reader.channels().size(), 2u);
    EXPECT_EQ(reader.channels()[0].metadata.at("qos"), "reliable");
    EXPECT_EQ(reader.schemaOf(reader.channels()[1])->data, "float64 x\n");
    EXPECT_EQ(contentOf(path), expected);
  }
  // zstd by default, and compressed: smaller than the same file uncompressed.
  const auto zstd = test::readBytes(file("z.mcap", {}));
  const auto none = test::readBytes(file("n.mcap", {.compression = McapCompression::none}));
  EXPECT_LT(zstd.size(), none.size());
  EXPECT_NE(zstd.find("zstd"), std::string::npos);
}

TEST_F(McapTest, ReadsFilesWithoutSummaryAndUnchunkedFilesByScanning) {
  const std::string expected = expectedContent();
  for (const bool chunked : {true, false}) {
    for (const bool summary : {true, false}) {
      SCOPED_TRACE(fmt::format("chunked {} summary {}", chunked, summary));
      const std::string path = file("s.mcap", {.compression = McapCompression::lz4,
                                               .chunk_size = 5000,
                                               .chunked = chunked,
                                               .summary = summary});
      EXPECT_EQ(McapReader(path).indexed(), chunked && summary);
      EXPECT_EQ(contentOf(path), expected);
    }
  }
}

TEST_F(McapTest, AnEmptyFileHasNoMessages) {
  const std::string path = dir_.file("empty.mcap");
  McapWriter(path).close();
  McapReader reader(path);
  EXPECT_TRUE(reader.channels().empty());
  EXPECT_TRUE(reader.messages().empty());
}

TEST_F(McapTest, AWriterNotClosedLeavesNoFile) {
  const std::string path = dir_.file("unfinished.mcap");
  {
    McapWriter writer(path);
    writer.write(writer.addChannel(0, "/x", "cdr"), 1, 1, std::vector<std::uint8_t>{1, 2});
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_TRUE(std::filesystem::is_empty(std::filesystem::path(path).parent_path()));
}

TEST_F(McapTest, OtherFilesAreRefusedByName) {
  const std::string empty = damaged("", "empty.mcap");
  EXPECT_TRUE(
      contains(fileError([&] { McapReader{empty}; }), empty + ": byte 0: not an MCAP file"));
  const std::string v1 = damaged("\x89MCAP1\r\n" + std::string(100, '\0'), "v1.mcap");
  EXPECT_TRUE(contains(fileError([&] { McapReader{v1}; }), "MCAP major version '1' is not read"));
  const std::string missing = dir_.file("missing.mcap");
  EXPECT_TRUE(contains(fileError([&] { McapReader{missing}; }), missing));
}

TEST_F(McapTest, AFileCutAnywhereIsRefusedNamingIt) {
  for (const bool summary : {true, false}) {
    const std::string bytes = test::readBytes(
        file("whole.mcap",
             {.compression = McapCompression::zstd, .chunk_size = 8192, .summary = summary}));
    std::vector<std::size_t> cuts = recordBoundaries(bytes);
    for (const std::size_t b : std::vector<std::size_t>(cuts)) {
      cuts.push_back(b + 1);
      cuts.push_back(b + 9);
    }
    cuts.push_back(bytes.size() - 1);
    for (const std::size_t cut : cuts) {
      if (cut >= bytes.size()) continue;
      SCOPED_TRACE(cut);
      const std::string path = damaged(bytes.substr(0, cut));
      const std::string msg = fileError([&] { contentOf(path); });
      EXPECT_TRUE(contains(msg, path + ": ")) << msg;
    }
  }
}

TEST_F(McapTest, RandomlyDamagedFilesAreReadOrRefusedNeverACrash) {
  std::mt19937 random(11);
  int refused = 0;
  for (const auto compression :
       {McapCompression::none, McapCompression::zstd, McapCompression::lz4}) {
    for (const bool summary : {true, false}) {
      const std::string bytes = test::readBytes(
          file("whole.mcap", {.compression = compression, .chunk_size = 4096, .summary = summary}));
      for (int copy = 0; copy < 60; ++copy) {
        std::string damaged_bytes = bytes;
        const int changes = 1 + static_cast<int>(random() % 20);
        for (int i = 0; i < changes; ++i) {
          damaged_bytes[random() % damaged_bytes.size()] = static_cast<char>(random());
        }
        const std::string path = damaged(damaged_bytes);
        try {
          contentOf(path);
        } catch (const core::FileError& e) {
          EXPECT_TRUE(contains(e.what(), path + ": "));
          ++refused;
        }
      }
    }
  }
  EXPECT_GT(refused, 300);  // the CRCs catch nearly every change
}

TEST_F(McapTest, LengthsAndSizesPastTheFileAreRefusedBeforeAnythingIsAllocated) {
  const std::string bytes =
      test::readBytes(file("whole.mcap", {.compression = McapCompression::zstd, .summary = false}));
  const auto patched = [&](std::size_t at, std::uint64_t value, int size = 8) {
    std::string out = bytes;
    std::memcpy(out.data() + at, &value, size);
    return damaged(out);
  };
  // A record claiming 2^62 bytes.
  const std::size_t chunk = recordOf(bytes, 0x06);
  std::string msg = fileError([&] { McapReader{patched(chunk + 1, std::uint64_t{1} << 62)}; });
  EXPECT_TRUE(
      contains(msg, fmt::format("byte {}: record (opcode 0x06) of 4611686018427387904 bytes "
                                "runs past byte",
                                chunk)))
      << msg;
  // A chunk claiming a terabyte once decompressed.
  msg = fileError([&] { McapReader{patched(chunk + 9 + 16, std::uint64_t{1} << 40)}; });
  EXPECT_TRUE(contains(msg, "chunk of 1099511627776 bytes: damaged (at most 1073741824)")) << msg;
  // A zstd chunk claiming 2000 times its bytes.
  std::uint64_t records = 0;
  std::memcpy(&records, bytes.data() + chunk + 9 + 28 + 4 + 4, 8);
  msg = fileError([&] { McapReader{patched(chunk + 9 + 16, 2000 * records)}; });
  EXPECT_TRUE(contains(msg, "compressed: damaged (at most 1000 times)")) << msg;
  // A schema whose name claims 4 GB.
  const std::string with_summary = test::readBytes(file("s.mcap", {}));
  std::uint64_t summary_start = 0;
  std::memcpy(&summary_start, with_summary.data() + with_summary.size() - 8 - 20, 8);
  std::string out = with_summary;
  const std::uint32_t huge = 0xFFFFFFF0u;
  std::memcpy(out.data() + summary_start + 9 + 2, &huge, 4);
  std::memset(out.data() + out.size() - 8 - 4, 0, 4);  // no summary crc, to reach the schema
  msg = fileError([&] { McapReader{damaged(out)}; });
  EXPECT_TRUE(contains(msg, fmt::format("byte {}: schema name of 4294967280 bytes runs past the "
                                        "end",
                                        summary_start + 9 + 2 + 4)))
      << msg;
}

TEST_F(McapTest, ChecksumsCatchChangedBytes) {
  const std::string bytes =
      test::readBytes(file("whole.mcap", {.compression = McapCompression::none, .summary = false}));
  // A byte of a message in an uncompressed chunk: the chunk's crc.
  std::string out = bytes;
  const std::size_t chunk = recordOf(bytes, 0x06);
  out[chunk + 200] ^= 0x01;
  EXPECT_TRUE(contains(fileError([&] { contentOf(damaged(out)); }),
                       fmt::format("byte {}: chunk (none): content crc", chunk)));
  // A byte of the summary.
  const std::string indexed = test::readBytes(file("s.mcap", {}));
  std::uint64_t summary_start = 0;
  std::memcpy(&summary_start, indexed.data() + indexed.size() - 8 - 20, 8);
  out = indexed;
  out[summary_start + 12] ^= 0x01;
  EXPECT_TRUE(contains(fileError([&] { McapReader{damaged(out)}; }), "summary crc"));
}

}  // namespace
}  // namespace dcl::io
