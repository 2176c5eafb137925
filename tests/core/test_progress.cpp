#include <cstdio>

#include <gtest/gtest.h>

#include <dcl/core/progress.hpp>

namespace dcl::core {
namespace {

TEST(Progress, FormatsCountsRateAndTimeLeft) {
  const std::string line = formatProgress("odometry", 50, 100, "frames", 10.0, "12.3 m", 10);
  EXPECT_EQ(line, "odometry [#####.....] 50/100 frames 5.0 frames/s eta 0:10  12.3 m");
}

TEST(Progress, UnknownRateGivesUnknownTimeLeft) {
  const std::string line = formatProgress("x", 0, 10, "items", 0.0, "", 4);
  EXPECT_EQ(line, "x [....] 0/10 items 0.0 items/s eta --:--");
}

TEST(Progress, Durations) {
  EXPECT_EQ(formatDuration(0.4), "0:00");
  EXPECT_EQ(formatDuration(125), "2:05");
  EXPECT_EQ(formatDuration(3725), "1:02:05");
  EXPECT_EQ(formatDuration(-1), "--:--");
}

TEST(Progress, SilentWhenNotATerminal) {
  std::FILE* file = std::tmpfile();
  ASSERT_NE(file, nullptr);
  {
    ProgressBar bar("test", 3, "frames", file);
    EXPECT_FALSE(bar.enabled());
    for (std::size_t i = 1; i <= 3; ++i) bar.update(i);
  }
  EXPECT_EQ(std::ftell(file), 0L);
  std::fclose(file);
}

}  // namespace
}  // namespace dcl::core
