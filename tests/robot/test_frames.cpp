// Joining the robots' frames: the rigid motion between two frames that the
// loops between them give, and every frame placed in the lowest one its links
// reach. Frame
// origins and trajectories are KITTI 00's ground truth.
#include <Eigen/Geometry>
#include <cstddef>
#include <map>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/error.hpp>
#include <dcl/robot/frames.hpp>

#include "../common/kitti_test_data.hpp"

namespace dcl::robot {
namespace {

/// Translation (m) and rotation (rad) between two poses.
std::pair<double, double> gap(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  const Eigen::Isometry3d d = a.inverse() * b;
  return {d.translation().norm(), Eigen::AngleAxisd(d.linear()).angle()};
}

/// KITTI's pose `i`, its rotation made exactly orthonormal (the file's
/// matrices are to 6-9 digits, and an isometry's inverse is its transpose).
Eigen::Isometry3d kitti(std::size_t i) {
  Eigen::Isometry3d T = test::kittiLidarPoses().at(i);
  T.linear() = Eigen::Quaterniond(T.linear()).normalized().toRotationMatrix();
  return T;
}

/// T_world_frame of frame r: KITTI 00's LiDAR pose at frame 400 r.
Eigen::Isometry3d origin(int r) {
  return kitti(static_cast<std::size_t>(400 * r));
}

/// The true link from frame `from` to frame `to`.
FrameLink link(int from, int to) {
  return {core::RobotId(static_cast<std::uint8_t>(from)),
          core::RobotId(static_cast<std::uint8_t>(to)), origin(to).inverse() * origin(from)};
}

void expectPlaced(const std::map<core::RobotId, FramePlacement>& placed, int frame, int root) {
  const auto it = placed.find(core::RobotId(static_cast<std::uint8_t>(frame)));
  ASSERT_NE(it, placed.end()) << "frame " << frame;
  EXPECT_EQ(it->second.root.value(), root) << "frame " << frame;
  const auto [t, r] = gap(it->second.T_root_frame, origin(root).inverse() * origin(frame));
  EXPECT_LT(t, 1e-9) << "frame " << frame;
  EXPECT_LT(r, 1e-9) << "frame " << frame;
}

TEST(Frames, ChainsOfLinksPlaceEveryFrameInTheLowest) {
  // Loops join b's frame to a's, c's to b's and to d's, f's to e's:
  // two groups of frames, rooted at a and at e.
  const std::vector<FrameLink> links{link(1, 0), link(2, 1), link(2, 3), link(5, 4)};
  const auto placed = joinFrames(links);
  EXPECT_EQ(placed.size(), 6u);
  for (const int f : {0, 1, 2, 3}) expectPlaced(placed, f, 0);
  for (const int f : {4, 5}) expectPlaced(placed, f, 4);
  EXPECT_FALSE(placed.contains(core::RobotId(6)));  // in no link: its own
}

TEST(Frames, TheFirstOfTwoLinksThatDisagreeWins) {
  FrameLink other = link(1, 0);
  other.T_to_from.translation() += Eigen::Vector3d(0.5, 0, 0);
  const auto placed = joinFrames(std::vector<FrameLink>{link(1, 0), other, link(1, 1)});
  expectPlaced(placed, 1, 0);
}

TEST(Frames, LoopsBetweenTwoFramesGiveTheirRelativePose) {
  // Robots 0 and 1 drive KITTI 00's frames 0-300 and 100-400; robot 0 is in
  // frame 0 (the world), robot 1 in frame 1 (origin(1) in the world), each
  // keyframe with a few cm of error; they share loops where their routes do.
  // Robot 2, also in frame 1, and robot 3, of unknown frame, add loops that
  // say nothing about the two frames.
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.03);
  const auto jitter = [&](Eigen::Isometry3d T) {
    T.translation() += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    return T;
  };
  std::vector<RobotEstimates> robots{{core::RobotId(0), core::RobotId(0), {}},
                                     {core::RobotId(1), core::RobotId(1), {}},
                                     {core::RobotId(2), core::RobotId(1), {}},
                                     {core::RobotId(3), std::nullopt, {}}};
  for (std::size_t i = 0; i <= 300; i += 3) {
    robots[0].keyframes.push_back(jitter(kitti(i)));
    robots[1].keyframes.push_back(jitter(origin(1).inverse() * kitti(i + 100)));
    robots[2].keyframes.push_back(jitter(origin(1).inverse() * kitti(i + 100)));
    robots[3].keyframes.push_back(kitti(i));
  }
  std::vector<backend::Factor> loops;
  const auto loop = [&](int r, std::size_t k, int s, std::size_t l, std::size_t kitti_k,
                        std::size_t kitti_l) {
    backend::Factor f;
    f.from = {core::RobotId(static_cast<std::uint8_t>(r)), core::KeyframeId(k)};
    f.to = {core::RobotId(static_cast<std::uint8_t>(s)), core::KeyframeId(l)};
    f.T_from_to = kitti(kitti_k).inverse() * kitti(kitti_l);
    f.kind = backend::FactorKind::inter_loop;
    loops.push_back(f);
  };
  for (std::size_t k = 40; k < 100; k += 5) {  // robot 0's keyframe k is KITTI's 3k
    loop(0, k, 1, k - 33, 3 * k, 3 * (k - 33) + 100);
    loop(1, k - 34, 0, k, 3 * (k - 34) + 100, 3 * k);  // and the other way round
    loop(1, k, 2, k, 3 * k + 100, 3 * k + 100);        // within frame 1
    loop(3, k, 0, k, 3 * k, 3 * k);                    // of an unknown frame
  }
  loop(0, 10, 7, 10, 30, 30);   // a robot that is not there
  loop(0, 10, 1, 500, 30, 30);  // a keyframe that is not there
  const std::vector<FrameLink> links = frameLinks(robots, loops);
  ASSERT_EQ(links.size(), 1u);
  EXPECT_EQ(links[0].from, core::RobotId(1));
  EXPECT_EQ(links[0].to, core::RobotId(0));
  EXPECT_EQ(links[0].loops, 24u);
  // Where the routes meet, robot 1's true poses land within a few cm of the
  // truth (frame 1's origin lies hundreds of metres away, where a milliradian
  // is decimetres).
  EXPECT_LT(gap(links[0].T_to_from, origin(1)).second, 1e-3);
  for (std::size_t i = 100; i < 200; i += 10) {
    const auto [t, r] = gap(links[0].T_to_from * origin(1).inverse() * kitti(i), kitti(i));
    EXPECT_LT(t, 0.05) << "KITTI frame " << i;
  }
}

TEST(Frames, TheRigidFitRecoversHowARoundMovedTheKeyframes) {
  std::vector<Eigen::Isometry3d> truth;
  for (std::size_t i = 0; i < 1200; ++i) truth.push_back(kitti(i));
  const Eigen::Isometry3d T = origin(3).inverse() * origin(1);  // tens of metres, a turn
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::vector<Eigen::Isometry3d> before, after;
  for (std::size_t i = 0; i < 1200; i += 4) {
    before.push_back(truth[i]);
    Eigen::Isometry3d moved = T * truth[i];  // and a few cm of correction each
    moved.translation() += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    after.push_back(moved);
  }
  auto [t, r] = gap(fitRigidMotion(before, after), T);
  EXPECT_LT(t, 0.01);
  EXPECT_LT(r, 1e-3);
  // KITTI 00's first 60 frames are a straight road: positions alone leave the
  // roll about it free, the orientations fix it.
  const std::vector<Eigen::Isometry3d> straight(truth.begin(), truth.begin() + 60);
  std::vector<Eigen::Isometry3d> straight_moved;
  for (const auto& p : straight) straight_moved.push_back(T * p);
  std::tie(t, r) = gap(fitRigidMotion(straight, straight_moved), T);
  EXPECT_LT(t, 1e-6);
  EXPECT_LT(r, 1e-8);
  // One keyframe: the motion between its two poses.
  std::tie(t, r) = gap(fitRigidMotion({&truth[500], 1}, std::vector{T * truth[500]}), T);
  EXPECT_LT(t, 1e-6);
  EXPECT_LT(r, 1e-8);
  EXPECT_THROW((void)fitRigidMotion(before, straight), core::Error);
  EXPECT_THROW((void)fitRigidMotion({}, {}), core::Error);
}

}  // namespace
}  // namespace dcl::robot
