// The shared building blocks of dcl::io (file.hpp): whole-file reads, atomic
// writes, the line reader, the byte reader and number parsing.

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <dcl/io/file.hpp>

#include "cloud_test_util.hpp"

namespace dcl::io {
namespace {

using test::contains;
using test::fileError;

TEST(FileTest, ReadFileReturnsEveryByte) {
  const auto dir = test::freshDir("read_file");
  const std::string bytes("a\0b\r\n\xff", 6);
  test::writeBytes(dir / "x.bin", bytes);
  const auto data = readFile((dir / "x.bin").string());
  EXPECT_EQ(std::string(data.begin(), data.end()), bytes);
  EXPECT_TRUE(readFile((test::writeBytes(dir / "empty", ""), dir / "empty").string()).empty());
}

TEST(FileTest, ReadFileNamesAMissingFileOrAFolder) {
  const auto dir = test::freshDir("read_missing");
  const std::string missing = (dir / "nope.bin").string();
  const std::string msg = fileError([&] { readFile(missing); });
  EXPECT_TRUE(contains(msg, missing));
  EXPECT_TRUE(contains(msg, "no such file"));
  EXPECT_TRUE(contains(fileError([&] { readFile(dir.string()); }), "not a regular file"));
  EXPECT_TRUE(contains(fileError([&] { requireFile(missing); }), missing));
}

/// The names in `dir`, sorted (hidden ones too).
std::vector<std::string> filesIn(const std::filesystem::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    names.push_back(e.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

TEST(FileTest, WriteFileAtomicCreatesFoldersAndReplaces) {
  const auto dir = test::freshDir("write_atomic");
  const std::string path = (dir / "a" / "b" / "out.txt").string();
  writeFileAtomic(path, [](std::ostream& out) { out << "first"; });
  writeFileAtomic(path, [](std::ostream& out) { out << "second"; });
  EXPECT_EQ(test::readBytes(path), "second");
  EXPECT_EQ(filesIn(dir / "a" / "b"), std::vector<std::string>{"out.txt"});  // no temporary left
}

TEST(FileTest, WriteFileAtomicTakesABareNameInTheWorkingFolder) {
  const auto dir = test::freshDir("write_bare");
  const auto before = std::filesystem::current_path();
  std::filesystem::current_path(dir);
  EXPECT_NO_THROW(writeFileAtomic("tables.md", [](std::ostream& out) { out << "| a |"; }));
  std::filesystem::current_path(before);
  EXPECT_EQ(test::readBytes((dir / "tables.md").string()), "| a |");
  EXPECT_EQ(filesIn(dir), std::vector<std::string>{"tables.md"});
}

TEST(FileTest, WriteFileAtomicKeepsTheOldFileWhenTheWriterThrows) {
  const auto dir = test::freshDir("write_throws");
  const std::string path = (dir / "out.txt").string();
  writeFileAtomic(path, [](std::ostream& out) { out << "kept"; });
  EXPECT_THROW(writeFileAtomic(path,
                               [](std::ostream& out) {
                                 out << "partial";
                                 throw std::runtime_error("writer failed");
                               }),
               std::runtime_error);
  EXPECT_EQ(test::readBytes(path), "kept");
  EXPECT_EQ(filesIn(dir), std::vector<std::string>{"out.txt"});
}

TEST(FileTest, WriteFileAtomicLeavesTheUsersOtherFilesAlone) {
  const auto dir = test::freshDir("write_neighbours");
  const std::string path = (dir / "o.tum").string();
  test::writeBytes(path + ".tmp", "the user's own file");
  writeFileAtomic(path, [](std::ostream& out) { out << "new"; });
  EXPECT_EQ(test::readBytes(path + ".tmp"), "the user's own file");
  EXPECT_EQ(test::readBytes(path), "new");
  EXPECT_EQ(filesIn(dir), (std::vector<std::string>{"o.tum", "o.tum.tmp"}));
}

TEST(FileTest, WriteFileAtomicWritesThroughSymbolicLinks) {
  namespace fs = std::filesystem;
  const auto dir = test::freshDir("write_links");
  fs::create_directories(dir / "data");
  test::writeBytes(dir / "data" / "real.txt", "old");
  fs::create_symlink("data/real.txt", dir / "link.txt");
  fs::create_symlink("link.txt", dir / "link2.txt");  // a link to a link
  writeFileAtomic((dir / "link2.txt").string(), [](std::ostream& out) { out << "new"; });
  EXPECT_TRUE(fs::is_symlink(dir / "link.txt"));
  EXPECT_TRUE(fs::is_symlink(dir / "link2.txt"));
  EXPECT_EQ(test::readBytes(dir / "data" / "real.txt"), "new");
  EXPECT_EQ(filesIn(dir / "data"), std::vector<std::string>{"real.txt"});
}

TEST(FileTest, WriteFileAtomicGivesNewFilesTheUsualPermissions) {
  namespace fs = std::filesystem;
  const auto dir = test::freshDir("write_mode");
  const mode_t old_mask = umask(027);
  writeFileAtomic((dir / "new.txt").string(), [](std::ostream& out) { out << "x"; });
  umask(old_mask);
  EXPECT_EQ(fs::status(dir / "new.txt").permissions(), static_cast<fs::perms>(0640));
  fs::permissions(dir / "new.txt", static_cast<fs::perms>(0604));
  writeFileAtomic((dir / "new.txt").string(), [](std::ostream& out) { out << "y"; });
  EXPECT_EQ(fs::status(dir / "new.txt").permissions(), static_cast<fs::perms>(0604));
}

TEST(FileTest, WriteFileAtomicOntoAFolderSaysSo) {
  const auto dir = test::freshDir("write_folder");
  std::filesystem::create_directories(dir / "out.tum");
  const std::string path = (dir / "out.tum").string();
  const std::string msg = fileError([&] { writeFileAtomic(path, [](std::ostream&) {}); });
  EXPECT_TRUE(contains(msg, path + ": is a folder, not a file")) << msg;
  EXPECT_EQ(filesIn(dir), std::vector<std::string>{"out.tum"});
}

TEST(FileTest, SplitWhitespaceDropsEmptyTokens) {
  const auto tokens = splitWhitespace("  a\tbb  c\r\n");
  ASSERT_EQ(tokens.size(), 3u);
  EXPECT_EQ(tokens[0], "a");
  EXPECT_EQ(tokens[1], "bb");
  EXPECT_EQ(tokens[2], "c");
  EXPECT_TRUE(splitWhitespace(" \t ").empty());
}

TEST(FileTest, ParseNumberTakesOnlyWholeTokens) {
  EXPECT_EQ(parseNumber<int>("+42"), 42);
  EXPECT_EQ(parseNumber<int>("-7"), -7);
  EXPECT_EQ(parseNumber<double>("1e-3"), 1e-3);
  EXPECT_TRUE(std::isnan(*parseNumber<double>("nan")));
  EXPECT_FALSE(parseNumber<int>("12abc"));
  EXPECT_FALSE(parseNumber<int>(""));
  EXPECT_FALSE(parseNumber<std::uint8_t>("300"));
  EXPECT_FALSE(parseNumber<std::size_t>("-1"));
  EXPECT_FALSE(parseNumber<double>("1.5.2"));
}

TEST(FileTest, LineReaderCountsLinesAndStripsCarriageReturns) {
  const auto dir = test::freshDir("line_reader");
  test::writeBytes(dir / "t.txt", "one\r\ntwo 2\n\nlast");
  LineReader reader((dir / "t.txt").string());
  std::vector<std::string> lines;
  while (reader.next()) lines.emplace_back(reader.line());
  EXPECT_EQ(lines, (std::vector<std::string>{"one", "two 2", "", "last"}));
  EXPECT_EQ(reader.lineNumber(), 4u);
}

TEST(FileTest, LineReaderErrorsNameFileLineAndField) {
  const auto dir = test::freshDir("line_reader_error");
  const std::string path = (dir / "t.txt").string();
  test::writeBytes(path, "1 2\n3 x\n");
  LineReader reader(path);
  ASSERT_TRUE(reader.next());
  EXPECT_EQ(reader.number<int>("2", "b"), 2);
  ASSERT_TRUE(reader.next());
  const std::string msg = fileError([&] { reader.number<int>("x", "b"); });
  EXPECT_TRUE(contains(msg, path + ":2: field 'b': 'x' is not a number"));
  EXPECT_TRUE(contains(fileError([&] { LineReader((dir / "none").string()); }), "no such file"));
}

TEST(FileTest, ByteReaderReadsAndChecksBounds) {
  const std::string bytes("\x01\x00\x00\x00\x02\x00head\r\nrest", 16);
  ByteReader in(std::span<const char>(bytes.data(), bytes.size()), "mem.bin");
  EXPECT_EQ(in.read<std::uint32_t>("a"), 1u);
  EXPECT_EQ(in.read<std::uint16_t>("b"), 2u);
  EXPECT_EQ(in.readLine("line"), "head");
  EXPECT_EQ(in.offset(), 12u);
  EXPECT_EQ(in.remaining(), 4u);
  const std::string msg = fileError([&] { in.take(5, "tail"); });
  EXPECT_TRUE(contains(msg, "mem.bin: byte 12: truncated: tail needs 5 bytes, 4 left"));
  EXPECT_EQ(in.readLine("line"), "rest");
  EXPECT_TRUE(in.atEnd());
  EXPECT_TRUE(contains(fileError([&] { in.readLine("more"); }), "byte 16"));
  EXPECT_TRUE(contains(fileError([&] { in.skip(1, "pad"); }), "pad needs 1 bytes"));
}

TEST(FileTest, DescribeFormatsEveryPart) {
  EXPECT_EQ(core::describe({"f.pcd", 3, std::nullopt, "SIZE"}, "bad"),
            "f.pcd:3: field 'SIZE': bad");
  EXPECT_EQ(core::describe({"f.bin", std::nullopt, 32, std::nullopt}, "cut"),
            "f.bin: byte 32: cut");
}

}  // namespace
}  // namespace dcl::io
