// The place index: the k-d tree's nearest keys against brute force, incremental
// insertion, exclusion of recent own keyframes, the acceptance threshold; then
// the same on real KITTI HDL-64 scans and simulated ones with LiDAR-Iris.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <system_error>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include <dcl/core/error.hpp>
#include <dcl/place/lidar_iris.hpp>
#include <dcl/place/place_index.hpp>
#include <dcl/sim/sim_source.hpp>

#include "descriptor_test_data.hpp"

namespace dcl::place {
namespace {

/// A stand-in description: a key and a longer signature whose mean absolute
/// difference is the match distance (so key order and match order differ).
class FakeDescription final : public PlaceDescriptor {
 public:
  FakeDescription(std::vector<float> key, std::vector<float> signature)
      : key_(std::move(key)), signature_(std::move(signature)) {}
  [[nodiscard]] DescriptorKind kind() const override { return DescriptorKind::kLidarIris; }
  [[nodiscard]] std::span<const float> key() const override { return key_; }
  [[nodiscard]] const std::vector<float>& signature() const { return signature_; }

 private:
  std::vector<float> key_;
  std::vector<float> signature_;
};

class FakeDescriptor final : public Descriptor {
 public:
  static constexpr std::size_t kKey = 8;
  [[nodiscard]] DescriptorKind kind() const override { return DescriptorKind::kLidarIris; }
  [[nodiscard]] std::size_t keySize() const override { return kKey; }
  [[nodiscard]] std::shared_ptr<const PlaceDescriptor> describe(
      const core::PointCloud& /*scan*/) const override {
    return nullptr;
  }
  [[nodiscard]] Match match(const PlaceDescriptor& query,
                            const PlaceDescriptor& candidate) const override {
    const auto& a = dynamic_cast<const FakeDescription&>(query).signature();
    const auto& b = dynamic_cast<const FakeDescription&>(candidate).signature();
    double sum = 0;
    for (std::size_t i = 0; i < a.size(); ++i) sum += std::abs(a[i] - b[i]);
    return {sum / static_cast<double>(a.size()), 0.25, false, 0};
  }
};

/// `n` random descriptions: key = the signature's first kKey values.
std::vector<std::shared_ptr<const PlaceDescriptor>> randomDescriptions(std::size_t n,
                                                                       unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<std::shared_ptr<const PlaceDescriptor>> out;
  for (std::size_t i = 0; i < n; ++i) {
    std::vector<float> signature(32);
    for (float& s : signature) s = u(rng);
    std::vector<float> key(signature.begin(), signature.begin() + FakeDescriptor::kKey);
    out.push_back(std::make_shared<FakeDescription>(std::move(key), std::move(signature)));
  }
  return out;
}

float keyDistance(const PlaceDescriptor& a, const PlaceDescriptor& b) {
  float sum = 0;
  for (std::size_t i = 0; i < a.key().size(); ++i) {
    sum += (a.key()[i] - b.key()[i]) * (a.key()[i] - b.key()[i]);
  }
  return std::sqrt(sum);
}

/// Slots of the k nearest keys among the first `limit` stored, by linear scan.
std::vector<std::size_t> bruteForceNearest(
    const std::vector<std::shared_ptr<const PlaceDescriptor>>& all, const PlaceDescriptor& query,
    std::size_t k, std::size_t limit) {
  std::vector<std::size_t> slots(limit);
  for (std::size_t i = 0; i < limit; ++i) slots[i] = i;
  std::sort(slots.begin(), slots.end(), [&](std::size_t a, std::size_t b) {
    return keyDistance(*all[a], query) < keyDistance(*all[b], query);
  });
  slots.resize(std::min(k, limit));
  std::sort(slots.begin(), slots.end());
  return slots;
}

std::vector<std::size_t> sortedSlots(const std::vector<PlaceCandidate>& ranked) {
  std::vector<std::size_t> slots;
  for (const auto& c : ranked) slots.push_back(c.slot);
  std::sort(slots.begin(), slots.end());
  return slots;
}

PlaceIndex makeIndex(const PlaceIndexConfig& config = {}) {
  return PlaceIndex(std::make_shared<FakeDescriptor>(), core::RobotId(1), config);
}

TEST(PlaceIndex, NearestKeysMatchBruteForceWhileGrowing) {
  const auto stored = randomDescriptions(700, 1);
  const auto queries = randomDescriptions(20, 2);
  PlaceIndex index = makeIndex();
  for (std::size_t i = 0; i < stored.size(); ++i) {
    index.add(core::KeyframeId(100 + i), stored[i]);
    if (i % 97 != 0 && i + 1 != stored.size()) continue;
    for (const auto& q : queries) {
      const auto ranked = index.rank(*q);
      ASSERT_EQ(sortedSlots(ranked), bruteForceNearest(stored, *q, 10, i + 1)) << "size " << i + 1;
      for (std::size_t r = 1; r < ranked.size(); ++r) {
        EXPECT_LE(ranked[r - 1].match.distance, ranked[r].match.distance);
      }
      EXPECT_EQ(ranked.front().keyframe.robot, core::RobotId(1));
      EXPECT_EQ(ranked.front().keyframe.keyframe, core::KeyframeId(100 + ranked.front().slot));
    }
  }
}

TEST(PlaceIndex, TopOneEqualsLinearScanWhenAllAreCandidates) {
  const auto stored = randomDescriptions(60, 3);
  PlaceIndexConfig config;
  config.candidates = 60;
  PlaceIndex index = makeIndex(config);
  for (std::size_t i = 0; i < stored.size(); ++i) index.add(core::KeyframeId(i), stored[i]);
  FakeDescriptor fake;
  for (const auto& q : randomDescriptions(10, 4)) {
    std::size_t best = 0;
    for (std::size_t i = 1; i < stored.size(); ++i) {
      if (fake.match(*q, *stored[i]).distance < fake.match(*q, *stored[best]).distance) best = i;
    }
    EXPECT_EQ(index.rank(*q).front().slot, best);
  }
}

TEST(PlaceIndex, QueryRightAfterInsertSeesIt) {
  const auto stored = randomDescriptions(40, 5);
  PlaceIndex index = makeIndex();
  EXPECT_TRUE(index.rank(*stored[0]).empty());
  EXPECT_FALSE(index.query(*stored[0]));
  for (std::size_t i = 0; i < stored.size(); ++i) {
    index.add(core::KeyframeId(i), stored[i]);
    const auto hit = index.query(*stored[i]);  // itself: distance 0
    ASSERT_TRUE(hit) << i;
    EXPECT_EQ(hit->slot, i);
    EXPECT_DOUBLE_EQ(hit->match.distance, 0.0);
    EXPECT_FLOAT_EQ(hit->key_distance, 0.0f);
    EXPECT_DOUBLE_EQ(hit->match.yaw_rad, 0.25);
  }
  EXPECT_EQ(index.size(), 40u);
}

TEST(PlaceIndex, SameRobotQueriesSkipTheMostRecent) {
  const auto stored = randomDescriptions(30, 6);
  PlaceIndexConfig config;
  config.exclude_recent = 12;
  config.candidates = 100;
  PlaceIndex index = makeIndex(config);
  for (std::size_t i = 0; i < stored.size(); ++i) {
    index.add(core::KeyframeId(i), stored[i]);
    const auto own = index.rank(*stored[i], QueryScope::kSameRobot);
    EXPECT_EQ(own.size(), i + 1 > 12 ? i + 1 - 12 : 0u);
    for (const auto& c : own) EXPECT_LT(c.slot + 12, i + 1);
    EXPECT_EQ(index.rank(*stored[i], QueryScope::kOtherRobot).size(), i + 1);
  }
  // The newest keyframe is its own best match only when other robots ask.
  EXPECT_FALSE(index.query(*stored.back(), QueryScope::kSameRobot) &&
               index.query(*stored.back(), QueryScope::kSameRobot)->slot == 29);
}

TEST(PlaceIndex, ThresholdIsStrict) {
  const auto stored = randomDescriptions(20, 7);
  PlaceIndexConfig config;
  PlaceIndex probe = makeIndex();
  for (std::size_t i = 0; i < stored.size(); ++i) probe.add(core::KeyframeId(i), stored[i]);
  const auto q = randomDescriptions(1, 8).front();
  const double best = probe.rank(*q).front().match.distance;
  EXPECT_GT(best, 0.0);
  config.max_distance = best;  // "below": equal is rejected
  PlaceIndex strict = makeIndex(config);
  config.max_distance = std::nextafter(best, 1.0);
  PlaceIndex loose = makeIndex(config);
  for (std::size_t i = 0; i < stored.size(); ++i) {
    strict.add(core::KeyframeId(i), stored[i]);
    loose.add(core::KeyframeId(i), stored[i]);
  }
  EXPECT_FALSE(strict.query(*q));
  ASSERT_TRUE(loose.query(*q));
  EXPECT_DOUBLE_EQ(loose.query(*q)->match.distance, best);
}

TEST(PlaceIndex, RejectsForeignDescriptions) {
  PlaceIndex index = makeIndex();
  EXPECT_THROW(index.add(core::KeyframeId(0), nullptr), core::Error);
  auto short_key =
      std::make_shared<FakeDescription>(std::vector<float>(3, 0.0f), std::vector<float>(32, 0.0f));
  EXPECT_THROW(index.add(core::KeyframeId(0), short_key), core::Error);
  EXPECT_EQ(index.size(), 0u);
}

/// LiDAR-Iris descriptions of real KITTI 00 scans and simulated HDL-64 scans.
class RealIndex : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    iris_ = std::make_shared<LidarIris>();
    for (int frame : {0, 1, 94, 95, 198, 199})
      kitti_[frame] = iris_->describe(test::kittiScan(frame));
    const auto folder = std::filesystem::path(::testing::TempDir()) /
                        ("dcl_place_index_demo_" + std::to_string(::getpid()));
    sim::PresetOptions options;
    options.sensor = "hdl64";
    const io::DatasetSpec spec =
        sim::writeSimDataset(folder.string(), sim::makePreset("small-3", options));
    const sim::SimWorld world(spec);
    for (std::size_t i = 0; i < 400; i += 10)
      simulated_.push_back(iris_->describe(world.scan(0, i)));
    std::error_code ec;
    std::filesystem::remove_all(folder, ec);
  }
  static void TearDownTestSuite() {
    iris_.reset();
    kitti_.clear();
    simulated_.clear();
  }

  /// An index of KITTI frames 0, 94, 198 among the simulated scans (slots in that order).
  static PlaceIndex mixedIndex() {
    PlaceIndex index(iris_, core::RobotId(0));
    std::size_t id = 0;
    for (std::size_t i = 0; i < simulated_.size(); ++i) {
      index.add(core::KeyframeId(id++), simulated_[i]);
      if (i == 5) index.add(core::KeyframeId(id++), kitti_[0]);
      if (i == 20) index.add(core::KeyframeId(id++), kitti_[94]);
      if (i == 35) index.add(core::KeyframeId(id++), kitti_[198]);
    }
    return index;
  }

  static inline std::shared_ptr<const LidarIris> iris_;
  static inline std::map<int, std::shared_ptr<const PlaceDescriptor>> kitti_;
  static inline std::vector<std::shared_ptr<const PlaceDescriptor>> simulated_;
};

TEST_F(RealIndex, KittiRevisitsAreFoundAndAgreeWithALinearScan) {
  const PlaceIndex index = mixedIndex();
  ASSERT_GT(index.size(), 40u);
  for (const auto& [query, expected] :
       std::vector<std::pair<int, int>>{{1, 0}, {95, 94}, {199, 198}}) {
    const auto hit = index.query(*kitti_[query]);
    ASSERT_TRUE(hit) << query;
    EXPECT_EQ(&index.description(hit->slot), kitti_[expected].get()) << query;
    EXPECT_LT(hit->match.distance, 0.2) << query;
    // Consecutive frames: the car turns a few degrees at most between them.
    EXPECT_LT(std::abs(test::degrees(hit->match.yaw_rad)), 5.0) << query;
    // The linear scan over every stored description agrees with the k-d tree + re-ranking.
    std::size_t best = 0;
    double best_distance = 2.0;
    for (std::size_t i = 0; i < index.size(); ++i) {
      const double d = iris_->match(*kitti_[query], index.description(i)).distance;
      if (d < best_distance) best_distance = d, best = i;
    }
    EXPECT_EQ(hit->slot, best) << query;
    EXPECT_DOUBLE_EQ(hit->match.distance, best_distance) << query;
  }
}

TEST_F(RealIndex, OppositeDirectionRevisitGivesItsYaw) {
  PlaceIndex index = mixedIndex();
  const auto turned = iris_->describe(test::rotatedZ(test::kittiScan(1), M_PI));
  const auto hit = index.query(*turned);
  ASSERT_TRUE(hit);
  EXPECT_EQ(&index.description(hit->slot), kitti_[0].get());
  EXPECT_TRUE(hit->match.reversed);
  // The query sees the candidate's points turned by 180 degrees.
  EXPECT_LT(std::abs(std::abs(test::degrees(hit->match.yaw_rad)) - 180.0), 2.0);
}

/// Keyframe positions for queryDistinct: keyframe i at (10 i, 0, 0), except
/// those given in `at`.
KeyframePosition positions(std::map<std::size_t, double> at = {}) {
  return [at = std::move(at)](core::KeyframeId id) {
    const auto it = at.find(id.value());
    return Eigen::Vector3d(it != at.end() ? it->second : 10.0 * static_cast<double>(id.value()),
                           0.0, 0.0);
  };
}

TEST_F(RealIndex, RealRevisitsAreDistinctFromEveryOtherPlace) {
  const PlaceIndex index = mixedIndex();
  for (const auto& [query, expected] :
       std::vector<std::pair<int, int>>{{1, 0}, {95, 94}, {199, 198}}) {
    const DistinctMatch found = index.queryDistinct(*kitti_[query], positions());
    EXPECT_FALSE(found.refused) << query;
    ASSERT_TRUE(found.best) << query;
    EXPECT_EQ(&index.description(found.best->slot), kitti_[expected].get()) << query;
  }
}

TEST_F(RealIndex, APlaceThatRepeatsElsewhereIsAmbiguous) {
  // KITTI frame 0 stored twice, as a world of identical blocks would show it:
  // frame 1 matches both copies equally.
  const auto indexWithRepeat = [](const PlaceIndexConfig& config) {
    PlaceIndex index(iris_, core::RobotId(0), config);
    for (std::size_t i = 0; i < simulated_.size(); ++i)
      index.add(core::KeyframeId(i), simulated_[i]);
    index.add(core::KeyframeId(100), kitti_[0]);
    index.add(core::KeyframeId(101), kitti_[0]);
    return index;
  };
  const PlaceIndex index = indexWithRepeat({});
  // 48 m apart: two places that look the same; the match is refused.
  DistinctMatch found = index.queryDistinct(*kitti_[1], positions({{100, 0.0}, {101, 48.0}}));
  EXPECT_FALSE(found.best);
  ASSERT_TRUE(found.refused);
  EXPECT_EQ(&index.description(found.refused->slot), kitti_[0].get());
  // 5 m apart: one place seen twice (a revisit); the match stands.
  found = index.queryDistinct(*kitti_[1], positions({{100, 0.0}, {101, 5.0}}));
  EXPECT_FALSE(found.refused);
  ASSERT_TRUE(found.best);
  EXPECT_EQ(&index.description(found.best->slot), kitti_[0].get());
  // The test off (the paper's search): the repeat is matched like query() does.
  PlaceIndexConfig off;
  off.distinct_ratio = 1.0;
  found = indexWithRepeat(off).queryDistinct(*kitti_[1], positions({{100, 0.0}, {101, 48.0}}));
  EXPECT_FALSE(found.refused);
  ASSERT_TRUE(found.best);
  EXPECT_EQ(found.best->slot, index.query(*kitti_[1])->slot);
}

TEST_F(RealIndex, AQueryThatRepeatsOnItsOwnRouteIsAmbiguousToo) {
  // The querying robot has passed KITTI frame 0's place twice, 48 m apart
  // (a world of identical blocks); the other robot only once. Its index
  // alone cannot tell, but the query's own look-alike distance, sent with it,
  // can: the match is not clearly closer than the query's own repeat.
  PlaceIndex querying(iris_, core::RobotId(1), {});
  for (std::size_t i = 0; i < simulated_.size(); ++i)
    querying.add(core::KeyframeId(i), simulated_[i]);
  querying.add(core::KeyframeId(100), kitti_[0]);
  const KeyframePosition route = positions({{100, 0.0}, {101, 48.0}});
  // Keyframe 101 (the repeat, frame 1 of the same place) asks before it is added.
  const std::optional<float> look_alike =
      querying.lookAlikeDistance(*kitti_[1], route(core::KeyframeId(101)), route, querying.size());
  ASSERT_TRUE(look_alike);
  EXPECT_FLOAT_EQ(*look_alike, iris_->match(*kitti_[1], *kitti_[0]).distance);
  // Which keyframe it resembles, closest first: what the robot tells its
  // neighbours, so that loops they hold at keyframe 100 are judged again.
  const auto alikes =
      querying.lookAlikes(*kitti_[1], route(core::KeyframeId(101)), route, querying.size());
  ASSERT_FALSE(alikes.empty());
  EXPECT_EQ(alikes.front().first, core::KeyframeId(100));
  EXPECT_FLOAT_EQ(alikes.front().second, *look_alike);
  for (std::size_t i = 1; i < alikes.size(); ++i) EXPECT_LE(alikes[i - 1].second, alikes[i].second);
  // A revisit 5 m on is the same place, not a look-alike: only places far
  // off count, which look less alike.
  const std::optional<float> revisit = querying.lookAlikeDistance(
      *kitti_[1], Eigen::Vector3d(5.0, 0.0, 0.0), positions({{100, 0.0}}), querying.size());
  EXPECT_TRUE(!revisit || *revisit > *look_alike);

  const PlaceIndex other = mixedIndex();  // holds frame 0 once
  const DistinctMatch plain = other.queryDistinct(*kitti_[1], positions());
  ASSERT_TRUE(plain.best);
  const DistinctMatch told = other.queryDistinct(*kitti_[1], positions(), look_alike);
  EXPECT_FALSE(told.best);
  ASSERT_TRUE(told.refused);
  EXPECT_EQ(told.refused->slot, plain.best->slot);
  // A query whose route holds no look-alike is matched as before.
  const DistinctMatch alone = other.queryDistinct(*kitti_[1], positions(), std::nullopt);
  ASSERT_TRUE(alone.best);
  EXPECT_EQ(alone.best->slot, plain.best->slot);
}

TEST_F(RealIndex, SimulatedRobotSkipsItsOwnRecentPast) {
  PlaceIndexConfig config;
  config.exclude_recent = 5;
  PlaceIndex own(iris_, core::RobotId(0), config);
  for (std::size_t i = 0; i < simulated_.size(); ++i) {
    own.add(core::KeyframeId(i), simulated_[i]);
    for (const auto& c : own.rank(*simulated_[i], QueryScope::kSameRobot)) {
      EXPECT_LT(c.slot + 5, i + 1);
    }
  }
  // Asked by another robot, the newest is its own best match at distance 0.
  const auto hit = own.query(*simulated_.back());
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->slot, simulated_.size() - 1);
  EXPECT_NEAR(hit->match.distance, 0.0, 1e-12);
}

}  // namespace
}  // namespace dcl::place
