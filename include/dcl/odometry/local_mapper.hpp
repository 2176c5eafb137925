#pragma once

/// One robot's front-end back half (paper §III-A): keyframes from the odometry
/// stream, intra-robot loops among them, and the local pose graph (odometry
/// factors plus accepted intra-robot loops) smoothed whenever a loop is added.
/// The `dcl-slam odometry` command and, later, the robot node drive it.

#include <Eigen/Geometry>
#include <optional>
#include <vector>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/keyframe.hpp>
#include <dcl/core/trajectory.hpp>
#include <dcl/odometry/keyframe_selector.hpp>
#include <dcl/odometry/loop_closure.hpp>
#include <dcl/odometry/odometry.hpp>

namespace dcl::odometry {

/// Keyframes, loop closure and local smoothing together.
struct LocalMapperConfig {
  KeyframeConfig keyframes{};      ///< keyframe selection
  bool loop_closure = true;        ///< search intra-robot loops (off for odometry that has its own)
  LoopClosureConfig loops{};       ///< loop search and verification
  backend::SolverConfig solver{};  ///< smoothing of the local graph

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.section("keyframes", keyframes, "keyframe selection");
    v.field("loop_closure", loop_closure, "search intra-robot loops");
    v.section("loops", loops, "intra-robot loop search and verification");
    v.section("solver", solver, "local pose graph smoothing");
  }
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const LocalMapperConfig& config);

/// What one frame produced.
struct MapperUpdate {
  std::optional<core::KeyframeId> keyframe;  ///< the keyframe the frame became
  std::optional<IntraLoop> loop;             ///< the loop accepted for that keyframe
  /// The local graph's optimisation after the loop.
  std::optional<backend::SolverSummary> optimisation;
};

/// Turns one robot's odometry stream into keyframes, intra-robot loops and a
/// smoothed keyframe trajectory. The local graph's world frame is the odometry
/// frame: keyframe 0 is fixed at its odometry pose.
class LocalMapper {
 public:
  /// A mapper for robot `robot`; throws core::Error for a config that breaks its rules.
  explicit LocalMapper(core::RobotId robot, const LocalMapperConfig& config = {});

  /// Takes the next frame and its cloud in the sensor frame at the frame's stamp
  /// (see KeyframeSelector::add).
  MapperUpdate process(const OdometryResult& frame, const core::PointCloud& scan);

  /// process() with the frame's own registered cloud.
  MapperUpdate process(const OdometryResult& frame) { return process(frame, frame.registered); }

  /// The keyframes so far (id i at index i), with their odometry poses.
  [[nodiscard]] const std::vector<core::Keyframe>& keyframes() const { return keyframes_; }

  /// The accepted intra-robot loops.
  [[nodiscard]] const std::vector<IntraLoop>& loops() const { return loops_; }

  /// The local pose graph (this robot's keyframes, odometry and intra-loop factors).
  [[nodiscard]] const backend::PoseGraph& graph() const { return graph_; }

  /// The smoothed keyframe poses T_odom_keyframe, by keyframe id.
  [[nodiscard]] const std::vector<Eigen::Isometry3d>& smoothedPoses() const { return estimates_; }

  /// The smoothed keyframe trajectory, stamped by keyframe.
  [[nodiscard]] core::Trajectory trajectory() const;

  /// The correction T_smoothed_odom of the newest keyframe: applied to an
  /// odometry pose after it, it gives that pose on the smoothed trajectory.
  [[nodiscard]] Eigen::Isometry3d correction() const;

  /// What the loop closure did.
  [[nodiscard]] const LoopClosureStats& loopStats() const { return loop_closure_.stats(); }

 private:
  void addKeyframe(core::Keyframe keyframe);
  [[nodiscard]] backend::SolverSummary addLoop(const IntraLoop& loop);
  [[nodiscard]] core::PoseKey key(core::KeyframeId id) const { return {robot_, id}; }

  core::RobotId robot_;
  LocalMapperConfig config_;
  KeyframeSelector selector_;
  LoopClosure loop_closure_;
  std::vector<core::Keyframe> keyframes_;
  std::vector<IntraLoop> loops_;
  backend::PoseGraph graph_;
  std::vector<Eigen::Isometry3d> estimates_;  ///< the graph's estimates by keyframe id
};

}  // namespace dcl::odometry
