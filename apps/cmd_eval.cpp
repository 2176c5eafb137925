// `dcl-slam eval ate|rpe`: trajectory metrics with the evo toolbox's definitions.
#include <optional>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/eval/ate.hpp>
#include <dcl/eval/rpe.hpp>
#include <dcl/io/pose_file.hpp>

#include "commands.hpp"

namespace dcl::apps {

namespace {

/// What `eval ate` and `eval rpe` share: the two trajectories and how to pair them.
struct EvalInputs {
  std::string gt_path;
  std::string est_path;
  std::string format = "tum";
  std::string gt_times;
  std::string est_times;
  std::string alignment;
  double max_diff = 0.01;
  double offset = 0.0;
  bool json = false;
};

void addInputOptions(CLI::App& cmd, EvalInputs& in) {
  cmd.add_option("--gt", in.gt_path, "ground-truth trajectory file")->required();
  cmd.add_option("--est", in.est_path, "estimated trajectory file")->required();
  cmd.add_option("--format", in.format, "file format of both: kitti or tum")->capture_default_str();
  cmd.add_option("--gt-times", in.gt_times,
                 "times file of a KITTI ground truth (one stamp a line)");
  cmd.add_option("--est-times", in.est_times, "times file of a KITTI estimate");
  cmd.add_option("--align", in.alignment, "alignment of the estimate: none, se3 or sim3")
      ->capture_default_str();
  cmd.add_option("--max-diff", in.max_diff, "s, largest stamp difference to associate")
      ->capture_default_str();
  cmd.add_option("--offset", in.offset, "s, added to the estimate's stamps")->capture_default_str();
  cmd.add_flag("--json", in.json, "print the result as JSON");
}

std::optional<std::string> optionalPath(const std::string& path) {
  return path.empty() ? std::nullopt : std::optional<std::string>(path);
}

/// Loads both files and pairs their poses: KITTI files without times pair by
/// index (as evo's `kitti` mode), everything else by nearest stamp.
eval::Association loadPairs(const EvalInputs& in) {
  const io::PoseFormat format = io::parsePoseFormat(in.format);
  const core::Trajectory gt = io::readPoses(in.gt_path, format, optionalPath(in.gt_times));
  const core::Trajectory est = io::readPoses(in.est_path, format, optionalPath(in.est_times));
  eval::AssociationOptions options;
  const bool stamped =
      format == io::PoseFormat::tum || (!in.gt_times.empty() && !in.est_times.empty());
  options.mode = stamped ? eval::AssociationMode::timestamp : eval::AssociationMode::index;
  options.max_diff = in.max_diff;
  options.offset = in.offset;
  return eval::associate(est, gt, options);
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

void runAte(const EvalInputs& in) {
  const eval::Association pairs = loadPairs(in);
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
  const eval::RpeResult rpe = eval::computeRpe(loadPairs(in), options);
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
  auto* ate = eval->add_subcommand("ate", "absolute trajectory error (evo_ape)");
  addInputOptions(*ate, *inputs);
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
