// The progress display of a swarm run: its lines, and the board that redraws
// them on a terminal.
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/progress.hpp>
#include <dcl/swarm/swarm_progress.hpp>

namespace dcl::swarm {
namespace {

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

SwarmStatus threeRobots() {
  SwarmStatus s;
  s.time = 30.0;
  s.end = 120.0;
  s.robots = {{"a", 300, 300, 150, 12, 1'210'000, false},
              {"b", 120, 600, 40, 3, 45'600, false},
              {"c", 80, 400, 30, 0, 0, true}};
  return s;
}

TEST(SwarmProgress, OneLinePerRobotWithItsFigures) {
  const std::vector<std::string> lines = progressLines("run demo", threeRobots(), 10.0);
  ASSERT_EQ(lines.size(), 4u);
  // A quarter of the simulated time in 10 s: 30 s left.
  EXPECT_TRUE(contains(lines[0], "run demo [######..................] t 30/120 s")) << lines[0];
  EXPECT_TRUE(contains(lines[0], "500/1300 frames")) << lines[0];
  EXPECT_TRUE(contains(lines[0], "eta 0:30")) << lines[0];
  EXPECT_TRUE(contains(lines[1], "a [##########]")) << lines[1];
  EXPECT_TRUE(contains(lines[1], "300/300 frames")) << lines[1];
  EXPECT_TRUE(contains(lines[1], "150 kf")) << lines[1];
  EXPECT_TRUE(contains(lines[1], "12 loops")) << lines[1];
  EXPECT_TRUE(contains(lines[1], "1.21 MB sent")) << lines[1];
  EXPECT_TRUE(contains(lines[2], "b [##........]")) << lines[2];
  EXPECT_TRUE(contains(lines[2], "45.6 kB sent")) << lines[2];
  EXPECT_TRUE(contains(lines[3], "(left)")) << lines[3];
  EXPECT_FALSE(contains(lines[2], "(left)"));
}

TEST(SwarmProgress, ManyRobotsShowTheSlowestAndSumUpTheRest) {
  SwarmStatus s;
  s.end = 100.0;
  for (std::size_t r = 0; r < 27; ++r) {
    // Robot r has played (r * 7) % 27 of its 27 scans: all different.
    std::string name = "r";
    name += std::to_string(r);
    s.robots.push_back({name, (r * 7) % 27, 27, 10, 1, 1000, false});
  }
  const std::vector<std::string> lines = progressLines("run campus", s, 1.0, 8);
  ASSERT_EQ(lines.size(), 1u + 8u);
  // The seven slowest (0..6 scans played), in member order, then the others.
  std::vector<std::string> shown;
  for (std::size_t i = 1; i < 8; ++i)
    shown.push_back(lines[i].substr(2, lines[i].find(' ', 2) - 2));
  EXPECT_EQ(shown, (std::vector<std::string>{"r0", "r4", "r8", "r12", "r16", "r20", "r24"}));
  EXPECT_TRUE(contains(lines[8], "+ 20 more robots (0 done): 200 kf 20 loops 20.0 kB sent"))
      << lines[8];
}

TEST(SwarmProgress, Bytes) {
  EXPECT_EQ(formatBytes(0), "0 B");
  EXPECT_EQ(formatBytes(999), "999 B");
  EXPECT_EQ(formatBytes(12'345), "12.3 kB");
  EXPECT_EQ(formatBytes(3'400'000'000), "3.40 GB");
}

TEST(ProgressBoard, RedrawsItsLinesInPlace) {
  const std::vector<std::string> lines{"first", "a much longer second line"};
  // The first draw starts where the cursor is.
  EXPECT_EQ(core::redrawText(0, lines, 0),
            "\rfirst\x1b[K\na much longer second line\x1b[K\n\x1b[J");
  // The next goes back up over the lines drawn, and cuts what the terminal cannot hold.
  EXPECT_EQ(core::redrawText(2, lines, 10), "\r\x1b[2Afirst\x1b[K\na much lo\x1b[K\n\x1b[J");
}

TEST(ProgressBoard, SilentWhenNotATerminal) {
  std::FILE* file = std::tmpfile();
  ASSERT_NE(file, nullptr);
  {
    core::ProgressBoard board(file);
    EXPECT_FALSE(board.enabled());
    EXPECT_FALSE(board.due());
    const std::vector<std::string> lines = progressLines("run", threeRobots(), 1.0);
    board.draw(lines);
    board.finish(lines);
  }
  EXPECT_EQ(std::ftell(file), 0L);
  std::fclose(file);
}

}  // namespace
}  // namespace dcl::swarm
