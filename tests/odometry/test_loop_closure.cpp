// Intra-robot loop closure and the local mapper on a simulated revisit: the
// small-3 preset's first robot drives its block loop and a quarter of it again;
// the odometry is its ground truth with a deterministic drift (scale and yaw
// bias plus noise), so the test runs in seconds without the LiDAR odometry.

#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include <dcl/eval/ate.hpp>
#include <dcl/odometry/local_mapper.hpp>
#include <dcl/odometry/loop_closure.hpp>
#include <dcl/sim/presets.hpp>
#include <dcl/sim/sim_source.hpp>

namespace dcl::odometry {
namespace {

constexpr std::size_t kFrameStride = 3;   // every third 10 Hz pose: about 0.55 m apart
constexpr std::size_t kExtraPoses = 250;  // the second pass: about 45 m of the first lap again

/// The small-3 preset's robot "a" with its route driven once and then its first
/// `extra` poses again, so that the second pass revisits those streets.
sim::Preset revisitPreset(std::size_t extra) {
  sim::PresetOptions options;
  options.data_dir = DCL_DATA_DIR;
  options.robots = 1;
  sim::Preset preset = sim::makePreset("small-3", options);
  core::Trajectory& route = preset.routes[0].T_world_sensor;
  const core::Trajectory lap = route;
  const double period = lap.stamp(1) - lap.stamp(0);
  for (std::size_t i = 1; i <= extra; ++i) {
    route.push_back(lap.stamps().back() + period * static_cast<double>(i), lap.pose(i));
  }
  return preset;
}

/// Odometry that drifts: each ground-truth step scaled by 1 %, turned by a yaw
/// bias of 0.8 mrad a metre (about 9 degrees over the lap), and perturbed by noise.
std::vector<Eigen::Isometry3d> driftingOdometry(const std::vector<Eigen::Isometry3d>& T_odom_gt) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<Eigen::Isometry3d> odometry{T_odom_gt.front()};
  for (std::size_t i = 1; i < T_odom_gt.size(); ++i) {
    const Eigen::Isometry3d step = T_odom_gt[i - 1].inverse() * T_odom_gt[i];
    const double distance = step.translation().norm();
    core::Vector6d error;
    error << 0.01 * step.translation() + 0.002 * Eigen::Vector3d(noise(rng), noise(rng), 0.0), 0.0,
        0.0, 8e-4 * distance + 2e-4 * noise(rng);
    odometry.push_back(odometry.back() * step * core::expSE3(error));
  }
  return odometry;
}

/// The sensor frames of one run: ground truth, drifting odometry, and the mapper's output.
struct RevisitRun {
  std::shared_ptr<sim::SimWorld> world;
  std::vector<std::size_t> frames;  ///< ground-truth pose index of each frame fed
  core::Trajectory ground_truth;    ///< T_world_sensor at the frames fed
  core::Trajectory odometry;        ///< the drifting T_odom_sensor at the frames fed
  std::unique_ptr<LocalMapper> mapper;
  std::vector<MapperUpdate> updates;
};

core::Trajectory keyframeOdometry(const LocalMapper& mapper) {
  core::Trajectory t;
  for (const core::Keyframe& kf : mapper.keyframes()) t.push_back(kf.stamp, kf.T_odom_keyframe);
  return t;
}

std::shared_ptr<sim::SimWorld> makeWorld() {
  const auto dir = std::filesystem::path(::testing::TempDir()) /
                   ("dcl_loop_closure_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  sim::SimDatasetOptions options;
  options.motion_distortion = false;  // the odometry would deskew; here it is ground truth
  const io::DatasetSpec spec =
      sim::writeSimDataset(dir.string(), revisitPreset(kExtraPoses), options);
  auto world = std::make_shared<sim::SimWorld>(spec);
  std::filesystem::remove_all(dir);
  return world;
}

/// Runs the mapper once over the revisiting route (shared by the tests).
const RevisitRun& revisitRun() {
  static const RevisitRun run = [] {
    RevisitRun r;
    r.world = makeWorld();
    const core::Trajectory& gt = r.world->groundTruth(0);
    std::vector<Eigen::Isometry3d> T_odom_gt;
    for (std::size_t i = 0; i < gt.size(); i += kFrameStride) {
      r.frames.push_back(i);
      r.ground_truth.push_back(gt.stamp(i), gt.pose(i));
      T_odom_gt.push_back(gt.pose(0).inverse() * gt.pose(i));
    }
    const std::vector<Eigen::Isometry3d> drifted = driftingOdometry(T_odom_gt);
    r.mapper = std::make_unique<LocalMapper>(core::RobotId(0));
    for (std::size_t k = 0; k < r.frames.size(); ++k) {
      OdometryResult frame;
      frame.stamp = gt.stamp(r.frames[k]);
      frame.T_odom_sensor = drifted[k];
      frame.covariance = core::Vector6d(1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6).asDiagonal();
      frame.health.accepted = true;
      r.odometry.push_back(frame.stamp, frame.T_odom_sensor);
      r.updates.push_back(r.mapper->process(frame, r.world->scan(0, r.frames[k])));
    }
    return r;
  }();
  return run;
}

/// Ground truth T_world_sensor at a keyframe's stamp.
Eigen::Isometry3d truthAt(const RevisitRun& run, const core::Keyframe& kf) {
  return *run.world->groundTruth(0).at(kf.stamp);
}

TEST(LoopClosure, FindsLoopsOnlyAtTheRevisitWithTheTrueRelativePose) {
  const RevisitRun& run = revisitRun();
  const LocalMapper& mapper = *run.mapper;
  const std::vector<IntraLoop>& loops = mapper.loops();
  ASSERT_GE(loops.size(), 5u) << "queries " << mapper.loopStats().queries;
  const double lap_end =
      run.world->groundTruth(0).stamp(run.world->groundTruth(0).size() - kExtraPoses - 1);
  for (const IntraLoop& loop : loops) {
    const core::Keyframe& from = mapper.keyframes()[loop.from.value()];
    const core::Keyframe& to = mapper.keyframes()[loop.to.value()];
    // The query is on the second pass, the candidate on the first, at the same place.
    EXPECT_GT(to.stamp, lap_end - 15.0);
    EXPECT_LT(from.stamp, 40.0);
    const Eigen::Isometry3d T_true = truthAt(run, from).inverse() * truthAt(run, to);
    EXPECT_LT(T_true.translation().norm(), 10.0);
    const core::Vector6d error = core::logSE3(T_true.inverse() * loop.T_from_to);
    EXPECT_LT(error.head<3>().norm(), 0.15) << loop.from.value() << " -> " << loop.to.value();
    EXPECT_LT(core::rad2deg(error.tail<3>().norm()), 0.5);
  }
}

TEST(LoopClosure, SmoothedTrajectoryBeatsTheDriftingOdometry) {
  const RevisitRun& run = revisitRun();
  const eval::AteResult drifting =
      eval::computeAte(keyframeOdometry(*run.mapper), run.ground_truth);
  const eval::AteResult smoothed = eval::computeAte(run.mapper->trajectory(), run.ground_truth);
  EXPECT_EQ(smoothed.pairs, run.mapper->keyframes().size());
  EXPECT_GT(drifting.translation_m.rmse, 1.0);  // the drift the loops must remove
  EXPECT_LT(smoothed.translation_m.rmse, 0.5 * drifting.translation_m.rmse);
  ::testing::Test::RecordProperty("ate_drifting_m", std::to_string(drifting.translation_m.rmse));
  ::testing::Test::RecordProperty("ate_smoothed_m", std::to_string(smoothed.translation_m.rmse));
  ::testing::Test::RecordProperty("loops", std::to_string(run.mapper->loops().size()));
  ::testing::Test::RecordProperty("rejected", std::to_string(run.mapper->loopStats().rejected));
  // Every loop triggered a solve of the local graph, and the first keyframe stayed put.
  std::size_t solves = 0;
  for (const MapperUpdate& u : run.updates) solves += u.optimisation ? 1 : 0;
  EXPECT_EQ(solves, run.mapper->loops().size());
  EXPECT_TRUE(run.mapper->smoothedPoses().front().isApprox(Eigen::Isometry3d::Identity()));
}

TEST(LoopClosure, RejectsAWrongCandidate) {
  const RevisitRun& run = revisitRun();
  const LocalMapper& mapper = *run.mapper;
  const std::vector<core::Keyframe>& keyframes = mapper.keyframes();
  LoopClosure loop_closure;
  const core::Keyframe& query = keyframes.back();
  // A keyframe about 60 m of driving from the query's place, put where the query
  // is estimated to be, so that the guess says "same place" and only the
  // geometry can tell.
  const std::size_t searchable = loop_closure.searchable(keyframes, query);
  std::size_t wrong = searchable;
  for (std::size_t i = 0; i < searchable && wrong == searchable; ++i) {
    const Eigen::Vector3d p = truthAt(run, keyframes[i]).translation();
    if ((p - truthAt(run, query).translation()).norm() > 40.0) wrong = i;
  }
  ASSERT_LT(wrong, searchable);
  std::vector<Eigen::Isometry3d> estimates = mapper.smoothedPoses();
  estimates[wrong] = estimates[query.id.value()];
  const LoopVerification v =
      loop_closure.verify(keyframes, estimates, core::KeyframeId(wrong), query.id, searchable);
  EXPECT_FALSE(v.loop);
  EXPECT_FALSE(v.rejection.empty());
}

TEST(LoopClosure, ExcludesRecentKeyframesByCountAndTime) {
  LoopClosureConfig config;
  config.exclude_recent = 5;
  config.exclude_seconds = 4.0;
  LoopClosure loop_closure(config);
  std::vector<core::Keyframe> keyframes(20);
  for (std::size_t i = 0; i < keyframes.size(); ++i) {
    keyframes[i].id = core::KeyframeId(i);
    keyframes[i].stamp = 0.5 * static_cast<double>(i);  // by time: 6 keyframes in 3 s
  }
  EXPECT_EQ(loop_closure.searchable(keyframes, keyframes[3]), 0u);
  // Keyframe 19 at 9.5 s: by count ids 0..13, by time stamps up to 5.5 s (ids 0..11).
  EXPECT_EQ(loop_closure.searchable(keyframes, keyframes[19]), 12u);
  config.exclude_seconds = 0.0;
  EXPECT_EQ(LoopClosure(config).searchable(keyframes, keyframes[19]), 14u);
}

TEST(LoopClosure, RadiusSearchReturnsTheNearestWithinTheRadiusAmongSearchable) {
  RadiusSearchConfig config;
  config.radius = 3.0;
  config.max_candidates = 2;
  const RadiusCandidateSearch search(config);
  std::vector<Eigen::Isometry3d> poses;
  for (int i = 0; i < 10; ++i) poses.push_back(core::makePose2d(i, 0, 0));
  core::Keyframe query;
  query.id = core::KeyframeId(9);
  poses[9] = core::makePose2d(2.2, 0.5, 0);
  const auto all = search.search(query, poses, 9);
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].keyframe, core::KeyframeId(2));
  EXPECT_EQ(all[1].keyframe, core::KeyframeId(3));
  EXPECT_EQ(search.search(query, poses, 2).size(), 2u);  // keyframes 0 and 1 only
  EXPECT_EQ(search.search(query, poses, 0).size(), 0u);
}

}  // namespace
}  // namespace dcl::odometry
