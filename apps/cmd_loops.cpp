// `dcl-slam bench loops`: the inter-robot loop pipeline end to end on a
// dataset (paper §III-B and §III-C): every robot's front-end, then for every
// keyframe the place search in each other robot's index, the compact
// verification cloud as it would cross the radio, verification against the
// other robot's submap, and PCM over each robot pair. Ground truth grades
// every stage: which candidates were real revisits, which verified loops
// measure the true relative pose, and which of those PCM kept.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include <dcl/backend/loop_check.hpp>
#include <dcl/backend/pcm.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/progress.hpp>
#include <dcl/eval/loop_scoring.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/file.hpp>
#include <dcl/odometry/lidar_odometry.hpp>
#include <dcl/odometry/local_mapper.hpp>
#include <dcl/place/place_index.hpp>
#include <dcl/registration/cloud_codec.hpp>
#include <dcl/registration/verification.hpp>
#include <dcl/robot/robot_node.hpp>
#include <dcl/sim/sim_source.hpp>

#include "commands.hpp"
#include "option_checks.hpp"
#include "output_folder.hpp"
#include "printing.hpp"

namespace dcl::apps {

namespace {

using Json = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

struct LoopsOptions {
  std::string dataset;                  ///< dataset folder, with ground truth
  std::string out = "out/bench_loops";  ///< output folder (metrics.json, loops.csv)
  std::size_t max_frames = 0;           ///< frames per robot, 0: all
  eval::LoopTolerance tolerance;        ///< a loop is correct within 1 m and 2 deg
  bool json = false;                    ///< print metrics.json instead of the summary
  bool force = false;                   ///< replace --out even when it holds other files
};

/// One robot after its front-end: keyframes (with clouds), its local graph
/// (odometry and intra-robot loops), the ground truth at its keyframes, and
/// its place index.
struct Robot {
  core::RobotId id;
  std::string name;
  std::vector<core::Keyframe> keyframes;
  backend::PoseGraph graph;
  std::vector<Eigen::Isometry3d> T_world_keyframe;  ///< ground truth at each keyframe
  std::vector<std::shared_ptr<const place::PlaceDescriptor>> descriptions;
  std::unique_ptr<place::PlaceIndex> index;
};

Robot runFrontEnd(const io::DatasetSpec& spec, std::size_t index,
                  const std::shared_ptr<const sim::SimWorld>& world, const AppConfig& config,
                  std::size_t max_frames) {
  const auto id = core::RobotId(static_cast<std::uint8_t>(index));
  Robot robot{id, spec.robots[index].name, {}, {}, {}, {}, {}};
  if (spec.robots[index].ground_truth.empty())
    throw core::Error("robot '" + robot.name + "' has no ground truth: bench loops grades by it");
  const core::Trajectory gt = io::readGroundTruth(spec, index);
  const auto scans = sim::openRobotScans(spec, index, world);
  const std::size_t frames = max_frames > 0 ? std::min(max_frames, scans->size()) : scans->size();
  odometry::LidarOdometry odometry(config.odometry);
  odometry::LocalMapper mapper(id, config.mapper);
  core::ProgressBar progress("front-end " + robot.name, frames, "frames");
  for (std::size_t i = 0; i < frames; ++i) {
    const core::PointCloud scan = scans->scan(i);
    if (const auto up = scans->up(i)) odometry.observeUp(*up);
    const odometry::OdometryResult result = odometry.process(scans->stamp(i), scan);
    if (result.registered.empty()) {
      (void)mapper.process(result, scan);
    } else {
      (void)mapper.process(result);
    }
    progress.update(i + 1, fmt::format("{} keyframes", mapper.keyframes().size()));
  }
  progress.finish();
  robot.keyframes = mapper.keyframes();
  robot.graph = mapper.graph();
  for (const core::Keyframe& k : robot.keyframes) {
    const auto T = gt.at(k.stamp);
    if (!T) throw core::Error("robot '" + robot.name + "': no ground truth at a keyframe's stamp");
    robot.T_world_keyframe.push_back(*T);
  }
  return robot;
}

void describe(Robot& robot, const std::shared_ptr<const place::Descriptor>& descriptor,
              const place::PlaceIndexConfig& index_config) {
  robot.descriptions.resize(robot.keyframes.size());
  tbb::parallel_for(std::size_t{0}, robot.keyframes.size(), [&](std::size_t i) {
    robot.descriptions[i] = descriptor->describe(robot.keyframes[i].cloud);
  });
  robot.index = std::make_unique<place::PlaceIndex>(descriptor, robot.id, index_config);
  for (std::size_t i = 0; i < robot.keyframes.size(); ++i)
    robot.index->add(robot.keyframes[i].id, robot.descriptions[i]);
}

/// A candidate found by robot `verifier` for robot `querier`'s keyframe, and
/// what became of it.
struct Candidate {
  std::size_t querier = 0;      ///< robot index of the query keyframe
  std::size_t query = 0;        ///< its keyframe index
  std::size_t verifier = 0;     ///< robot index of the matched keyframe
  std::size_t match = 0;        ///< its keyframe index
  place::Match place;           ///< the place match
  double ground_truth_m = 0.0;  ///< true distance between the two keyframes
  std::size_t wire_bytes = 0;   ///< the compact verification cloud
  registration::VerificationResult verification;
  eval::LoopError error;   ///< of the verified relative pose against the ground truth
  bool correct = false;    ///< verified, and within the error bounds of ground truth
  bool kept = false;       ///< PCM kept it, and the check after it did not withdraw it
  bool withdrawn = false;  ///< PCM kept it, the check after it withdrew it
};

/// Matches refused as ambiguous (PlaceIndexConfig::distinct_ratio).
struct Refused {
  std::size_t count = 0;
  std::size_t true_places = 0;  ///< of which the refused match was the right place
};

/// Every candidate of one querying robot's keyframes in another robot's index.
std::vector<Candidate> search(const std::vector<Robot>& robots, std::size_t querier,
                              std::size_t verifier, double true_loop_distance, Refused& refused) {
  std::vector<Candidate> out;
  const Robot& q = robots[querier];
  const Robot& v = robots[verifier];
  const auto positionOn = [](const Robot& robot) -> place::KeyframePosition {
    return [&robot](core::KeyframeId id) {
      return Eigen::Vector3d(robot.keyframes.at(id.value()).T_odom_keyframe.translation());
    };
  };
  for (std::size_t i = 0; i < q.keyframes.size(); ++i) {
    // How closely each robot's own route repeats the place, over the whole
    // route (RobotNode judges a loop again whenever either robot passes a
    // place like it, before or after the loop was found).
    const std::optional<float> look_alike =
        q.index->lookAlikeDistance(*q.descriptions[i], q.keyframes[i].T_odom_keyframe.translation(),
                                   positionOn(q), q.keyframes.size());
    place::DistinctMatch found =
        v.index->queryDistinct(*q.descriptions[i], positionOn(v), look_alike);
    if (found.best) {
      const auto m = static_cast<std::size_t>(found.best->slot);
      const std::optional<float> repeat = v.index->lookAlikeDistance(
          *v.descriptions[m], v.keyframes[m].T_odom_keyframe.translation(), positionOn(v),
          v.keyframes.size());
      if (repeat && !v.index->config().beats(found.best->match.distance, *repeat)) {
        found.refused = found.best;
        found.best.reset();
      }
    }
    if (found.refused) {
      ++refused.count;
      const Eigen::Isometry3d& T_match = v.T_world_keyframe[found.refused->slot];
      if ((q.T_world_keyframe[i].translation() - T_match.translation()).norm() < true_loop_distance)
        ++refused.true_places;
    }
    const std::optional<place::PlaceCandidate>& best = found.best;
    if (!best) continue;
    Candidate c;
    c.querier = querier;
    c.query = i;
    c.verifier = verifier;
    c.match = static_cast<std::size_t>(best->slot);
    c.place = best->match;
    c.ground_truth_m =
        (q.T_world_keyframe[i].translation() - v.T_world_keyframe[c.match].translation()).norm();
    out.push_back(c);
  }
  return out;
}

void verify(const std::vector<Robot>& robots, Candidate& c, const AppConfig& config) {
  const Robot& q = robots[c.querier];
  const Robot& v = robots[c.verifier];
  const registration::VerificationConfig& vc = config.verification;
  registration::CloudCodecConfig codec;
  codec.voxel_size = vc.voxel_size;
  const std::vector<std::uint8_t> wire =
      registration::encodeVerificationCloud(q.keyframes[c.query].cloud, codec);
  c.wire_bytes = wire.size();
  const core::PointCloud received = registration::decodeVerificationCloud(wire);
  const core::PointCloud submap =
      registration::buildSubmap(v.keyframes, c.match, vc.submap_keyframes, vc.voxel_size);
  c.verification = registration::verifyLoop(received, -c.place.yaw_rad, submap, vc);
  if (!c.verification.accepted) return;
  c.error = eval::loopError(c.verification.T_candidate_query, v.T_world_keyframe[c.match],
                            q.T_world_keyframe[c.query]);
}

/// The loop as a robot node keeps it: its covariance with the configured loop noise.
backend::Factor loopFactor(const std::vector<Robot>& robots, const Candidate& c,
                           const robot::RobotConfig& node) {
  backend::Factor f;
  f.from = {robots[c.verifier].id, robots[c.verifier].keyframes[c.match].id};
  f.to = {robots[c.querier].id, robots[c.querier].keyframes[c.query].id};
  f.T_from_to = c.verification.T_candidate_query;
  f.information =
      backend::informationFromCovariance(robot::loopCovariance(c.verification.covariance, node));
  f.kind = backend::FactorKind::inter_loop;
  return f;
}

/// PCM over each robot pair; marks the candidates it kept.
Json runPcm(const std::vector<Robot>& robots, std::vector<Candidate>& candidates,
            const robot::RobotConfig& node) {
  const backend::PcmConfig& config = node.pcm;
  Json pairs = Json::array();
  for (std::size_t a = 0; a < robots.size(); ++a)
    for (std::size_t b = a + 1; b < robots.size(); ++b) {
      backend::PairwiseConsistency pcm(robots[a].id, robots[b].id, config);
      for (const std::size_t r : {a, b})
        for (const backend::Factor& f : robots[r].graph.factors()) pcm.addRobotFactor(f);
      // The verified loops between a and b, from either robot's queries.
      std::vector<Candidate*> verified;
      for (Candidate& c : candidates) {
        const bool pair =
            std::min(c.querier, c.verifier) == a && std::max(c.querier, c.verifier) == b;
        if (pair && c.verification.accepted) verified.push_back(&c);
      }
      std::size_t loops = 0;
      for (const Candidate* c : verified)
        loops += pcm.addLoop(loopFactor(robots, *c, node)) ? 1 : 0;
      const backend::PcmDecision& decision = pcm.decide();
      std::set<backend::LoopId> kept;
      for (const backend::Factor& f : decision.accepted) kept.insert(backend::loopId(f));
      for (Candidate* c : verified)
        c->kept = kept.contains(backend::loopId(loopFactor(robots, *c, node)));
      pairs.push_back({{"robots", robots[a].name + "-" + robots[b].name},
                       {"loops", loops},
                       {"kept", decision.accepted.size()},
                       {"exact", decision.exact}});
    }
  return pairs;
}

/// The second line of defence, as the robots' rounds apply it: the robots'
/// own graphs with the loops PCM kept, solved together; a robot pair at a
/// time, the loops the solution cannot explain are withdrawn. Marks them.
void checkKeptLoops(const std::vector<Robot>& robots, std::vector<Candidate>& candidates,
                    const robot::RobotConfig& node) {
  backend::PoseGraph joint;
  for (const Robot& r : robots) {
    for (const auto& [key, T] : r.graph.nodes()) joint.addNode(key, T);
    for (const backend::Factor& f : r.graph.factors()) joint.addFactor(f);
  }
  std::set<backend::LoopId> added;
  for (const Candidate& c : candidates) {
    const backend::Factor f = loopFactor(robots, c, node);
    if (c.kept && added.insert(backend::loopId(f)).second) joint.addFactor(f);
  }
  backend::SolverConfig solver;
  solver.initialisation = "chordal";
  const std::vector<backend::LoopId> out =
      backend::withdrawUnexplained(joint, node.loop_check, solver);
  const std::set<backend::LoopId> withdrawn(out.begin(), out.end());
  for (Candidate& c : candidates) {
    if (!c.kept || !withdrawn.contains(backend::loopId(loopFactor(robots, c, node)))) continue;
    c.kept = false;
    c.withdrawn = true;
  }
}

double ratio(std::size_t a, std::size_t b) {
  return b == 0 ? 0.0 : static_cast<double>(a) / static_cast<double>(b);
}

/// What became of candidate `c`, as eval grades it.
eval::CandidateLoop gradeOf(const Candidate& c) {
  return {c.ground_truth_m, c.verification.accepted, c.correct, c.kept, c.withdrawn};
}

Json metricsOf(const std::vector<Candidate>& candidates, const LoopsOptions& o,
               double true_loop_distance) {
  std::vector<eval::CandidateLoop> graded;
  std::size_t ransac = 0, bytes = 0;
  registration::VerificationStats stats;
  for (const Candidate& c : candidates) {
    graded.push_back(gradeOf(c));
    stats.add(c.verification);
    bytes += c.wire_bytes;
    ransac += c.verification.accepted && c.verification.used_ransac ? 1 : 0;
  }
  const eval::LoopCounts n = eval::countLoops(graded, true_loop_distance);
  Json reasons = Json::object();
  for (std::size_t r = 1; r < registration::kRejectReasonCount; ++r) {
    const auto reason = static_cast<registration::RejectReason>(r);
    reasons[std::string(registration::toString(reason))] = stats.count(reason);
  }
  return {{"candidates", n.candidates},
          {"candidates_true", n.candidates_true},
          {"verified", n.verified},
          {"verified_correct", n.verified_correct},
          {"verified_wrong", n.verified_wrong},
          {"verified_by_ransac", ransac},
          {"rejected_by_reason", reasons},
          {"kept", n.kept},
          {"kept_correct", n.kept_correct},
          {"kept_wrong", n.kept_wrong},
          {"withdrawn", n.withdrawn},
          {"withdrawn_correct", n.withdrawn_correct},
          {"precision", n.precision},
          {"recall", n.recall},
          {"wire_bytes_mean", ratio(bytes, candidates.size())},
          {"correct_within", {{"m", o.tolerance.max_error_m}, {"deg", o.tolerance.max_error_deg}}}};
}

void writeCsv(const std::string& path, const std::vector<Robot>& robots,
              const std::vector<Candidate>& candidates) {
  std::string s =
      "query_robot,query_keyframe,match_robot,match_keyframe,place_distance,yaw_deg,"
      "ground_truth_m,verified,reason,inlier_share,fitness,ransac,error_m,error_deg,correct,kept,"
      "withdrawn\n";
  for (const Candidate& c : candidates)
    s += fmt::format(
        "{},{},{},{},{:.4f},{:.2f},{:.3f},{},{},{:.3f},{:.3f},{},{:.3f},{:.3f},{},{},{}\n",
        robots[c.querier].name, c.query, robots[c.verifier].name, c.match, c.place.distance,
        c.place.yaw_rad * 180.0 / M_PI, c.ground_truth_m, c.verification.accepted ? 1 : 0,
        registration::toString(c.verification.reason), c.verification.inlier_share,
        c.verification.fitness, c.verification.used_ransac ? 1 : 0, c.error.translation_m,
        c.error.rotation_deg, c.correct ? 1 : 0, c.kept ? 1 : 0, c.withdrawn ? 1 : 0);
  io::writeFileAtomic(path, [&](std::ostream& out) { out << s; });
}

void runLoops(const LoopsOptions& o, const AppConfig& config) {
  OutputFolder out(o.out, o.force);
  out.requireOutside(o.dataset, "the dataset");
  const io::DatasetSpec spec = io::readDataset(o.dataset, datasetReadOptions());
  if (spec.robots.size() < 2)
    throw core::Error("dataset '" + o.dataset + "' has one robot: inter-robot loops need two");
  std::shared_ptr<const sim::SimWorld> world;
  if (spec.sim) world = std::make_shared<const sim::SimWorld>(spec);

  const auto start = Clock::now();
  std::vector<Robot> robots;
  for (std::size_t r = 0; r < spec.robots.size(); ++r)
    robots.push_back(runFrontEnd(spec, r, world, config, o.max_frames));
  const double front_end_s = secondsSince(start);

  const std::shared_ptr<const place::Descriptor> descriptor =
      place::makeDescriptor(config.place.descriptor);
  for (Robot& robot : robots) describe(robot, descriptor, config.place.evaluation.index);
  std::vector<Candidate> candidates;
  Refused refused;
  for (std::size_t q = 0; q < robots.size(); ++q)
    for (std::size_t v = 0; v < robots.size(); ++v)
      if (q != v) {
        std::vector<Candidate> found =
            search(robots, q, v, config.place.evaluation.true_loop_distance, refused);
        candidates.insert(candidates.end(), found.begin(), found.end());
      }

  const auto verify_start = Clock::now();
  core::ProgressBar progress("verification", candidates.size(), "candidates");
  std::mutex progress_mutex;  // the bar is not thread-safe
  std::size_t done = 0;
  tbb::parallel_for(std::size_t{0}, candidates.size(), [&](std::size_t i) {
    verify(robots, candidates[i], config);
    const std::lock_guard lock(progress_mutex);
    progress.update(++done);
  });
  progress.finish();
  const double verify_s = secondsSince(verify_start);
  for (Candidate& c : candidates)
    c.correct = c.verification.accepted && eval::isCorrect(c.error, o.tolerance);

  const robot::RobotConfig node = robotConfig(config);
  const auto pcm_start = Clock::now();
  const Json pairs = runPcm(robots, candidates, node);
  const double pcm_s = secondsSince(pcm_start);
  const auto check_start = Clock::now();
  checkKeptLoops(robots, candidates, node);
  const double check_s = secondsSince(check_start);

  Json m = {{"dataset", spec.name}, {"robots", robots.size()}};
  Json keyframes = Json::object();
  for (const Robot& r : robots) keyframes[r.name] = r.keyframes.size();
  m["keyframes"] = keyframes;
  m["loops"] = metricsOf(candidates, o, config.place.evaluation.true_loop_distance);
  m["loops"]["refused_ambiguous"] = refused.count;
  m["loops"]["refused_ambiguous_true_place"] = refused.true_places;
  m["pcm_pairs"] = pairs;
  m["seconds"] = {{"front_end", front_end_s},
                  {"verification", verify_s},
                  {"verification_mean_ms", 1e3 * ratio(1, candidates.size()) * verify_s},
                  {"pcm", pcm_s},
                  {"loop_check", check_s}};
  io::writeFileAtomic(out.path() + "/metrics.json",
                      [&](std::ostream& s) { s << m.dump(2) << "\n"; });
  writeCsv(out.path() + "/loops.csv", robots, candidates);
  out.commit();
  if (o.json) {
    fmt::print("{}\n", m.dump(2));
    return;
  }
  const Json& l = m["loops"];
  fmt::print("{}: {} robots, {} candidates ({} real revisits)\n", spec.name, robots.size(),
             l["candidates"].get<std::size_t>(), l["candidates_true"].get<std::size_t>());
  fmt::print("  refused {} matches as ambiguous (another place nearly as close; {} were right)\n",
             l["refused_ambiguous"].get<std::size_t>(),
             l["refused_ambiguous_true_place"].get<std::size_t>());
  fmt::print("  verified {} ({} correct, {} wrong; {} by the RANSAC fallback)\n",
             l["verified"].get<std::size_t>(), l["verified_correct"].get<std::size_t>(),
             l["verified_wrong"].get<std::size_t>(), l["verified_by_ransac"].get<std::size_t>());
  fmt::print(
      "  PCM and the check after it kept {} ({} correct, {} wrong): precision {:.3f}, "
      "recall {:.3f}; the check withdrew {} ({} correct)\n",
      l["kept"].get<std::size_t>(), l["kept_correct"].get<std::size_t>(),
      l["kept_wrong"].get<std::size_t>(), l["precision"].get<double>(), l["recall"].get<double>(),
      l["withdrawn"].get<std::size_t>(), l["withdrawn_correct"].get<std::size_t>());
  fmt::print("  wrote {}/metrics.json and loops.csv\n", o.out);
}

}  // namespace

void addBenchLoopsCommand(CLI::App& bench, const AppConfig& config) {
  auto o = std::make_shared<LoopsOptions>();
  CLI::App* cmd = bench.add_subcommand(
      "loops",
      "inter-robot loops end to end on a dataset: front-ends, place search, compact cloud, "
      "verification, PCM, each stage graded by ground truth");
  cmd->add_option("--dataset", o->dataset, "dataset folder (dataset.yaml), with ground truth")
      ->required();
  cmd->add_option("--out", o->out, "output folder (metrics.json, loops.csv)")
      ->capture_default_str();
  cmd->add_option("--max-frames", o->max_frames, "frames per robot (0: all)")
      ->check(kNonNegative)
      ->capture_default_str();
  cmd->add_option("--max-error-m", o->tolerance.max_error_m,
                  "m, a correct loop's largest translation error")
      ->check(kNonNegative)
      ->capture_default_str();
  cmd->add_option("--max-error-deg", o->tolerance.max_error_deg,
                  "deg, a correct loop's largest rotation error")
      ->check(kNonNegative)
      ->capture_default_str();
  cmd->add_flag("--json", o->json, "print metrics.json");
  addForceFlag(*cmd, o->force);
  cmd->callback([o, &config] { runLoops(*o, config); });
}

}  // namespace dcl::apps
