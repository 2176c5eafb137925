#pragma once

/// Place-recognition evaluation as the paper does it (§IV "Performance of
/// Distributed Loop Closure"): every keyframe queries the other robots'
/// history; its closest candidate is a successful loop when the ground-truth
/// distance between the two keyframes is below 4 m (Scan Context's criterion);
/// precision and recall are swept over the match-distance threshold.
///
/// Also the readers of the LiDAR-Iris authors' published KITTI files, so that
/// the published method's recall at 100 % precision is always shown beside ours:
/// - `gtNN.txt`: line `i j1 j2 ...` lists the frames j within 4 m of frame i in
///   the ground plane (x, z of KITTI's camera frame). Frames are numbered from 1
///   (MATLAB): the listed pairs are all within 4.0 m with that numbering and up
///   to 8 m with numbering from 0. Temporal neighbours are included.
/// - `lidar_iris_result_NN.txt`: line `query match score flag`, numbered from 1
///   too; `score` is the masked Hamming distance of the best match among the
///   frames at least 300 older than the query; `flag` is 1 exactly when the
///   match is listed for the query in `gtNN.txt`.

#include <Eigen/Geometry>
#include <cstddef>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <dcl/core/ids.hpp>
#include <dcl/place/descriptor.hpp>
#include <dcl/place/place_index.hpp>

namespace dcl::place {

/// One query's closest candidate, as the precision-recall sweep sees it.
struct QueryOutcome {
  double distance = 0.0;     ///< match distance of the closest candidate (lower: more alike)
  bool true_loop = false;    ///< the candidate is a real revisit (ground truth within 4 m)
  bool has_revisit = false;  ///< some real revisit of the query was in the database
};

/// One point of a precision-recall curve: everything with distance <= threshold reported.
struct PrPoint {
  double threshold = 0.0;           ///< largest reported distance
  double precision = 1.0;           ///< true / reported (1 when nothing is reported)
  double recall = 0.0;              ///< true / queries with a revisit
  std::size_t true_positives = 0;   ///< reported and real
  std::size_t false_positives = 0;  ///< reported and wrong
};

/// A precision-recall curve over the match-distance threshold.
struct PrCurve {
  std::vector<PrPoint> points;  ///< one per distinct distance, ascending threshold
  std::size_t queries = 0;      ///< queries that had a candidate
  std::size_t positives = 0;    ///< queries with a revisit in the database (recall's denominator)
  double recall_at_full_precision = 0.0;  ///< the largest recall with no false positive
  /// A threshold giving it with the index's "distance below threshold" rule: halfway
  /// between the last true positive kept and the first false positive; none when
  /// the closest candidate of all is already wrong.
  std::optional<double> threshold_at_full_precision;
  double max_f1 = 0.0;  ///< the best F1 score along the curve
};

/// The precision-recall curve of `outcomes` (the order does not matter).
PrCurve computePrCurve(std::vector<QueryOutcome> outcomes);

/// The LiDAR-Iris loop ground truth of one KITTI sequence (`gtNN.txt`).
struct LoopGroundTruth {
  /// near[i]: the frames within 4 m of frame i, numbered from 0, ascending.
  std::vector<std::vector<std::size_t>> near;

  /// True when frame `j` is listed as within 4 m of frame `i`.
  [[nodiscard]] bool isNear(std::size_t i, std::size_t j) const;
};

/// Reads `gtNN.txt` (frames numbered from 1 in the file, from 0 in the result).
/// Throws core::FileError naming the line for a malformed line or frame 0.
LoopGroundTruth readLoopGroundTruth(const std::string& path);

/// One line of the published LiDAR-Iris result (`lidar_iris_result_NN.txt`).
struct PublishedMatch {
  std::size_t query = 0;  ///< frame, numbered from 0
  std::size_t match = 0;  ///< the best match's frame, numbered from 0
  double distance = 0.0;  ///< its masked Hamming distance
  bool flag = false;      ///< the authors' verdict: the match is a true loop
};

/// Reads a published result file (frames numbered from 1 in the file, from 0 in
/// the result). Throws core::FileError naming the line for a malformed line.
std::vector<PublishedMatch> readPublishedMatches(const std::string& path);

/// The published method's curve: each line is one query; it is a true loop when
/// `gt` lists the match for the query (which is the authors' flag); the query
/// has a revisit when `gt` lists any frame at least `min_gap` older (the
/// authors' database is every frame 300 or more older than the query).
PrCurve evaluatePublished(const LoopGroundTruth& gt, const std::vector<PublishedMatch>& matches,
                          std::size_t min_gap = 300);

/// How the inter-robot evaluation judges and searches.
struct EvaluationConfig {
  /// m, a candidate is a true loop when the keyframes are closer than this
  /// (the paper, after Scan Context: 4 m).
  double true_loop_distance = 4.0;
  /// rad, heading difference above which a true loop counts as a revisit in the
  /// opposite driving direction (90 degrees).
  double opposite_heading = 1.5707963267948966;
  /// The per-robot indices; max_distance is not used (the curve sweeps it).
  PlaceIndexConfig index{};

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("true_loop_distance", true_loop_distance,
            "m, ground-truth distance of a true loop (paper: 4)")
        .positive();
    v.field("opposite_heading", opposite_heading,
            "rad, heading change of an opposite-direction revisit")
        .within(0.0, std::numbers::pi);
    v.section("index", index, "the place index searched");
  }
};

/// One keyframe to evaluate: who took it, when, where (ground truth), and its description.
struct EvaluationKeyframe {
  core::PoseKey key;   ///< robot and keyframe
  double stamp = 0.0;  ///< s since the robot's start
  Eigen::Isometry3d T_world_keyframe = Eigen::Isometry3d::Identity();  ///< ground truth
  std::shared_ptr<const PlaceDescriptor> description;  ///< made by the evaluated descriptor
};

/// What one keyframe's query found among the other robots' earlier keyframes.
struct QueryRecord {
  core::PoseKey query;                 ///< the querying keyframe
  std::optional<PlaceCandidate> best;  ///< the closest candidate of all other robots
  bool has_revisit = false;            ///< an earlier keyframe of another robot is within reach
  bool true_loop = false;              ///< the best candidate is within true_loop_distance
  double ground_truth_distance = 0.0;  ///< m, between the query and the best candidate
  double heading_difference = 0.0;     ///< rad, |yaw| of the ground-truth T_query_candidate
  double yaw_error = 0.0;              ///< rad, matched yaw minus ground-truth yaw, wrapped
  double milliseconds = 0.0;           ///< the query's search time over all indices
};

/// The inter-robot evaluation of one descriptor on one dataset.
struct PlaceEvaluation {
  PrCurve curve;                       ///< over the match distance
  std::vector<QueryRecord> queries;    ///< one per keyframe that had another robot's history
  std::size_t same_direction = 0;      ///< true loops kept at 100 % precision, same direction
  std::size_t opposite_direction = 0;  ///< ... in the opposite direction
  std::size_t true_loops = 0;  ///< queries whose best candidate is a true loop (any distance)
  std::size_t opposite_true_loops = 0;  ///< of those, revisits in the opposite direction
  double yaw_error_mean_deg = 0.0;      ///< mean |yaw error| over all true loops
  double yaw_error_max_deg = 0.0;       ///< largest |yaw error| over all true loops
  std::size_t yaw_within_2deg = 0;      ///< true loops with |yaw error| within 2 degrees
  double query_ms_mean = 0.0;           ///< mean search time of a query
};

/// The paper's inter-robot protocol, all robots starting together: keyframes are
/// taken in stamp order; each queries every other robot's index (holding that
/// robot's keyframes up to now) and keeps the closest candidate; then it joins
/// its own robot's index. Throws core::Error when a description is missing.
PlaceEvaluation evaluatePlaces(std::shared_ptr<const Descriptor> descriptor,
                               std::vector<EvaluationKeyframe> keyframes,
                               const EvaluationConfig& config = {});

}  // namespace dcl::place
