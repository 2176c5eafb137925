// The kd-tree against brute force on a real scan.

#include <algorithm>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/registration/point_tree.hpp>
#include <dcl/registration/voxel_filter.hpp>

#include "registration_test_data.hpp"

namespace dcl::registration {
namespace {

/// Squared distances from `q` to every point, sorted.
std::vector<double> bruteForce(const std::vector<Eigen::Vector3d>& points,
                               const Eigen::Vector3d& q) {
  std::vector<double> d;
  for (const Eigen::Vector3d& p : points) d.push_back((p - q).squaredNorm());
  std::sort(d.begin(), d.end());
  return d;
}

class PointTreeOnKitti : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    points_ = new std::vector<Eigen::Vector3d>(voxelDownsample(test::kittiScan(0).points, 0.6));
  }
  static void TearDownTestSuite() { delete points_; }

  /// Queries near the scan's points (sensor noise to 2 m off).
  static std::vector<Eigen::Vector3d> queries(int n) {
    std::mt19937 rng(3);
    std::normal_distribution<double> offset(0.0, 1.0);
    std::vector<Eigen::Vector3d> q;
    for (int i = 0; i < n; ++i)
      q.push_back((*points_)[rng() % points_->size()] +
                  Eigen::Vector3d(offset(rng), offset(rng), offset(rng)));
    return q;
  }

  static std::vector<Eigen::Vector3d>* points_;
};
std::vector<Eigen::Vector3d>* PointTreeOnKitti::points_ = nullptr;

TEST_F(PointTreeOnKitti, NearestAndKNearestMatchBruteForce) {
  const PointTree tree(*points_);
  ASSERT_EQ(tree.size(), points_->size());
  std::vector<Neighbor> found;
  for (const Eigen::Vector3d& q : queries(200)) {
    const std::vector<double> truth = bruteForce(*points_, q);
    const auto nearest = tree.nearest(q, std::numeric_limits<double>::infinity());
    ASSERT_TRUE(nearest.has_value());
    EXPECT_DOUBLE_EQ(nearest->squared_distance, truth[0]);
    EXPECT_DOUBLE_EQ(((*points_)[nearest->index] - q).squaredNorm(), truth[0]);
    tree.nearest(q, 10, std::numeric_limits<double>::infinity(), found);
    ASSERT_EQ(found.size(), 10U);
    for (std::size_t k = 0; k < found.size(); ++k)
      EXPECT_DOUBLE_EQ(found[k].squared_distance, truth[k]);  // closest first
  }
}

TEST_F(PointTreeOnKitti, GatesAndRadiiMatchBruteForce) {
  const PointTree tree(*points_);
  std::vector<Neighbor> found;
  for (const Eigen::Vector3d& q : queries(200)) {
    const std::vector<double> truth = bruteForce(*points_, q);
    const double gate = 0.5;
    const auto nearest = tree.nearest(q, gate);
    EXPECT_EQ(nearest.has_value(), truth[0] < gate * gate);
    tree.nearest(q, 8, gate, found);
    const auto within_gate =
        std::lower_bound(truth.begin(), truth.end(), gate * gate) - truth.begin();
    EXPECT_EQ(found.size(), std::min<std::size_t>(8, static_cast<std::size_t>(within_gate)));
    const double radius = 2.0;
    tree.within(q, radius, found);
    const auto within =
        std::lower_bound(truth.begin(), truth.end(), radius * radius) - truth.begin();
    EXPECT_EQ(found.size(), static_cast<std::size_t>(within));
    for (const Neighbor& n : found) EXPECT_LT(n.squared_distance, radius * radius);
  }
}

TEST(PointTree, EmptyAndMovedFromTreesFindNothing) {
  const PointTree empty;
  std::vector<Neighbor> found{{1, 1.0}};
  EXPECT_FALSE(empty.nearest(Eigen::Vector3d::Zero(), 1e9).has_value());
  empty.nearest(Eigen::Vector3d::Zero(), 5, 1e9, found);
  EXPECT_TRUE(found.empty());
  empty.within(Eigen::Vector3d::Zero(), 1e9, found);
  EXPECT_TRUE(found.empty());
  PointTree tree(std::vector<Eigen::Vector3d>{{1.0, 2.0, 3.0}});
  const PointTree moved = std::move(tree);
  ASSERT_TRUE(moved.nearest(Eigen::Vector3d::Zero(), 10.0).has_value());
  EXPECT_EQ(moved.nearest(Eigen::Vector3d::Zero(), 10.0)->index, 0U);
  EXPECT_FALSE(moved.nearest(Eigen::Vector3d::Zero(), 1.0).has_value());  // 3.7 m away
}

}  // namespace
}  // namespace dcl::registration
