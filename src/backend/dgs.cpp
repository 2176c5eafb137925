#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <utility>

#include <dcl/backend/dgs.hpp>
#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>

#include "dgs_block.hpp"

namespace dcl::backend {
namespace {

/// Largest plausible entry magnitude of a neighbour's value (a chordal estimate
/// has entries near [-1, 1]; a translation is in metres).
constexpr double kMaxRotationEntry = 1e3;
constexpr double kMaxTranslation = 1e9;
/// How far from orthonormal a stage-2 rotation from a neighbour may be.
constexpr double kRotationTolerance = 1e-6;

/// Stage index for the per-stage state: 0 rotation, 1 pose.
int stageIndex(DgsStage stage) {
  return stage == DgsStage::pose ? 1 : 0;
}

/// What a robot holds of one neighbour in one stage.
struct NeighbourView {
  int iteration = -1;  ///< the neighbour's latest step received
  bool initialised = false;
};

/// The own keys of `robot` in `local`: its nodes and the ends its factors name.
std::vector<core::PoseKey> ownKeys(core::RobotId robot, const PoseGraph& local) {
  std::set<core::PoseKey> keys;
  for (const auto& [key, pose] : local.nodes()) {
    if (key.robot == robot) keys.insert(key);
  }
  for (const Factor& f : local.factors()) {
    if (f.from.robot == robot) keys.insert(f.from);
    if (f.to.robot == robot) keys.insert(f.to);
  }
  return {keys.begin(), keys.end()};
}

bool plausibleRotations(const std::map<core::PoseKey, Eigen::Matrix3d>& values) {
  return std::all_of(values.begin(), values.end(), [](const auto& entry) {
    return entry.second.allFinite() && entry.second.cwiseAbs().maxCoeff() <= kMaxRotationEntry;
  });
}

bool plausiblePoses(const std::map<core::PoseKey, Eigen::Isometry3d>& values) {
  return std::all_of(values.begin(), values.end(), [](const auto& entry) {
    const Eigen::Isometry3d& T = entry.second;
    if (!T.matrix().allFinite() || T.translation().norm() > kMaxTranslation) return false;
    const Eigen::Matrix3d R = T.linear();
    return (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <=
               kRotationTolerance &&
           R.determinant() > 0.0;
  });
}

}  // namespace

void validate(const DgsConfig& config) {
  core::checkConfig(config, "dgs config");
}

struct DgsAgent::Impl {
  core::RobotId robot;
  DgsConfig config;
  dgs::Block block;
  std::vector<Eigen::Isometry3d> initial;  ///< per own node, the last finished round's
  std::vector<bool> given_fixed;           ///< per own node, fixed in the local graph
  std::map<core::RobotId, std::set<core::PoseKey>> separators;  ///< own keys per neighbour
  std::set<core::PoseKey> needed;  ///< neighbours' nodes this robot's factors touch
  /// Neighbours' nodes `local` holds fixed: constant separators of every
  /// round whose group leaves their robot out.
  std::map<core::PoseKey, Eigen::Isometry3d> given_held;
  std::map<core::PoseKey, Eigen::Isometry3d> estimates;
  std::size_t factorizations = 0;
  std::size_t rejected = 0;

  // The round.
  DgsStage stage = DgsStage::idle;
  std::uint32_t round = 0;
  std::set<core::RobotId> group;
  std::vector<bool> fixed;   ///< given_fixed plus the anchor
  std::vector<bool> member;  ///< per separator: its neighbour is in the group
  std::vector<bool> held;    ///< per separator: its node is held (its robot out of the group)
  int step = 0;
  std::array<int, 2> stage_steps{0, 0};
  bool initialised = false;
  bool converged = false;
  std::array<std::map<core::RobotId, NeighbourView>, 2> views;
  std::array<std::map<core::RobotId, DgsProgress>, 2> progress;
  std::map<core::PoseKey, Eigen::Matrix3d> neighbour_rotations;
  std::map<core::PoseKey, Eigen::Isometry3d> neighbour_poses;
  std::map<core::PoseKey, Eigen::Matrix3d> neighbour_linearisation;  ///< their R^, stage 2
  std::set<core::RobotId> linearisation_sent;  ///< neighbours sent this robot's R^
  std::vector<Eigen::Matrix3d> rotations;      ///< stage 1 values
  dgs::PoseValues poses;                       ///< stage 2 values
  std::optional<dgs::Layout> layout;           ///< of the current factorisation
  std::vector<bool> active;                    ///< separators in the current factorisation
  dgs::RotationProblem rotation_problem;
  dgs::PoseProblem pose_problem;
  std::vector<DgsMessage> outbox;
  /// Per stage, the last message sent to each neighbour (the one that says this
  /// robot left the stage), and the replies due.
  std::array<std::map<core::RobotId, DgsMessage>, 2> last_sent;
  std::vector<DgsMessage> replies;

  Impl(core::RobotId r, const PoseGraph& local, const DgsConfig& c) : robot(r), config(c) {
    validate(config);
    std::vector<core::PoseKey> keys = ownKeys(robot, local);
    if (keys.empty()) throw core::Error("dgs: robot " + core::robotName(robot) + " has no pose");
    initial = dgs::initialEstimates(keys, local);
    for (const core::PoseKey& key : keys) given_fixed.push_back(local.isFixed(key));
    block = dgs::Block(std::move(keys), local.factors(), "dgs robot " + core::robotName(robot));
    for (const dgs::Edge& e : block.separators()) {
      separators[e.other.robot].insert(block.keys()[e.own()]);
      needed.insert(e.other);
      if (local.hasNode(e.other) && local.isFixed(e.other))
        given_held.emplace(e.other, local.estimate(e.other));
    }
    for (int i = 0; i < block.size(); ++i) estimates.emplace(block.keys()[i], initial[i]);
  }

  void startRound(const std::set<core::RobotId>& members, std::uint32_t number) {
    if (!members.contains(robot)) {
      throw core::Error("dgs: robot " + core::robotName(robot) + " is not in the round's group");
    }
    stage = DgsStage::rotation;
    round = number;
    group = members;
    member.clear();
    held.clear();
    neighbour_rotations.clear();
    neighbour_poses.clear();
    neighbour_linearisation.clear();
    for (const dgs::Edge& e : block.separators()) {
      member.push_back(group.contains(e.other.robot));
      const auto value = given_held.find(e.other);
      held.push_back(!member.back() && value != given_held.end());
      if (!held.back()) continue;
      neighbour_rotations[e.other] = value->second.linear();
      neighbour_linearisation[e.other] = value->second.linear();
      neighbour_poses[e.other] = value->second;
    }
    // The gauge: the own fixed nodes, else held separators, else (on the
    // group's lowest robot) the lowest own node.
    fixed = given_fixed;
    const bool anchored = std::find(fixed.begin(), fixed.end(), true) != fixed.end() ||
                          std::find(held.begin(), held.end(), true) != held.end();
    if (*group.begin() == robot && !anchored) fixed[0] = true;
    step = 0;
    stage_steps = {0, 0};
    views = {};
    progress = {};
    linearisation_sent.clear();
    rotations.clear();
    for (const Eigen::Isometry3d& T : initial) rotations.push_back(T.linear());
    layout.reset();
    outbox.clear();
    last_sent = {};
    replies.clear();
    beginStage();
  }

  void beginStage() {
    initialised = false;
    converged = false;
    layout.reset();
  }

  void abortRound() {
    stage = DgsStage::idle;
    layout.reset();
    outbox.clear();
  }

  [[nodiscard]] std::set<core::RobotId> groupNeighbours() const {
    std::set<core::RobotId> out;
    for (const auto& [neighbour, keys] : separators) {
      if (group.contains(neighbour)) out.insert(neighbour);
    }
    return out;
  }

  // ---- receiving -------------------------------------------------------

  void receive(const DgsMessage& m) {
    if (stage == DgsStage::idle) return;
    if (m.to != robot || m.round != round || !group.contains(m.from) || m.from == robot) return;
    if (!separators.contains(m.from)) return;
    if (m.stage != DgsStage::rotation && m.stage != DgsStage::pose) return;
    const int s = stageIndex(m.stage);
    if (stage == DgsStage::done || s < stageIndex(stage)) return answerStraggler(m, s);
    if (!wellFormed(m)) {
      ++rejected;
      return;
    }
    if (s > stageIndex(stage)) {
      // The sender has left this robot's stage; its message saying so may
      // have been lost, and without it this robot would step on alone to the cap.
      progress[stageIndex(stage)][m.from].finished = true;
    }
    NeighbourView& view = views[s][m.from];
    if (m.iteration <= view.iteration) return;
    view.iteration = m.iteration;
    view.initialised = m.initialised;
    auto& rotation_values = s == 0 ? neighbour_rotations : neighbour_linearisation;
    for (const auto& [key, R] : m.rotations) {
      if (key.robot == m.from && needed.contains(key)) rotation_values[key] = R;
    }
    for (const auto& [key, T] : m.poses) {
      if (key.robot == m.from && needed.contains(key)) neighbour_poses[key] = T;
    }
    for (const auto& [member_robot, p] : m.progress) {
      if (member_robot == robot || !group.contains(member_robot)) continue;
      auto [it, added] = progress[s].try_emplace(member_robot, p);
      if (!added && p.iteration > it->second.iteration) it->second = p;
    }
  }

  /// The sender of `m` is still in stage `s`, which this robot has left: it
  /// lost the message saying so, and would step on alone to the cap. Not
  /// when `m` is the sender's own last message of the stage.
  void answerStraggler(const DgsMessage& m, int s) {
    const auto own = m.progress.find(m.from);
    if (own != m.progress.end() && own->second.finished) return;
    const auto last = last_sent[s].find(m.from);
    if (last != last_sent[s].end()) replies.push_back(last->second);
  }

  [[nodiscard]] bool wellFormed(const DgsMessage& m) const {
    if (m.iteration < 0) return false;
    for (const auto& [r, p] : m.progress) {
      if (p.iteration < 0 || p.converged_since > p.iteration || p.converged_since < -1) {
        return false;
      }
    }
    if (m.stage == DgsStage::pose) {  // stage-2 rotations are R^, projected: proper rotations
      for (const auto& [k, R] : m.rotations) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = R;
        if (!plausiblePoses({{k, T}})) return false;
      }
    }
    return plausibleRotations(m.rotations) && plausiblePoses(m.poses);
  }

  // ---- stepping --------------------------------------------------------

  /// Separators in use this step: the neighbour is in the group, initialised
  /// in this stage, and has sent the node's value.
  [[nodiscard]] std::vector<bool> activeSeparators(int s) const {
    std::vector<bool> out(block.separators().size(), false);
    for (std::size_t i = 0; i < out.size(); ++i) {
      const dgs::Edge& e = block.separators()[i];
      if (held[i]) {
        out[i] = true;
        continue;
      }
      if (!member[i]) continue;
      const auto view = views[s].find(e.other.robot);
      if (view == views[s].end() || !view->second.initialised) continue;
      out[i] = s == 0 ? neighbour_rotations.contains(e.other) : neighbour_poses.contains(e.other);
    }
    return out;
  }

  [[nodiscard]] bool allNeighboursInitialised(int s) const {
    for (const core::RobotId q : groupNeighbours()) {
      const auto view = views[s].find(q);
      if (view == views[s].end() || !view->second.initialised) return false;
    }
    return true;
  }

  /// Refactors when the separators in use changed; false when the block cannot be solved.
  bool configure(int s, const std::vector<bool>& in_use) {
    if (layout && in_use == active) return layout->grounded;
    active = in_use;
    layout = dgs::makeLayout(block, fixed, active);
    if (!layout->grounded) return false;
    ++factorizations;
    const bool ok = s == 0 ? rotation_problem.configure(block, *layout, active, rotations)
                           : pose_problem.configure(block, *layout, active, poses);
    if (!ok) layout->grounded = false;  // not positive definite: wait rather than diverge
    return layout->grounded;
  }

  /// One solve of the stage; returns the change of the estimate.
  double solve(int s) {
    const bool first = !initialised;
    if (s == 0) {
      const std::vector<Eigen::Matrix3d> solved =
          rotation_problem.solve(block, active, neighbour_rotations, rotations);
      double change = 0.0;
      for (int i = 0; i < block.size(); ++i) {
        const Eigen::Matrix3d next = dgs::relax(rotations[i], solved[i], config.gamma, first);
        change += (next - rotations[i]).squaredNorm();
        rotations[i] = next;
      }
      return std::sqrt(change);
    }
    const dgs::PoseValues before = poses;
    pose_problem.step(block, active, neighbour_poses, neighbour_linearisation, config.gamma, first,
                      poses);
    double change = 0.0;
    for (int i = 0; i < block.size(); ++i) {
      change += (poses.t[i] - before.t[i]).squaredNorm() +
                (poses.delta[i] - before.delta[i]).squaredNorm();
    }
    return std::sqrt(change);
  }

  void iterate() {
    outbox.clear();
    if (stage != DgsStage::rotation && stage != DgsStage::pose) return;
    const int s = stageIndex(stage);
    ++step;
    ++stage_steps[s];
    const bool complete = allNeighboursInitialised(s);
    converged = false;
    if (configure(s, activeSeparators(s))) {
      const bool was_initialised = initialised;
      const double change = solve(s);
      initialised = true;
      const double threshold = s == 0 ? config.rotation_threshold : config.pose_threshold;
      converged = was_initialised && complete && change < threshold;
    }
    DgsProgress& own = progress[s][robot];
    own.converged_since = converged ? (own.converged_since >= 0 ? own.converged_since : step) : -1;
    own.iteration = step;
    const int cap = s == 0 ? config.max_rotation_iterations : config.max_pose_iterations;
    const bool leave = groupConverged(s) || someoneLeft(s) || stage_steps[s] >= cap;
    own.finished = leave;
    outbox = messages(s);
    if (!leave) return;
    for (const DgsMessage& m : outbox) last_sent[s][m.to] = m;
    finishStage(s);
  }

  /// True when the progress heard of shows a step at which every member was converged.
  [[nodiscard]] bool groupConverged(int s) const {
    int latest_start = 0;
    int earliest_report = std::numeric_limits<int>::max();
    for (const core::RobotId q : group) {
      const auto it = progress[s].find(q);
      if (it == progress[s].end() || it->second.converged_since < 0) return false;
      latest_start = std::max(latest_start, it->second.converged_since);
      earliest_report = std::min(earliest_report, it->second.iteration);
    }
    return latest_start <= earliest_report;
  }

  /// True when a member has left the stage: it saw the group converged (or hit
  /// the cap), so the rest follow even if their own view changed since.
  [[nodiscard]] bool someoneLeft(int s) const {
    return std::any_of(progress[s].begin(), progress[s].end(),
                       [](const auto& entry) { return entry.second.finished; });
  }

  void finishStage(int s) {
    if (s == 0) {
      poses.R_hat.resize(block.size());
      poses.delta.assign(block.size(), Eigen::Vector3d::Zero());
      poses.t.resize(block.size());
      for (int i = 0; i < block.size(); ++i) {
        const bool pinned = fixed[i] || (layout && layout->unknown[i] < 0);
        poses.R_hat[i] = pinned ? initial[i].linear() : core::projectToSO3(rotations[i]);
        poses.t[i] = initial[i].translation();
      }
      stage = DgsStage::pose;
      beginStage();
      return;
    }
    for (int i = 0; i < block.size(); ++i) {
      if (fixed[i]) continue;
      initial[i] = poses.pose(i);
      estimates[block.keys()[i]] = initial[i];
    }
    stage = DgsStage::done;
  }

  /// Stage 2 sends each neighbour its R^ once, with the first initialised message.
  [[nodiscard]] std::vector<DgsMessage> messages(int s) {
    std::vector<DgsMessage> out;
    for (const core::RobotId q : groupNeighbours()) {
      DgsMessage m;
      m.from = robot;
      m.to = q;
      m.stage = s == 0 ? DgsStage::rotation : DgsStage::pose;
      m.round = round;
      m.iteration = step;
      m.initialised = initialised;
      m.converged = converged;
      m.progress = progress[s];
      if (initialised) {
        for (const core::PoseKey& key : separators.at(q)) {
          const int i = block.indexOf(key);
          if (s == 0) {
            m.rotations.emplace(key, rotations[i]);
          } else {
            m.poses.emplace(key, poses.pose(i));
            if (!linearisation_sent.contains(q)) m.rotations.emplace(key, poses.R_hat[i]);
          }
        }
        if (s == 1) linearisation_sent.insert(q);
      }
      out.push_back(std::move(m));
    }
    return out;
  }
};

DgsAgent::DgsAgent(core::RobotId robot, PoseGraph local, const DgsConfig& config)
    : impl_(std::make_unique<Impl>(robot, local, config)) {}
DgsAgent::~DgsAgent() = default;
DgsAgent::DgsAgent(DgsAgent&&) noexcept = default;
DgsAgent& DgsAgent::operator=(DgsAgent&&) noexcept = default;

std::set<core::RobotId> DgsAgent::neighbours() const {
  std::set<core::RobotId> out;
  for (const auto& [neighbour, keys] : impl_->separators) out.insert(neighbour);
  return out;
}

const std::map<core::RobotId, std::set<core::PoseKey>>& DgsAgent::separators() const {
  return impl_->separators;
}

void DgsAgent::startRound(const std::set<core::RobotId>& group) {
  impl_->startRound(group, impl_->round + 1);
}

void DgsAgent::startRound(const std::set<core::RobotId>& group, std::uint32_t round) {
  impl_->startRound(group, round);
}

void DgsAgent::receive(const DgsMessage& message) noexcept {
  try {
    impl_->receive(message);
  } catch (...) {  // allocation failure: drop the message rather than the robot
    ++impl_->rejected;
  }
}

void DgsAgent::iterate() {
  impl_->iterate();
}

std::vector<DgsMessage> DgsAgent::outgoing() const {
  return impl_->outbox;
}

std::vector<DgsMessage> DgsAgent::replies() {
  return std::exchange(impl_->replies, {});
}

void DgsAgent::abortRound() {
  impl_->abortRound();
}

DgsStage DgsAgent::stage() const {
  return impl_->stage;
}

core::RobotId DgsAgent::robot() const {
  return impl_->robot;
}

bool DgsAgent::initialised() const {
  return impl_->initialised;
}

int DgsAgent::iteration() const {
  return impl_->step;
}

int DgsAgent::stageIterations(DgsStage stage) const {
  if (stage == DgsStage::rotation) return impl_->stage_steps[0];
  if (stage == DgsStage::pose) return impl_->stage_steps[1];
  return 0;
}

std::size_t DgsAgent::factorizations() const {
  return impl_->factorizations;
}

std::size_t DgsAgent::rejectedMessages() const {
  return impl_->rejected;
}

const std::map<core::PoseKey, Eigen::Isometry3d>& DgsAgent::estimates() const {
  return impl_->estimates;
}

// ---- graphs -------------------------------------------------------------

std::map<core::RobotId, PoseGraph> partitionByRobot(const PoseGraph& graph) {
  std::map<core::RobotId, PoseGraph> locals;
  for (const auto& [key, pose] : graph.nodes()) {
    PoseGraph& local = locals[key.robot];
    local.addNode(key, pose);
    if (graph.isFixed(key)) local.fix(key);
  }
  for (const Factor& f : graph.factors()) {
    const auto from = locals.find(f.from.robot);
    if (from != locals.end()) from->second.addFactor(f);
    if (f.to.robot == f.from.robot) continue;
    const auto to = locals.find(f.to.robot);
    if (to != locals.end()) to->second.addFactor(f);
  }
  return locals;
}

PoseGraph splitIntoRobots(const PoseGraph& graph, int robots) {
  const auto n = static_cast<long long>(graph.size());
  if (robots < 1 || robots > std::min<long long>(255, n)) {
    throw core::Error("split: cannot split a graph of " + std::to_string(n) + " nodes into " +
                      std::to_string(robots) + " robots (1.." +
                      std::to_string(std::min<long long>(255, n)) + ")");
  }
  std::map<core::PoseKey, core::PoseKey> rekey;
  long long index = 0;
  int robot = 0;
  long long first = 0;
  for (const auto& [key, pose] : graph.nodes()) {
    while (index >= (robot + 1) * n / robots) first = (++robot) * n / robots;
    rekey.emplace(key, core::PoseKey{core::RobotId(static_cast<std::uint8_t>(robot)),
                                     core::KeyframeId(static_cast<std::uint64_t>(index - first))});
    ++index;
  }
  PoseGraph split;
  for (const auto& [key, pose] : graph.nodes()) split.addNode(rekey.at(key), pose);
  for (const core::PoseKey& key : graph.fixedNodes()) {
    if (rekey.contains(key)) split.fix(rekey.at(key));
  }
  for (const Factor& f : graph.factors()) {
    const auto from = rekey.find(f.from);
    const auto to = rekey.find(f.to);
    if (from == rekey.end() || to == rekey.end()) {
      throw core::Error("split: factor " + core::keyName(f.from) + " -> " + core::keyName(f.to) +
                        " names a node the graph does not hold");
    }
    Factor g = f;
    g.from = from->second;
    g.to = to->second;
    if (g.from.robot != g.to.robot) {
      g.kind = FactorKind::inter_loop;
    } else {
      const auto a = g.from.keyframe.value();
      const auto b = g.to.keyframe.value();
      g.kind = (a + 1 == b || b + 1 == a) ? FactorKind::odometry : FactorKind::intra_loop;
    }
    split.addFactor(g);
  }
  return split;
}

namespace {

/// Inter-robot factor counts between the robots of `robots`, both directions.
std::map<std::pair<core::RobotId, core::RobotId>, std::size_t> interRobotCounts(
    const PoseGraph& graph, const std::set<core::RobotId>& robots) {
  std::map<std::pair<core::RobotId, core::RobotId>, std::size_t> counts;
  for (const Factor& f : graph.factors()) {
    const core::RobotId a = f.from.robot;
    const core::RobotId b = f.to.robot;
    if (a == b || !robots.contains(a) || !robots.contains(b)) continue;
    ++counts[{a, b}];
    ++counts[{b, a}];
  }
  return counts;
}

}  // namespace

std::vector<std::set<core::RobotId>> connectedGroups(const PoseGraph& graph,
                                                     const std::set<core::RobotId>& exclude) {
  std::set<core::RobotId> robots;
  for (const auto& [key, pose] : graph.nodes()) {
    if (!exclude.contains(key.robot)) robots.insert(key.robot);
  }
  const auto counts = interRobotCounts(graph, robots);
  std::vector<std::set<core::RobotId>> groups;
  std::set<core::RobotId> placed;
  for (const core::RobotId start : robots) {
    if (placed.contains(start)) continue;
    std::set<core::RobotId> group{start};
    std::vector<core::RobotId> frontier{start};
    while (!frontier.empty()) {
      const core::RobotId r = frontier.back();
      frontier.pop_back();
      for (const core::RobotId q : robots) {
        if (!group.contains(q) && counts.contains({r, q})) {
          group.insert(q);
          frontier.push_back(q);
        }
      }
    }
    placed.insert(group.begin(), group.end());
    groups.push_back(std::move(group));
  }
  return groups;
}

std::vector<core::RobotId> optimisationOrder(const PoseGraph& graph,
                                             const std::set<core::RobotId>& group) {
  if (group.empty()) return {};
  const auto counts = interRobotCounts(graph, group);
  std::vector<core::RobotId> order{*group.begin()};
  std::set<core::RobotId> left(std::next(group.begin()), group.end());
  while (!left.empty()) {
    core::RobotId best = *left.begin();
    std::size_t best_edges = 0;
    for (const core::RobotId r : left) {
      std::size_t edges = 0;
      for (const core::RobotId o : order) {
        const auto it = counts.find({r, o});
        if (it != counts.end()) edges += it->second;
      }
      if (edges > best_edges) {
        best = r;
        best_edges = edges;
      }
    }
    order.push_back(best);
    left.erase(best);
  }
  return order;
}

void chordalInitialise(PoseGraph& graph) {
  std::vector<core::PoseKey> keys;
  std::vector<Eigen::Isometry3d> initial;
  std::vector<bool> fixed;
  for (const auto& [key, pose] : graph.nodes()) {
    keys.push_back(key);
    initial.push_back(pose);
    fixed.push_back(graph.isFixed(key));
  }
  if (keys.empty()) return;
  std::vector<Factor> factors;
  for (const Factor& f : graph.factors()) {
    if (graph.connects(f)) factors.push_back(f);
  }
  const dgs::Block block(keys, factors, "chordal initialisation");
  const std::vector<bool> none;
  const dgs::Layout layout = dgs::makeLayout(block, fixed, none);
  std::vector<Eigen::Matrix3d> rotations;
  for (const Eigen::Isometry3d& T : initial) rotations.push_back(T.linear());
  dgs::RotationProblem rotation;
  if (!rotation.configure(block, layout, none, rotations)) {
    throw core::Error("chordal initialisation: the rotation system is not positive definite");
  }
  rotations = rotation.solve(block, none, {}, rotations);
  dgs::PoseValues poses;
  for (int i = 0; i < block.size(); ++i) {
    const bool held = layout.unknown[i] < 0;
    poses.R_hat.push_back(held ? initial[i].linear() : core::projectToSO3(rotations[i]));
    poses.delta.push_back(Eigen::Vector3d::Zero());
    poses.t.push_back(initial[i].translation());
  }
  dgs::PoseProblem pose;
  if (!pose.configure(block, layout, none, poses)) {
    throw core::Error("chordal initialisation: the pose system is not positive definite");
  }
  pose.step(block, none, {}, {}, 1.0, true, poses);
  for (int i = 0; i < block.size(); ++i) {
    if (layout.unknown[i] >= 0) graph.setEstimate(keys[i], poses.pose(i));
  }
}

// ---- the in-process driver ----------------------------------------------

namespace {

/// One group's round as runDgs drives it.
struct RunningRound {
  std::set<core::RobotId> group;
  std::vector<core::RobotId> order;
  int sweeps = 0;
  int max_sweeps = 0;  ///< a safety net: both caps plus a wave across the group per stage
};

/// Runs every group's rounds side by side, one sweep of each at a time.
class Driver {
 public:
  Driver(PoseGraph& graph, const DgsConfig& config, const std::set<core::RobotId>& vanish,
         int vanish_after, const DgsTraffic& traffic)
      : graph_(graph),
        config_(config),
        vanish_(vanish),
        vanish_after_(vanish_after),
        traffic_(traffic) {
    for (auto& [robot, local] : partitionByRobot(graph)) {
      agents_.emplace(robot, DgsAgent(robot, std::move(local), config));
    }
    for (const auto& group : connectedGroups(graph)) start(group);
  }

  DgsSummary run() {
    while (!rounds_.empty()) sweep();
    for (const auto& [robot, agent] : agents_) {
      for (const auto& [key, T] : agent.estimates()) {
        if (graph_.hasNode(key)) graph_.setEstimate(key, T);
      }
    }
    return summary_;
  }

 private:
  void start(const std::set<core::RobotId>& group) {
    ++round_number_;
    for (const core::RobotId robot : group) agents_.at(robot).startRound(group, round_number_);
    const int wave = 2 * static_cast<int>(group.size()) + 2;
    rounds_.push_back({group, optimisationOrder(graph_, group), 0,
                       config_.max_rotation_iterations + config_.max_pose_iterations + wave});
  }

  /// One sweep of every running round; finished rounds leave, abandoned ones restart.
  void sweep() {
    bool rotation = false;
    bool pose = false;
    std::vector<RunningRound> running;
    std::vector<std::set<core::RobotId>> restart;
    for (RunningRound& r : rounds_) {
      bool silence = false;
      for (const core::RobotId robot : r.order) {
        DgsAgent& agent = agents_.at(robot);
        rotation |= agent.stage() == DgsStage::rotation;
        pose |= agent.stage() == DgsStage::pose;
        if (agent.stage() == DgsStage::done) continue;
        if (isSilent(agent)) {
          silence = true;
          continue;
        }
        agent.iterate();
        deliver(agent.outgoing());
      }
      const bool done = std::all_of(r.group.begin(), r.group.end(), [&](core::RobotId robot) {
        return agents_.at(robot).stage() == DgsStage::done || silent_.contains(robot);
      });
      if (done) {
        ++summary_.groups;
      } else if (silence || ++r.sweeps > r.max_sweeps) {
        abandon(r, restart);
      } else {
        running.push_back(std::move(r));
      }
    }
    summary_.iterations_rotation += rotation ? 1 : 0;
    summary_.iterations_pose += pose ? 1 : 0;
    rounds_ = std::move(running);
    for (const auto& group : restart) start(group);
  }

  /// A robot of `vanish` stops answering once it has taken vanish_after stage-1 steps.
  bool isSilent(const DgsAgent& agent) {
    if (silent_.contains(agent.robot())) return true;
    if (!vanish_.contains(agent.robot())) return false;
    if (agent.stage() == DgsStage::rotation &&
        agent.stageIterations(DgsStage::rotation) < vanish_after_) {
      return false;
    }
    silent_.insert(agent.robot());
    return true;
  }

  void deliver(const std::vector<DgsMessage>& messages) {
    for (const DgsMessage& m : messages) {
      if (traffic_) traffic_(m);
      ++summary_.messages;
      summary_.separator_values_rotation += m.rotations.size();
      summary_.separator_values_pose += m.poses.size();
      summary_.values_sent[m.from] += m.rotations.size() + m.poses.size();
      const auto to = agents_.find(m.to);
      if (to != agents_.end() && !silent_.contains(m.to)) to->second.receive(m);
    }
  }

  /// The neighbours noticed a silence (or the round overran): everyone
  /// abandons the round and keeps the last finished round's estimates; the
  /// robots still answering start again in the groups they form without the
  /// silent ones (a round that overran without a silence is not retried).
  void abandon(const RunningRound& r, std::vector<std::set<core::RobotId>>& restart) {
    ++summary_.aborted_rounds;
    bool silence = false;
    for (const core::RobotId robot : r.group) {
      agents_.at(robot).abortRound();
      silence |= silent_.contains(robot);
    }
    if (!silence) return;
    std::set<core::RobotId> exclude = silent_;
    for (const auto& [robot, agent] : agents_) {
      if (!r.group.contains(robot)) exclude.insert(robot);
    }
    for (const auto& group : connectedGroups(graph_, exclude)) restart.push_back(group);
  }

  PoseGraph& graph_;
  DgsConfig config_;
  std::set<core::RobotId> vanish_;
  int vanish_after_ = 0;
  const DgsTraffic& traffic_;
  std::map<core::RobotId, DgsAgent> agents_;
  std::vector<RunningRound> rounds_;
  std::set<core::RobotId> silent_;
  std::uint32_t round_number_ = 0;
  DgsSummary summary_;
};

}  // namespace

DgsSummary runDgs(PoseGraph& graph, const DgsConfig& config, const std::set<core::RobotId>& vanish,
                  int vanish_after, const DgsTraffic& traffic) {
  const auto start = std::chrono::steady_clock::now();
  validate(config);
  Driver driver(graph, config, vanish, vanish_after, traffic);
  DgsSummary summary = driver.run();
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace dcl::backend
