#include "dcl/place/evaluation.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include <dcl/core/error.hpp>

namespace dcl::place {

namespace {

PrPoint makePoint(double threshold, std::size_t tp, std::size_t fp, std::size_t positives) {
  PrPoint p;
  p.threshold = threshold;
  p.true_positives = tp;
  p.false_positives = fp;
  p.precision = tp + fp > 0 ? static_cast<double>(tp) / static_cast<double>(tp + fp) : 1.0;
  p.recall = positives > 0 ? static_cast<double>(tp) / static_cast<double>(positives) : 0.0;
  return p;
}

double f1(const PrPoint& p) {
  const double sum = p.precision + p.recall;
  return sum > 0.0 ? 2.0 * p.precision * p.recall / sum : 0.0;
}

/// The recall before the first false positive and a threshold between the last
/// true positive and that false positive (so "distance below threshold" keeps it).
void fillFullPrecision(const std::vector<QueryOutcome>& sorted, PrCurve& curve) {
  std::optional<double> last_true;
  for (const QueryOutcome& o : sorted) {
    if (!o.true_loop) {
      if (last_true) curve.threshold_at_full_precision = 0.5 * (*last_true + o.distance);
      return;
    }
    last_true = o.distance;
  }
  if (last_true) curve.threshold_at_full_precision = *last_true + 1e-6;
}

}  // namespace

PrCurve computePrCurve(std::vector<QueryOutcome> outcomes) {
  // Ties sort the wrong candidates first: a threshold cannot separate equal distances.
  std::sort(outcomes.begin(), outcomes.end(), [](const QueryOutcome& a, const QueryOutcome& b) {
    return a.distance != b.distance ? a.distance < b.distance : a.true_loop < b.true_loop;
  });
  PrCurve curve;
  curve.queries = outcomes.size();
  for (const QueryOutcome& o : outcomes) curve.positives += o.has_revisit ? 1 : 0;
  std::size_t tp = 0, fp = 0;
  for (std::size_t i = 0; i < outcomes.size(); ++i) {
    (outcomes[i].true_loop ? tp : fp) += 1;
    const bool last_of_tie =
        i + 1 == outcomes.size() || outcomes[i + 1].distance != outcomes[i].distance;
    if (!last_of_tie) continue;
    curve.points.push_back(makePoint(outcomes[i].distance, tp, fp, curve.positives));
    if (fp == 0) curve.recall_at_full_precision = curve.points.back().recall;
    curve.max_f1 = std::max(curve.max_f1, f1(curve.points.back()));
  }
  fillFullPrecision(outcomes, curve);
  return curve;
}

bool LoopGroundTruth::isNear(std::size_t i, std::size_t j) const {
  if (i >= near.size()) return false;
  return std::binary_search(near[i].begin(), near[i].end(), j);
}

namespace {

/// Reads a text file line by line with its 1-based line number for errors.
class TextLines {
 public:
  explicit TextLines(const std::string& path) : path_(path), stream_(path) {
    if (!stream_) throw core::FileError({path_, {}, {}, {}}, "cannot open the file");
  }
  bool next() {
    ++number_;
    return static_cast<bool>(std::getline(stream_, line_));
  }
  [[nodiscard]] const std::string& line() const { return line_; }
  [[noreturn]] void fail(const std::string& what) const {
    throw core::FileError({path_, number_, {}, {}}, what);
  }

 private:
  std::string path_;
  std::ifstream stream_;
  std::string line_;
  std::size_t number_ = 0;
};

std::vector<std::string> tokens(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> out;
  for (std::string t; in >> t;) out.push_back(t);
  return out;
}

template <class T>
T parseToken(const TextLines& lines, const std::string& token) {
  T value{};
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (ec != std::errc() || ptr != token.data() + token.size()) {
    lines.fail("'" + token + "' is not a number");
  }
  return value;
}

/// A frame number of the authors' files (from 1) as an index from 0.
std::size_t parseFrame(const TextLines& lines, const std::string& token) {
  const auto frame = parseToken<std::size_t>(lines, token);
  if (frame == 0) lines.fail("frame 0: the LiDAR-Iris files number frames from 1");
  return frame - 1;
}

}  // namespace

LoopGroundTruth readLoopGroundTruth(const std::string& path) {
  TextLines lines(path);
  LoopGroundTruth gt;
  while (lines.next()) {
    const auto t = tokens(lines.line());
    if (t.size() < 2) continue;  // "0" and blank lines: no frame or no neighbour
    const std::size_t i = parseFrame(lines, t[0]);
    if (gt.near.size() <= i) gt.near.resize(i + 1);
    for (std::size_t k = 1; k < t.size(); ++k) gt.near[i].push_back(parseFrame(lines, t[k]));
    std::sort(gt.near[i].begin(), gt.near[i].end());
  }
  return gt;
}

std::vector<PublishedMatch> readPublishedMatches(const std::string& path) {
  TextLines lines(path);
  std::vector<PublishedMatch> out;
  while (lines.next()) {
    const auto t = tokens(lines.line());
    if (t.empty()) continue;
    if (t.size() != 4) lines.fail("expected 'query match score flag'");
    const auto flag = parseToken<int>(lines, t[3]);
    if (flag != 0 && flag != 1) lines.fail("flag '" + t[3] + "' is neither 0 nor 1");
    out.push_back({parseFrame(lines, t[0]), parseFrame(lines, t[1]),
                   parseToken<double>(lines, t[2]), flag == 1});
  }
  return out;
}

PrCurve evaluatePublished(const LoopGroundTruth& gt, const std::vector<PublishedMatch>& matches,
                          std::size_t min_gap) {
  std::vector<QueryOutcome> outcomes;
  outcomes.reserve(matches.size());
  for (const PublishedMatch& m : matches) {
    QueryOutcome o{m.distance, gt.isNear(m.query, m.match), false};
    if (m.query < gt.near.size()) {
      for (std::size_t j : gt.near[m.query]) o.has_revisit |= j + min_gap <= m.query;
    }
    outcomes.push_back(o);
  }
  return computePrCurve(std::move(outcomes));
}

namespace {

constexpr double kDegPerRad = 57.29577951308232;

double wrapAngle(double a) {
  return std::atan2(std::sin(a), std::cos(a));
}

double yawOf(const Eigen::Isometry3d& T) {
  return std::atan2(T.linear()(1, 0), T.linear()(0, 0));
}

/// The keyframes' per-robot indices, filled as the swarm's clock advances.
class Swarm {
 public:
  Swarm(std::shared_ptr<const Descriptor> descriptor, const PlaceIndexConfig& config)
      : descriptor_(std::move(descriptor)), config_(config) {}

  /// The index of `robot`, made on first use.
  PlaceIndex& index(core::RobotId robot) {
    auto it = indices_.find(robot);
    if (it == indices_.end())
      it = indices_.emplace(robot, PlaceIndex(descriptor_, robot, config_)).first;
    return it->second;
  }

  /// The closest candidate over every other robot's index.
  std::optional<PlaceCandidate> best(const EvaluationKeyframe& q) const {
    std::optional<PlaceCandidate> best;
    for (const auto& [robot, index] : indices_) {
      if (robot == q.key.robot) continue;
      const auto ranked = index.rank(*q.description);
      if (!ranked.empty() && (!best || ranked.front().match.distance < best->match.distance)) {
        best = ranked.front();
      }
    }
    return best;
  }

  [[nodiscard]] bool hasOthers(core::RobotId robot) const {
    for (const auto& [r, index] : indices_) {
      if (r != robot && index.size() > 0) return true;
    }
    return false;
  }

 private:
  std::shared_ptr<const Descriptor> descriptor_;
  PlaceIndexConfig config_;
  std::map<core::RobotId, PlaceIndex> indices_;
};

/// Whether an earlier keyframe of another robot lies within `radius` of `q`.
bool hasRevisit(const EvaluationKeyframe& q, const std::vector<const EvaluationKeyframe*>& seen,
                double radius) {
  for (const EvaluationKeyframe* k : seen) {
    if (k->key.robot == q.key.robot) continue;
    if ((k->T_world_keyframe.translation() - q.T_world_keyframe.translation()).norm() < radius) {
      return true;
    }
  }
  return false;
}

/// Fills the ground-truth verdict of `record`'s best candidate.
void judge(QueryRecord& record, const EvaluationKeyframe& q, const EvaluationKeyframe& match,
           double radius) {
  const Eigen::Isometry3d T_query_match = q.T_world_keyframe.inverse() * match.T_world_keyframe;
  record.ground_truth_distance = T_query_match.translation().norm();
  record.true_loop = record.ground_truth_distance < radius;
  record.heading_difference = std::abs(yawOf(T_query_match));
  record.yaw_error = wrapAngle(record.best->match.yaw_rad - yawOf(T_query_match));
}

void summarise(PlaceEvaluation& e, const EvaluationConfig& config) {
  double yaw_sum = 0.0, ms_sum = 0.0;
  const double threshold = e.curve.threshold_at_full_precision.value_or(-1.0);
  for (const QueryRecord& r : e.queries) {
    ms_sum += r.milliseconds;
    if (!r.true_loop) continue;
    ++e.true_loops;
    e.opposite_true_loops += r.heading_difference > config.opposite_heading ? 1 : 0;
    const double err = std::abs(r.yaw_error) * kDegPerRad;
    yaw_sum += err;
    e.yaw_error_max_deg = std::max(e.yaw_error_max_deg, err);
    e.yaw_within_2deg += err <= 2.0 ? 1 : 0;
    if (r.best->match.distance >= threshold) continue;
    (r.heading_difference > config.opposite_heading ? e.opposite_direction : e.same_direction) += 1;
  }
  if (e.true_loops > 0) e.yaw_error_mean_deg = yaw_sum / static_cast<double>(e.true_loops);
  if (!e.queries.empty()) e.query_ms_mean = ms_sum / static_cast<double>(e.queries.size());
}

}  // namespace

PlaceEvaluation evaluatePlaces(std::shared_ptr<const Descriptor> descriptor,
                               std::vector<EvaluationKeyframe> keyframes,
                               const EvaluationConfig& config) {
  std::stable_sort(keyframes.begin(), keyframes.end(),
                   [](const auto& a, const auto& b) { return a.stamp < b.stamp; });
  Swarm swarm(std::move(descriptor), config.index);
  std::map<core::PoseKey, const EvaluationKeyframe*> by_key;
  std::vector<const EvaluationKeyframe*> seen;
  PlaceEvaluation e;
  std::vector<QueryOutcome> outcomes;
  for (const EvaluationKeyframe& q : keyframes) {
    if (!q.description) throw core::Error("evaluatePlaces: keyframe without a description");
    if (swarm.hasOthers(q.key.robot)) {
      QueryRecord record;
      record.query = q.key;
      const auto start = std::chrono::steady_clock::now();
      record.best = swarm.best(q);
      record.milliseconds =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
              .count();
      record.has_revisit = hasRevisit(q, seen, config.true_loop_distance);
      if (record.best) {
        judge(record, q, *by_key.at(record.best->keyframe), config.true_loop_distance);
        outcomes.push_back({record.best->match.distance, record.true_loop, record.has_revisit});
      }
      e.queries.push_back(record);
    }
    swarm.index(q.key.robot).add(q.key.keyframe, q.description);
    by_key[q.key] = &q;
    seen.push_back(&q);
  }
  e.curve = computePrCurve(std::move(outcomes));
  summarise(e, config);
  return e;
}

}  // namespace dcl::place
