#include <type_traits>
#include <unordered_set>

#include <gtest/gtest.h>

#include <dcl/core/ids.hpp>

namespace dcl::core {
namespace {

TEST(Ids, RobotAndKeyframeIdsDoNotMix) {
  static_assert(!std::is_convertible_v<RobotId, KeyframeId>);
  static_assert(!std::is_convertible_v<int, RobotId>);
  EXPECT_FALSE(RobotId().valid());
  EXPECT_TRUE(RobotId(0).valid());
  EXPECT_LT(KeyframeId(3), KeyframeId(4));
}

TEST(Ids, PoseKeyPacksLikeGtsamSymbols) {
  // distributed-mapper's multi-robot g2o files name robot a's first pose 'a' << 56.
  const PoseKey key{RobotId(0), KeyframeId(0)};
  EXPECT_EQ(key.pack(), 6989586621679009792ULL);
  const PoseKey b17{RobotId(1), KeyframeId(17)};
  EXPECT_EQ(PoseKey::unpack(b17.pack()), b17);
  EXPECT_TRUE(PoseKey::isSymbol(b17.pack()));
  EXPECT_FALSE(PoseKey::isSymbol(42));
}

TEST(Ids, HashAndNames) {
  std::unordered_set<PoseKey> keys;
  keys.insert({RobotId(2), KeyframeId(5)});
  keys.insert({RobotId(2), KeyframeId(5)});
  keys.insert({RobotId(3), KeyframeId(5)});
  EXPECT_EQ(keys.size(), 2u);
  EXPECT_EQ(robotName(RobotId(0)), "a");
  EXPECT_EQ(robotName(RobotId(25)), "z");
  EXPECT_EQ(robotName(RobotId(30)), "30");
}

}  // namespace
}  // namespace dcl::core
