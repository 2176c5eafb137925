#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <iterator>
#include <ostream>
#include <string_view>
#include <unordered_map>

#include <dcl/core/error.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/g2o.hpp>

namespace dcl::io {
namespace {

using core::FileError;
using core::FileLocation;
using Tokens = std::vector<std::string_view>;
using Index = Eigen::Index;
using Entry = std::pair<int, int>;

/// How negative an information eigenvalue may be, relative to the largest
/// magnitude, and still be the rounding of a printed semi-definite matrix (six
/// significant digits move an eigenvalue of a 6x6 by up to about 3e-5 of it).
constexpr double kIndefiniteTolerance = 1e-4;

/// Rows/columns of x, y, yaw in the 6x6 tangent [x y z; roll pitch yaw].
constexpr std::array<Index, 3> kPlanarAxes = {0, 1, 5};
/// Rows/columns of z, roll, pitch: what a planar measurement says nothing about.
constexpr std::array<Index, 3> kOffPlaneAxes = {2, 3, 4};

/// g2o's upper-triangular order of a 3x3 information (xx xy xt yy yt tt).
constexpr std::array<Entry, 6> kG2oOrder3 = {{{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}}};
/// TORO's order of EDGE2's information (xx xy yy tt xt yt).
constexpr std::array<Entry, 6> kToroOrder3 = {{{0, 0}, {0, 1}, {1, 1}, {2, 2}, {0, 2}, {1, 2}}};

constexpr std::array<Entry, 21> upperTriangle6() {
  std::array<Entry, 21> order{};
  std::size_t k = 0;
  for (int r = 0; r < 6; ++r) {
    for (int c = r; c < 6; ++c) order[k++] = {r, c};
  }
  return order;
}
constexpr std::array<Entry, 21> kOrder6 = upperTriangle6();

std::string infoName(const Entry& e) {
  // Appended piece by piece: GCC 12 warns (falsely) on `"I" + std::to_string(...)`.
  return std::string("I").append(std::to_string(e.first + 1)).append(std::to_string(e.second + 1));
}

/// Reads one graph file line by line into a G2oGraph.
class Parser {
 public:
  Parser(const std::string& path, const G2oReadOptions& options) : in_(path), options_(options) {}

  G2oGraph run();

 private:
  using Handler = void (Parser::*)(const Tokens&);

  static const std::unordered_map<std::string_view, Handler>& handlers();
  void parseLine(const Tokens& tokens);
  void vertexSe3(const Tokens& t);
  void edgeSe3(const Tokens& t);
  void vertexSe2(const Tokens& t);
  void edgeSe2(const Tokens& t);
  void edge2(const Tokens& t);
  void vertex3(const Tokens& t);
  void edge3(const Tokens& t);
  void fix(const Tokens& t);
  void equiv(const Tokens& t);

  void expectFields(const Tokens& t, std::size_t numbers, const char* layout) const;
  void setDimension(bool planar);
  [[nodiscard]] std::uint64_t id(std::string_view token, const char* field) const;
  [[nodiscard]] double number(std::string_view token, const std::string& field) const;
  [[nodiscard]] Eigen::Quaterniond quaternion(const Tokens& t, std::size_t first) const;
  [[nodiscard]] Eigen::Vector3d vector3(const Tokens& t, std::size_t first,
                                        std::array<const char*, 3> names) const;
  template <int N, std::size_t K>
  [[nodiscard]] Eigen::Matrix<double, N, N> readInformation(
      const Tokens& t, std::size_t first, const std::array<Entry, K>& order) const;
  template <int N>
  void checkInformation(const Eigen::Matrix<double, N, N>& info) const;
  void addVertex(std::uint64_t vertex, const Eigen::Isometry3d& T_world_vertex);
  void addEdge(std::uint64_t from, std::uint64_t to, const Eigen::Isometry3d& T_from_to,
               const core::Matrix6d& information);
  [[noreturn]] void failUnknownTag(std::string_view tag) const;

  LineReader in_;
  G2oReadOptions options_;
  G2oGraph graph_;
  std::optional<bool> planar_;
  std::size_t dimension_line_ = 0;
};

G2oGraph Parser::run() {
  while (in_.next()) {
    const Tokens tokens = splitWhitespace(in_.line());
    if (!tokens.empty() && tokens.front().front() != '#') parseLine(tokens);
  }
  if (graph_.vertices.empty() && graph_.edges.empty()) {
    throw FileError(FileLocation{in_.path(), in_.lineNumber() + 1},
                    "no vertices or edges (empty file?)");
  }
  graph_.is_2d = planar_.value_or(false);
  if (graph_.vertices.empty() && options_.chain_missing_vertices) chainInitialPoses(graph_);
  return std::move(graph_);
}

void Parser::parseLine(const Tokens& tokens) {
  const auto it = handlers().find(tokens.front());
  if (it != handlers().end()) return (this->*(it->second))(tokens);
  if (!options_.skip_unknown_tags) failUnknownTag(tokens.front());
  graph_.skipped_lines.push_back(in_.lineNumber());
}

void Parser::failUnknownTag(std::string_view tag) const {
  in_.fail("unknown tag '" + std::string(tag) +
               "' (expected VERTEX_SE3:QUAT, EDGE_SE3:QUAT, VERTEX_SE2, EDGE_SE2, VERTEX2, "
               "EDGE2, VERTEX3, EDGE3, FIX or EQUIV)",
           "tag");
}

void Parser::expectFields(const Tokens& t, std::size_t numbers, const char* layout) const {
  const std::size_t found = t.size() - 1;
  if (found == numbers) return;
  in_.fail(std::string(t.front()) + " needs " + std::to_string(numbers) + " fields (" + layout +
           "), found " + std::to_string(found));
}

void Parser::setDimension(bool planar) {
  if (!planar_) {
    planar_ = planar;
    dimension_line_ = in_.lineNumber();
  } else if (*planar_ != planar) {
    in_.fail(std::string("mixes 2D and 3D: this line is ") + (planar ? "2D" : "3D") + ", line " +
             std::to_string(dimension_line_) + " was " + (planar ? "3D" : "2D"));
  }
}

std::uint64_t Parser::id(std::string_view token, const char* field) const {
  if (auto value = parseNumber<std::uint64_t>(token)) return *value;
  in_.fail("'" + std::string(token) + "' is not a vertex id (a non-negative integer)", field);
}

double Parser::number(std::string_view token, const std::string& field) const {
  const double value = in_.number<double>(token, field.c_str());
  if (!std::isfinite(value)) in_.fail("'" + std::string(token) + "' is not finite", field);
  return value;
}

Eigen::Vector3d Parser::vector3(const Tokens& t, std::size_t first,
                                std::array<const char*, 3> names) const {
  return {number(t[first], names[0]), number(t[first + 1], names[1]),
          number(t[first + 2], names[2])};
}

Eigen::Quaterniond Parser::quaternion(const Tokens& t, std::size_t first) const {
  const Eigen::Vector3d xyz = vector3(t, first, {"qx", "qy", "qz"});
  const Eigen::Quaterniond q(number(t[first + 3], "qw"), xyz.x(), xyz.y(), xyz.z());
  const double norm = q.norm();
  if (std::abs(norm - 1.0) > kQuaternionTolerance) {
    in_.fail("quaternion norm " + exactText(norm) + " is not 1 (corrupt line?)");
  }
  return q;
}

/// The symmetric information matrix of an edge from its upper triangle, checked.
template <int N, std::size_t K>
Eigen::Matrix<double, N, N> Parser::readInformation(const Tokens& t, std::size_t first,
                                                    const std::array<Entry, K>& order) const {
  Eigen::Matrix<double, N, N> M = Eigen::Matrix<double, N, N>::Zero();
  for (std::size_t k = 0; k < K; ++k) {
    const auto [r, c] = order[k];
    M(r, c) = M(c, r) = number(t[first + k], infoName(order[k]));
  }
  checkInformation(M);
  return M;
}

/// A cost r^T Omega r means something only for a positive semi-definite Omega
/// (a negative direction rewards error); a zero one measures nothing. Only
/// semi-definite is asked: planar graphs say nothing about some directions on
/// purpose, and the solvers read those as unconstrained.
template <int N>
void Parser::checkInformation(const Eigen::Matrix<double, N, N>& info) const {
  if (info.isZero(0.0))
    in_.fail("information matrix is zero (the edge measures nothing)", "information");
  using Solver = Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>>;
  const auto eigenvalues = Solver(info, Eigen::EigenvaluesOnly).eigenvalues();
  const double smallest = eigenvalues.minCoeff();
  const double largest = eigenvalues.cwiseAbs().maxCoeff();
  if (smallest >= -kIndefiniteTolerance * largest) return;
  in_.fail("information matrix is not positive semi-definite (eigenvalue " + exactText(smallest) +
               ", largest magnitude " + exactText(largest) + ")",
           "information");
}

/// A 3x3 information over (x, y, theta) placed in the 6x6 tangent order.
core::Matrix6d liftPlanarInformation(const Eigen::Matrix3d& info) {
  core::Matrix6d lifted = core::Matrix6d::Zero();
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) lifted(kPlanarAxes[r], kPlanarAxes[c]) = info(r, c);
  }
  const double stiffest = info.diagonal().maxCoeff();
  for (const Index axis : kOffPlaneAxes) lifted(axis, axis) = stiffest > 0.0 ? stiffest : 1.0;
  return lifted;
}

/// R = Rz(yaw) Ry(pitch) Rx(roll), TORO's and GTSAM's convention for VERTEX3/EDGE3.
Eigen::Isometry3d poseFromEuler(const Eigen::Vector3d& t, const Eigen::Vector3d& rpy) {
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  return core::makePose(t, R);
}

void Parser::addVertex(std::uint64_t vertex, const Eigen::Isometry3d& T_world_vertex) {
  if (!graph_.vertices.emplace(vertex, T_world_vertex).second) {
    in_.fail("vertex " + std::to_string(vertex) + " is defined twice", "id");
  }
  graph_.vertex_lines.emplace(vertex, in_.lineNumber());
}

void Parser::addEdge(std::uint64_t from, std::uint64_t to, const Eigen::Isometry3d& T_from_to,
                     const core::Matrix6d& information) {
  if (from == to) in_.fail("edge joins vertex " + std::to_string(from) + " to itself", "to");
  graph_.edges.push_back({from, to, T_from_to, information, in_.lineNumber()});
}

void Parser::vertexSe3(const Tokens& t) {
  expectFields(t, 8, "id x y z qx qy qz qw");
  setDimension(false);
  const std::uint64_t vertex = id(t[1], "id");
  addVertex(vertex, core::makePose(vector3(t, 2, {"x", "y", "z"}), quaternion(t, 5)));
}

void Parser::edgeSe3(const Tokens& t) {
  expectFields(t, 30, "from to x y z qx qy qz qw and 21 information entries");
  setDimension(false);
  const std::uint64_t from = id(t[1], "from");
  const std::uint64_t to = id(t[2], "to");
  const auto T = core::makePose(vector3(t, 3, {"x", "y", "z"}), quaternion(t, 6));
  addEdge(from, to, T, readInformation<6>(t, 10, kOrder6));
}

void Parser::vertexSe2(const Tokens& t) {
  expectFields(t, 4, "id x y theta");
  setDimension(true);
  const std::uint64_t vertex = id(t[1], "id");
  const Eigen::Vector3d v = vector3(t, 2, {"x", "y", "theta"});
  addVertex(vertex, core::makePose2d(v.x(), v.y(), v.z()));
}

void Parser::edgeSe2(const Tokens& t) {
  expectFields(t, 11, "from to dx dy dtheta and 6 information entries");
  setDimension(true);
  const std::uint64_t from = id(t[1], "from");
  const std::uint64_t to = id(t[2], "to");
  const Eigen::Vector3d d = vector3(t, 3, {"dx", "dy", "dtheta"});
  const Eigen::Matrix3d info = readInformation<3>(t, 6, kG2oOrder3);
  addEdge(from, to, core::makePose2d(d.x(), d.y(), d.z()), liftPlanarInformation(info));
}

void Parser::edge2(const Tokens& t) {
  expectFields(t, 11, "from to dx dy dtheta and 6 information entries in TORO order");
  setDimension(true);
  const std::uint64_t from = id(t[1], "from");
  const std::uint64_t to = id(t[2], "to");
  const Eigen::Vector3d d = vector3(t, 3, {"dx", "dy", "dtheta"});
  const Eigen::Matrix3d info = readInformation<3>(t, 6, kToroOrder3);
  addEdge(from, to, core::makePose2d(d.x(), d.y(), d.z()), liftPlanarInformation(info));
}

void Parser::vertex3(const Tokens& t) {
  expectFields(t, 7, "id x y z roll pitch yaw");
  setDimension(false);
  const std::uint64_t vertex = id(t[1], "id");
  addVertex(vertex,
            poseFromEuler(vector3(t, 2, {"x", "y", "z"}), vector3(t, 5, {"roll", "pitch", "yaw"})));
}

void Parser::edge3(const Tokens& t) {
  if (t.size() != 9 && t.size() != 30) {
    in_.fail(
        "EDGE3 needs 8 fields (from to x y z roll pitch yaw) or 29 (and 21 information "
        "entries), found " +
        std::to_string(t.size() - 1));
  }
  setDimension(false);
  const std::uint64_t from = id(t[1], "from");
  const std::uint64_t to = id(t[2], "to");
  const auto T =
      poseFromEuler(vector3(t, 3, {"x", "y", "z"}), vector3(t, 6, {"roll", "pitch", "yaw"}));
  const core::Matrix6d info =
      t.size() == 9 ? core::Matrix6d::Identity() : readInformation<6>(t, 9, kOrder6);
  addEdge(from, to, T, info);
}

void Parser::fix(const Tokens& t) {
  expectFields(t, 1, "id");
  graph_.fixed.insert(id(t[1], "id"));
}

void Parser::equiv(const Tokens& t) {
  expectFields(t, 2, "id1 id2");
  graph_.equivalences.emplace_back(id(t[1], "id1"), id(t[2], "id2"));
}

const std::unordered_map<std::string_view, Parser::Handler>& Parser::handlers() {
  static const std::unordered_map<std::string_view, Handler> table = {
      {"VERTEX_SE3:QUAT", &Parser::vertexSe3},
      {"EDGE_SE3:QUAT", &Parser::edgeSe3},
      {"VERTEX_SE2", &Parser::vertexSe2},
      {"EDGE_SE2", &Parser::edgeSe2},
      {"VERTEX2", &Parser::vertexSe2},
      {"EDGE2", &Parser::edge2},
      {"VERTEX3", &Parser::vertex3},
      {"EDGE3", &Parser::edge3},
      {"FIX", &Parser::fix},
      {"EQUIV", &Parser::equiv}};
  return table;
}

// ---- chaining -------------------------------------------------------------

using Adjacency = std::unordered_map<std::uint64_t, std::vector<std::size_t>>;

std::vector<std::uint64_t> edgeEnds(const G2oGraph& graph) {
  std::vector<std::uint64_t> ids;
  ids.reserve(2 * graph.edges.size());
  for (const auto& e : graph.edges) {
    ids.push_back(e.from);
    ids.push_back(e.to);
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  return ids;
}

Adjacency adjacencyOf(const G2oGraph& graph) {
  Adjacency adjacency;
  for (std::size_t i = 0; i < graph.edges.size(); ++i) {
    adjacency[graph.edges[i].from].push_back(i);
    adjacency[graph.edges[i].to].push_back(i);
  }
  return adjacency;
}

/// The pose of `vertex` from `edge` when the edge's other end is placed.
std::optional<Eigen::Isometry3d> poseVia(const G2oGraph& graph, const G2oEdge& edge,
                                         std::uint64_t vertex) {
  const std::uint64_t other = edge.from == vertex ? edge.to : edge.from;
  const auto it = graph.vertices.find(other);
  if (it == graph.vertices.end()) return std::nullopt;
  return edge.from == other ? it->second * edge.T_from_to : it->second * edge.T_from_to.inverse();
}

/// The pose of `vertex` through the first edge joining it to `neighbour` (any placed
/// neighbour when none is given).
std::optional<Eigen::Isometry3d> poseFromNeighbour(const G2oGraph& graph,
                                                   const std::vector<std::size_t>& incident,
                                                   std::uint64_t vertex,
                                                   std::optional<std::uint64_t> neighbour) {
  for (const std::size_t i : incident) {
    const G2oEdge& e = graph.edges[i];
    const std::uint64_t other = e.from == vertex ? e.to : e.from;
    if (neighbour && other != *neighbour) continue;
    if (auto T = poseVia(graph, e, vertex)) return T;
  }
  return std::nullopt;
}

Eigen::Isometry3d placeVertex(const G2oGraph& graph, const Adjacency& adjacency,
                              const std::vector<std::uint64_t>& ids, std::size_t k) {
  if (k == 0) return Eigen::Isometry3d::Identity();
  const auto& incident = adjacency.at(ids[k]);
  if (auto T = poseFromNeighbour(graph, incident, ids[k], ids[k - 1])) return *T;
  if (auto T = poseFromNeighbour(graph, incident, ids[k], std::nullopt)) return *T;
  return graph.vertices.at(ids[k - 1]);
}

// ---- writing --------------------------------------------------------------

void writeNumbers(std::ostream& out, std::initializer_list<double> values) {
  for (const double v : values) out << ' ' << exactText(v);
}

Eigen::Quaterniond quaternionOf(const Eigen::Isometry3d& T) {
  Eigen::Quaterniond q(T.linear());
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  return q;
}

void writePose3(std::ostream& out, const Eigen::Isometry3d& T) {
  const Eigen::Vector3d& p = T.translation();
  const Eigen::Quaterniond q = quaternionOf(T);
  writeNumbers(out, {p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w()});
}

void writePose2(std::ostream& out, const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d& R = T.linear();
  writeNumbers(out, {T.translation().x(), T.translation().y(), std::atan2(R(1, 0), R(0, 0))});
}

template <std::size_t K>
void writeInformation(std::ostream& out, const core::Matrix6d& info,
                      const std::array<Entry, K>& order, bool planar) {
  for (const auto& [r, c] : order) {
    const Index row = planar ? kPlanarAxes[static_cast<std::size_t>(r)] : r;
    const Index col = planar ? kPlanarAxes[static_cast<std::size_t>(c)] : c;
    out << ' ' << exactText(info(row, col));
  }
}

void writeVertex(std::ostream& out, std::uint64_t vertex, const Eigen::Isometry3d& T, bool planar) {
  out << (planar ? "VERTEX_SE2 " : "VERTEX_SE3:QUAT ") << vertex;
  planar ? writePose2(out, T) : writePose3(out, T);
  out << '\n';
}

void writeEdge(std::ostream& out, const G2oEdge& e, bool planar) {
  out << (planar ? "EDGE_SE2 " : "EDGE_SE3:QUAT ") << e.from << ' ' << e.to;
  if (planar) {
    writePose2(out, e.T_from_to);
    writeInformation(out, e.information, kG2oOrder3, true);
  } else {
    writePose3(out, e.T_from_to);
    writeInformation(out, e.information, kOrder6, false);
  }
  out << '\n';
}

void writeGraph(std::ostream& out, const G2oGraph& graph) {
  for (const auto& [vertex, T] : graph.vertices) writeVertex(out, vertex, T, graph.is_2d);
  for (const auto& e : graph.edges) writeEdge(out, e, graph.is_2d);
  for (const std::uint64_t vertex : graph.fixed) out << "FIX " << vertex << '\n';
  for (const auto& [a, b] : graph.equivalences) out << "EQUIV " << a << ' ' << b << '\n';
}

std::uint8_t topByte(std::uint64_t id) {
  return static_cast<std::uint8_t>(id >> core::PoseKey::kIndexBits);
}

void insertRobot(std::set<core::RobotId>& robots, std::uint64_t id) {
  if (auto key = vertexKey(id)) robots.insert(key->robot);
}

}  // namespace

G2oGraph readG2o(const std::string& path, const G2oReadOptions& options) {
  return Parser(path, options).run();
}

void writeG2o(const std::string& path, const G2oGraph& graph) {
  writeFileAtomic(path, [&](std::ostream& out) { writeGraph(out, graph); });
}

void chainInitialPoses(G2oGraph& graph) {
  const std::vector<std::uint64_t> ids = edgeEnds(graph);
  const Adjacency adjacency = adjacencyOf(graph);
  for (std::size_t k = 0; k < ids.size(); ++k) {
    if (!graph.hasVertex(ids[k])) graph.vertices[ids[k]] = placeVertex(graph, adjacency, ids, k);
  }
  graph.chained = true;
}

std::optional<core::PoseKey> vertexKey(std::uint64_t id) {
  const std::uint8_t c = topByte(id);
  if (c < 'a') return std::nullopt;  // robots past 'z' pack on the bytes above it
  return core::PoseKey::unpack(id);
}

bool isInterRobot(const G2oEdge& edge) {
  return core::PoseKey::isSymbol(edge.from) && core::PoseKey::isSymbol(edge.to) &&
         topByte(edge.from) != topByte(edge.to);
}

std::set<core::RobotId> robotsOf(const G2oGraph& graph) {
  std::set<core::RobotId> robots;
  for (const auto& entry : graph.vertices) insertRobot(robots, entry.first);
  for (const auto& e : graph.edges) {
    insertRobot(robots, e.from);
    insertRobot(robots, e.to);
  }
  return robots;
}

std::vector<G2oEdge> interRobotEdges(const G2oGraph& graph) {
  std::vector<G2oEdge> edges;
  std::copy_if(graph.edges.begin(), graph.edges.end(), std::back_inserter(edges), isInterRobot);
  return edges;
}

}  // namespace dcl::io
