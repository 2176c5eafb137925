#pragma once

/// Pose graphs in g2o text (`VERTEX_SE3:QUAT`, `EDGE_SE3:QUAT`, `VERTEX_SE2`,
/// `EDGE_SE2`, `FIX`) and in TORO text (`VERTEX2`, `EDGE2`, `VERTEX3`, `EDGE3`,
/// `EQUIV`), read into one plain struct; written back as g2o.
///
/// The tag decides the format, not the file name. '#' comments and blank lines
/// are skipped. Every 2D graph is lifted to SE(3) (z = 0, roll = pitch = 0) and
/// remembers that it was 2D, so that it writes back as 2D.
///
/// Information matrices are 6x6 in the project's tangent order [translation;
/// rotation], the order of g2o's EDGE_SE3:QUAT. They are kept exactly as read
/// (upper triangle mirrored): writing a graph back prints the same doubles.
/// Each, as read (the 3x3 of a planar edge before it is lifted), must be
/// positive semi-definite (no eigenvalue below -1e-4 times the largest
/// magnitude, the rounding of printed digits) and not zero: a negative
/// direction makes the cost reward error, a zero matrix measures nothing.
/// Semi-definite is enough: planar graphs leave directions free on purpose.
/// - EDGE_SE2 / EDGE2 (3x3 over x, y, theta) go to rows/columns (0, 1, 5). The
///   z, roll and pitch diagonal, which a 2D measurement says nothing about, gets
///   the largest diagonal entry of the 3x3 block (1 if that is not positive): as
///   stiff as the stiffest measured direction, which keeps a 3D solver's graph
///   planar without making the problem worse conditioned than the 2D one.
/// - EDGE2 lists its entries in TORO's order (xx, xy, yy, tt, xt, yt), EDGE_SE2
///   in g2o's upper-triangular order (xx, xy, xt, yy, yt, tt).
/// - EDGE3 (x y z roll pitch yaw, R = Rz(yaw) Ry(pitch) Rx(roll)) lists the upper
///   triangle of its 6x6 over (x, y, z, roll, pitch, yaw); it is kept as is, so
///   its rotation block is over Euler-angle increments, which agree with the
///   tangent to first order at small angles. An EDGE3 without information
///   entries (as in TORO's sphere files) gets the identity.
///
/// Vertex ids may be GTSAM symbols (core::PoseKey: robot character in the top
/// byte), as in the multi-robot graphs of distributed-mapper or Kimera-Multi;
/// see vertexKey, robotsOf and isInterRobot.

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <dcl/core/ids.hpp>
#include <dcl/core/se3.hpp>

namespace dcl::io {

/// One relative pose measurement between two vertices.
struct G2oEdge {
  std::uint64_t from = 0;  ///< id of the vertex the measurement is expressed in
  std::uint64_t to = 0;    ///< id of the measured vertex
  /// The pose of `to` in the frame of `from`.
  Eigen::Isometry3d T_from_to = Eigen::Isometry3d::Identity();
  /// Inverse covariance over the tangent [translation; rotation], symmetric.
  core::Matrix6d information = core::Matrix6d::Identity();
  std::size_t line = 0;  ///< the line it was read from (1-based); 0 when not read from a file
};

/// A pose graph as a file holds it.
struct G2oGraph {
  /// Initial estimates T_world_vertex by id. In a multi-robot graph split per
  /// robot, edges may name vertices held by another robot's file: an edge's end
  /// need not be a vertex here.
  std::map<std::uint64_t, Eigen::Isometry3d> vertices{};
  std::vector<G2oEdge> edges{};     ///< in file order
  std::set<std::uint64_t> fixed{};  ///< ids of `FIX` lines
  /// TORO `EQUIV a b` lines: vertices that are the same place.
  std::vector<std::pair<std::uint64_t, std::uint64_t>> equivalences{};
  bool is_2d = false;  ///< read from planar tags (and written back as planar)
  /// True when the file had no vertex lines and the vertices were made by
  /// chainInitialPoses.
  bool chained = false;
  /// Lines skipped because of G2oReadOptions::skip_unknown_tags (1-based).
  std::vector<std::size_t> skipped_lines{};
  /// The line each vertex was read from (1-based), by id; chained vertices have none.
  std::map<std::uint64_t, std::size_t> vertex_lines{};

  /// True when `id` is a vertex of this graph.
  [[nodiscard]] bool hasVertex(std::uint64_t id) const { return vertices.contains(id); }
};

/// How strict readG2o is.
struct G2oReadOptions {
  /// Skip lines whose tag is unknown (recording them in G2oGraph::skipped_lines)
  /// instead of failing. Lines with a known tag must still be well formed.
  bool skip_unknown_tags = false;  // default: an unknown tag is an error
  /// Make initial poses by chaining odometry when the file has edges but no vertices.
  bool chain_missing_vertices = true;  // default: on
};

/// Reads a g2o or TORO pose graph. Throws core::FileError naming the file, the
/// line, the field and what was wrong: unknown tag, wrong number of fields,
/// non-number, NaN or infinity, quaternion norm not within 1e-2 of 1, an
/// information matrix that is zero or not positive semi-definite, repeated
/// vertex id, 2D and 3D tags mixed, or a file with neither vertices nor edges.
/// An edge may name a vertex the file does not define (a per-robot file of a
/// split graph names its neighbours'); whoever reads a whole graph checks that.
G2oGraph readG2o(const std::string& path, const G2oReadOptions& options = {});

/// Writes `graph` as g2o text (VERTEX_SE2/EDGE_SE2 when `is_2d`, else
/// VERTEX_SE3:QUAT/EDGE_SE3:QUAT; then FIX and EQUIV lines) with full round-trip
/// precision, atomically. Vertices are written even when they were chained.
void writeG2o(const std::string& path, const G2oGraph& graph);

/// Fills `graph.vertices` for a graph read without vertex lines, by composing
/// odometry edges. The ids named by edges are visited in increasing order; the
/// first is placed at the identity, and each next id by the edge between it and
/// the id before it (either direction), else by any edge to an already placed
/// vertex (a loop closure), else -- a gap in odometry, the start of another
/// component -- at the pose of the id before it. Existing vertices are kept;
/// sets `graph.chained`.
void chainInitialPoses(G2oGraph& graph);

/// The robot and keyframe of a vertex id, when it is a GTSAM symbol with a lower
/// case robot character ('a' + robot); none for a plain integer id.
std::optional<core::PoseKey> vertexKey(std::uint64_t id);

/// True when both ends are symbols of different robots (compares the top bytes).
bool isInterRobot(const G2oEdge& edge);

/// The robots that own the graph's vertices and edge ends, from symbol ids (empty
/// when the ids are plain integers).
std::set<core::RobotId> robotsOf(const G2oGraph& graph);

/// The edges joining two different robots, in file order.
std::vector<G2oEdge> interRobotEdges(const G2oGraph& graph);

}  // namespace dcl::io
