// `dcl-slam eval ate|rpe`: trajectory metrics with the evo toolbox's definitions.
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/core/error.hpp>
#include <dcl/eval/ate.hpp>
#include <dcl/eval/rpe.hpp>
#include <dcl/io/pose_file.hpp>

#include "commands.hpp"
#include "option_checks.hpp"

namespace dcl::apps {

namespace {

/// What `eval ate` and `eval rpe` share: the two trajectories and how to pair them.
struct EvalInputs {
  std::vector<std::string> gt_paths;   ///< one per robot
  std::vector<std::string> est_paths;  ///< one per robot, in the order of gt_paths
  std::string format = "tum";
  std::vector<std::string> gt_times;   ///< KITTI only: none, or one per robot
  std::vector<std::string> est_times;  ///< KITTI only: none, or one per robot
  std::string alignment;
  std::size_t reference_robot = 0;  ///< several robots: whose pairs fix the common alignment
  double max_diff = 0.01;
  double offset = 0.0;
  bool json = false;
};

void addInputOptions(CLI::App& cmd, EvalInputs& in) {
  cmd.add_option("--gt", in.gt_paths, "ground-truth trajectory file (one per robot)")->required();
  cmd.add_option("--est", in.est_paths, "estimated trajectory file (one per robot)")->required();
  cmd.add_option("--format", in.format, "file format of both: kitti or tum")->capture_default_str();
  cmd.add_option("--gt-times", in.gt_times,
                 "times file of a KITTI ground truth (one stamp a line; one per robot)");
  cmd.add_option("--est-times", in.est_times, "times file of a KITTI estimate (one per robot)");
  cmd.add_option("--align", in.alignment, "alignment of the estimate: none, se3 or sim3")
      ->capture_default_str();
  cmd.add_option("--max-diff", in.max_diff, "s, largest stamp difference to associate")
      ->check(kNonNegative)
      ->capture_default_str();
  cmd.add_option("--offset", in.offset, "s, added to the estimate's stamps")
      ->check(kFinite)
      ->capture_default_str();
  cmd.add_flag("--json", in.json, "print the result as JSON");
}

std::optional<std::string> optionalPath(const std::vector<std::string>& paths, std::size_t i) {
  return paths.empty() ? std::nullopt : std::optional<std::string>(paths[i]);
}

void requireOnePerRobot(const EvalInputs& in) {
  const std::size_t n = in.gt_paths.size();
  if (in.est_paths.size() != n) {
    throw core::Error(fmt::format("{} --gt files but {} --est files: give one of each per robot", n,
                                  in.est_paths.size()));
  }
  for (const auto* times : {&in.gt_times, &in.est_times}) {
    if (!times->empty() && times->size() != n) {
      throw core::Error(fmt::format("{} times files for {} robots", times->size(), n));
    }
  }
}

/// Loads robot i's files and pairs their poses: KITTI files without times pair
/// by index (as evo's `kitti` mode), everything else by nearest stamp.
eval::Association loadPairs(const EvalInputs& in, std::size_t i) {
  const io::PoseFormat format = io::parsePoseFormat(in.format);
  const auto gt = io::readPoses(in.gt_paths[i], format, optionalPath(in.gt_times, i));
  const auto est = io::readPoses(in.est_paths[i], format, optionalPath(in.est_times, i));
  eval::AssociationOptions options;
  const bool stamped =
      format == io::PoseFormat::tum || (!in.gt_times.empty() && !in.est_times.empty());
  options.mode = stamped ? eval::AssociationMode::timestamp : eval::AssociationMode::index;
  options.max_diff = in.max_diff;
  options.offset = in.offset;
  return eval::associate(est, gt, options);
}

/// Every robot's pairs, in the order the files were given.
std::vector<eval::Association> loadAllPairs(const EvalInputs& in) {
  requireOnePerRobot(in);
  std::vector<eval::Association> robots;
  for (std::size_t i = 0; i < in.gt_paths.size(); ++i) robots.push_back(loadPairs(in, i));
  return robots;
}

nlohmann::ordered_json toJson(const eval::Statistics& s) {
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"std", s.std},
          {"min", s.min},   {"max", s.max},   {"count", s.count}};
}

void printJson(const nlohmann::ordered_json& j) {
  // 17 significant digits: the figures round-trip exactly.
  fmt::print("{}\n", j.dump(2));
}

void printStatsTable(const eval::Statistics& t, const eval::Statistics& r) {
  fmt::print("{:>12} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}\n", "", "rmse", "mean", "median",
             "std", "min", "max");
  fmt::print("{:>12} {:10.4f} {:10.4f} {:10.4f} {:10.4f} {:10.4f} {:10.4f}\n", "trans [m]", t.rmse,
             t.mean, t.median, t.std, t.min, t.max);
  fmt::print("{:>12} {:10.4f} {:10.4f} {:10.4f} {:10.4f} {:10.4f} {:10.4f}\n", "rot [deg]", r.rmse,
             r.mean, r.median, r.std, r.min, r.max);
}

nlohmann::ordered_json toJson(const eval::AteResult& ate) {
  return {{"pairs", ate.pairs},
          {"translation_m", toJson(ate.translation_m)},
          {"rotation_deg", toJson(ate.rotation_deg)}};
}

void runSingleAte(const eval::Association& pairs, const EvalInputs& in) {
  const eval::AteResult ate = eval::computeAte(pairs, eval::parseAlignment(in.alignment));
  if (in.json) {
    printJson({{"metric", "ate"},
               {"align", std::string(eval::toString(ate.alignment))},
               {"pairs", ate.pairs},
               {"translation_m", toJson(ate.translation_m)},
               {"rotation_deg", toJson(ate.rotation_deg)},
               {"scale", ate.S_gt_est.s}});
    return;
  }
  fmt::print("ATE: {} pose pairs, alignment {}, scale {:.6f}\n", ate.pairs,
             eval::toString(ate.alignment), ate.S_gt_est.s);
  printStatsTable(ate.translation_m, ate.rotation_deg);
}

void printMultiRobotAte(const eval::MultiRobotAteResult& ate, const EvalInputs& in) {
  fmt::print("ATE of {} robots, alignment {} fitted on robot {} (scale {:.6f})\n",
             ate.robots.size(), in.alignment, ate.reference_robot, ate.S_gt_est.s);
  for (std::size_t i = 0; i < ate.robots.size(); ++i) {
    fmt::print("robot {} ({}, {} pairs)\n", i, in.est_paths[i], ate.robots[i].pairs);
    printStatsTable(ate.robots[i].translation_m, ate.robots[i].rotation_deg);
  }
  fmt::print("all robots ({} pairs)\n", ate.pooled.pairs);
  printStatsTable(ate.pooled.translation_m, ate.pooled.rotation_deg);
}

/// The paper's multi-robot protocol: one alignment, fitted on the reference
/// robot's trajectory, applied to every robot.
void runMultiRobotAte(const std::vector<eval::Association>& robots, const EvalInputs& in) {
  eval::MultiRobotAteOptions options;
  options.alignment = eval::parseAlignment(in.alignment);
  options.reference_robot = in.reference_robot;
  const eval::MultiRobotAteResult ate = eval::computeMultiRobotAte(robots, options);
  if (!in.json) return printMultiRobotAte(ate, in);
  nlohmann::ordered_json per_robot = nlohmann::ordered_json::array();
  for (const auto& robot : ate.robots) per_robot.push_back(toJson(robot));
  printJson({{"metric", "ate"},
             {"align", in.alignment},
             {"reference_robot", ate.reference_robot},
             {"scale", ate.S_gt_est.s},
             {"robots", per_robot},
             {"pooled", toJson(ate.pooled)}});
}

void runAte(const EvalInputs& in) {
  const std::vector<eval::Association> robots = loadAllPairs(in);
  if (robots.size() == 1 && in.reference_robot == 0) return runSingleAte(robots.front(), in);
  runMultiRobotAte(robots, in);
}

nlohmann::ordered_json toJson(const std::optional<eval::KittiResult>& kitti) {
  if (!kitti) return nullptr;
  return {{"translation_percent", kitti->translation_percent},
          {"rotation_deg_per_100m", kitti->rotation_deg_per_100m},
          {"rotation_deg_per_m", kitti->rotation_deg_per_m},
          {"segments", kitti->segments}};
}

void printRpe(const eval::RpeResult& rpe, const eval::RpeOptions& options) {
  fmt::print("RPE: {} pairs, delta {} {}, alignment {}\n", rpe.pairs.size(), options.delta,
             eval::toString(options.delta_unit), eval::toString(rpe.alignment));
  printStatsTable(rpe.translation_m, rpe.rotation_deg);
  if (!rpe.kitti) {
    fmt::print("KITTI metric: trajectory shorter than the shortest segment\n");
    return;
  }
  fmt::print("KITTI metric: {:.4f} % translation, {:.4f} deg/100 m rotation ({} segments)\n",
             rpe.kitti->translation_percent, rpe.kitti->rotation_deg_per_100m, rpe.kitti->segments);
}

void runRpe(const EvalInputs& in, const eval::RpeOptions& base) {
  eval::RpeOptions options = base;
  options.alignment = eval::parseAlignment(in.alignment);
  const std::vector<eval::Association> robots = loadAllPairs(in);
  if (robots.size() != 1) throw core::Error("eval rpe takes one --gt and one --est");
  const eval::RpeResult rpe = eval::computeRpe(robots.front(), options);
  if (!in.json) return printRpe(rpe, options);
  printJson({{"metric", "rpe"},
             {"delta", options.delta},
             {"delta_unit", std::string(eval::toString(options.delta_unit))},
             {"align", std::string(eval::toString(rpe.alignment))},
             {"pairs", rpe.pairs.size()},
             {"translation_m", toJson(rpe.translation_m)},
             {"rotation_deg", toJson(rpe.rotation_deg)},
             {"kitti", toJson(rpe.kitti)}});
}

}  // namespace

void addEvalCommand(CLI::App& app, const AppConfig& config) {
  auto* eval = app.add_subcommand("eval", "trajectory metrics (evo-compatible definitions)");
  eval->require_subcommand(1);

  auto inputs = std::make_shared<EvalInputs>();
  inputs->alignment = config.eval.alignment;
  inputs->max_diff = config.eval.max_time_diff;
  inputs->offset = config.eval.time_offset;
  auto* ate = eval->add_subcommand(
      "ate", "absolute trajectory error (evo_ape); several --gt/--est pairs: one per robot");
  addInputOptions(*ate, *inputs);
  ate->add_option("--reference-robot", inputs->reference_robot,
                  "several robots: the one whose trajectory fixes the common alignment")
      ->check(kNonNegative)
      ->capture_default_str();
  ate->callback([inputs] { runAte(*inputs); });

  auto rpe_options = std::make_shared<eval::RpeOptions>();
  rpe_options->delta = config.eval.rpe_delta;
  rpe_options->delta_unit = eval::parseDeltaUnit(config.eval.rpe_delta_unit);
  rpe_options->kitti_options.lengths = config.eval.kitti_lengths;
  rpe_options->kitti_options.step = static_cast<std::size_t>(config.eval.kitti_step);
  auto* rpe = eval->add_subcommand("rpe", "relative pose error (evo_rpe) and the KITTI metric");
  addInputOptions(*rpe, *inputs);
  rpe->add_option("--delta", rpe_options->delta, "pair distance")->capture_default_str();
  rpe->add_option_function<std::string>(
      "--delta-unit",
      [rpe_options](const std::string& u) { rpe_options->delta_unit = eval::parseDeltaUnit(u); },
      "frames or meters");
  rpe->add_flag("--all-pairs", rpe_options->all_pairs,
                "use every pair at the delta, not consecutive ones");
  rpe->callback([inputs, rpe_options] { runRpe(*inputs, *rpe_options); });
}

}  // namespace dcl::apps
