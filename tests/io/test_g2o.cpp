#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/io/g2o.hpp>

#include "io_test_util.hpp"

namespace dcl::io {
namespace {

namespace fs = std::filesystem;

const std::string kGraphs = std::string(DCL_DATA_DIR) + "/pose_graphs";

/// What a graph file holds, counted from its tags without the reader.
struct TagCount {
  std::size_t vertices = 0;
  std::size_t edges = 0;
  std::size_t unknown = 0;
  bool planar = false;
  std::set<std::uint64_t> edge_ends;
  std::size_t inter_robot = 0;  ///< edges whose ids' top bytes differ
};

TagCount countTags(const std::string& path) {
  TagCount count;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::string tag;
    if (!(words >> tag) || tag.front() == '#' || tag == "FIX" || tag == "EQUIV") continue;
    const bool vertex = tag.rfind("VERTEX", 0) == 0;
    const bool edge = tag.rfind("EDGE", 0) == 0;
    count.unknown += !vertex && !edge;
    count.vertices += vertex;
    count.edges += edge;
    count.planar = count.planar || tag == "VERTEX_SE2" || tag == "EDGE_SE2" || tag == "EDGE2";
    if (!edge) continue;
    std::string a, b;
    words >> a >> b;
    const auto from = std::stoull(a), to = std::stoull(b);
    count.edge_ends.insert({from, to});
    count.inter_robot += (from >> 56) != (to >> 56) && (from >> 56) != 0 && (to >> 56) != 0;
  }
  return count;
}

std::vector<std::string> allGraphFiles() {
  std::vector<std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(kGraphs)) {
    const auto ext = entry.path().extension();
    if (entry.is_regular_file() && (ext == ".g2o" || ext == ".graph")) {
      files.push_back(entry.path().string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

void expectSamePose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b,
                    const std::string& what) {
  const double scale = std::max(1.0, a.translation().norm());
  EXPECT_LE((a.translation() - b.translation()).norm(), 1e-12 * scale) << what;
  EXPECT_LE((a.linear() - b.linear()).norm(), 1e-12) << what;
}

void expectSameGraph(const G2oGraph& a, const G2oGraph& b, const std::string& name) {
  ASSERT_EQ(a.vertices.size(), b.vertices.size()) << name;
  ASSERT_EQ(a.edges.size(), b.edges.size()) << name;
  EXPECT_EQ(a.is_2d, b.is_2d) << name;
  EXPECT_EQ(a.fixed, b.fixed) << name;
  EXPECT_EQ(a.equivalences, b.equivalences) << name;
  for (auto ia = a.vertices.begin(), ib = b.vertices.begin(); ia != a.vertices.end(); ++ia, ++ib) {
    ASSERT_EQ(ia->first, ib->first) << name;
    expectSamePose(ia->second, ib->second, name + " vertex " + std::to_string(ia->first));
  }
  for (std::size_t i = 0; i < a.edges.size(); ++i) {
    const G2oEdge& ea = a.edges[i];
    const G2oEdge& eb = b.edges[i];
    ASSERT_EQ(ea.from, eb.from) << name;
    ASSERT_EQ(ea.to, eb.to) << name;
    expectSamePose(ea.T_from_to, eb.T_from_to, name + " edge " + std::to_string(i));
    ASSERT_TRUE(ea.information == eb.information) << name << " edge " << i;
  }
}

/// The one file of the data set with a stray line ("0410268 0.7588833", line 16).
bool isKnownCorrupt(const std::string& path) {
  return path.find("pairwise_consistency_maximization/spoiled/simulation/example_2robots/1.g2o") !=
         std::string::npos;
}

TEST(G2o, EveryDataFileLoadsWithItsCountsAndRoundTrips) {
  test::TempDir dir;
  const auto files = allGraphFiles();
  ASSERT_EQ(files.size(), 368u);  // 369 files in the folder, one is PROVENANCE.md
  for (const auto& path : files) {
    SCOPED_TRACE(path);
    const TagCount count = countTags(path);
    G2oReadOptions options;
    if (count.unknown > 0) {
      EXPECT_TRUE(isKnownCorrupt(path));
      EXPECT_THROW(readG2o(path), core::FileError);
      options.skip_unknown_tags = true;
    }
    const G2oGraph graph = readG2o(path, options);
    EXPECT_EQ(graph.skipped_lines.size(), count.unknown);
    EXPECT_EQ(graph.edges.size(), count.edges);
    EXPECT_EQ(graph.vertices.size(), count.vertices > 0 ? count.vertices : count.edge_ends.size());
    EXPECT_EQ(graph.chained, count.vertices == 0);
    EXPECT_EQ(graph.is_2d, count.planar);
    EXPECT_EQ(interRobotEdges(graph).size(), count.inter_robot);

    writeG2o(dir.file("out.g2o"), graph);
    expectSameGraph(graph, readG2o(dir.file("out.g2o")), path);
  }
}

TEST(G2o, WellKnownBenchmarksHaveTheirPublishedSizes) {
  struct Expected {
    const char* file;
    std::size_t vertices;
    std::size_t edges;
    bool planar;
  };
  const std::vector<Expected> expected = {
      {"3d/sphere2500.g2o", 2500, 4949, false},
      {"3d/torus3D.g2o", 5000, 9048, false},
      {"3d/parking-garage.g2o", 1661, 6275, false},
      {"3d/smallGrid3D.g2o", 125, 297, false},
      {"3d/tinyGrid3D.g2o", 9, 11, false},
      {"3d/sphere_bignoise_vertex3.g2o", 2200, 8647, false},
      {"3d/gtsam_pose3example-grid.g2o", 27, 44, false},
      {"3d/gtsam_pose3example.g2o", 5, 6, false},
      {"3d/sphere_smallnoise.graph", 2200, 8647, false},
      {"3d/sphere2500_groundtruth.graph", 2500, 4949, false},  // chained: edges only
      {"2d/MIT.g2o", 808, 827, true},
      {"2d/intel.g2o", 1728, 2512, true},
      {"2d/city10000.g2o", 10000, 20687, true},
      {"2d/M3500.g2o", 3500, 5453, true},
      {"2d/manhattan.g2o", 3500, 5453, true},  // chained
      {"2d/CSAIL.g2o", 1045, 1172, true},      // chained
      {"2d/kitti_00.g2o", 4541, 4677, true},   // chained; as many as KITTI 00 has scans
      {"2d/w100.graph", 100, 300, true},
      {"2d/gtsam_noisyToyGraph.g2o", 4, 5, true},
  };
  for (const auto& e : expected) {
    const G2oGraph graph = readG2o(kGraphs + "/" + e.file);
    EXPECT_EQ(graph.vertices.size(), e.vertices) << e.file;
    EXPECT_EQ(graph.edges.size(), e.edges) << e.file;
    EXPECT_EQ(graph.is_2d, e.planar) << e.file;
  }
}

TEST(G2o, InformationKeptExactlyInTangentOrder) {
  // sphere2500 line 2501: "... 10 0 0 0 0 0 10 0 0 0 0 10 0 0 0 400.021 0.00193512 2.06612
  // 399.993 0.496977 99.203"
  const G2oGraph sphere = readG2o(kGraphs + "/3d/sphere2500.g2o");
  const auto& info = sphere.edges.front().information;
  EXPECT_EQ(info(0, 0), 10.0);
  EXPECT_EQ(info(3, 3), 400.021);
  EXPECT_EQ(info(3, 4), 0.00193512);
  EXPECT_EQ(info(4, 3), 0.00193512);
  EXPECT_EQ(info(3, 5), 2.06612);
  EXPECT_EQ(info(5, 5), 99.203);
  EXPECT_EQ(sphere.edges.front().T_from_to.translation(),
            Eigen::Vector3d(0.341895, -0.0416997, 0.0330394));

  // kitti_00 line 1: "EDGE_SE2 0 1 0.686993 -0.002361 0.003338 554.211419 -35.951359
  // -388.373897 388.036411 525.434911 294517.342200" (g2o order xx xy xt yy yt tt).
  const G2oGraph kitti = readG2o(kGraphs + "/2d/kitti_00.g2o");
  const auto& planar = kitti.edges.front().information;
  EXPECT_EQ(planar(0, 0), 554.211419);
  EXPECT_EQ(planar(0, 1), -35.951359);
  EXPECT_EQ(planar(0, 5), -388.373897);
  EXPECT_EQ(planar(5, 0), -388.373897);
  EXPECT_EQ(planar(1, 1), 388.036411);
  EXPECT_EQ(planar(1, 5), 525.434911);
  EXPECT_EQ(planar(5, 5), 294517.342200);
  for (const int axis : {2, 3, 4}) EXPECT_EQ(planar(axis, axis), 294517.342200);  // stiffest
  EXPECT_EQ(planar(0, 2), 0.0);
  EXPECT_EQ(planar(2, 3), 0.0);
}

TEST(G2o, PlanarInformationOrdersOfG2oAndToro) {
  test::TempDir dir;
  const std::string g2o = dir.write("a.g2o", "EDGE_SE2 0 1 1 2 0.1 11 12 13 22 23 33\n");
  const std::string toro = dir.write("a.graph", "EDGE2 0 1 1 2 0.1 11 12 22 33 13 23\n");
  for (const auto& path : {g2o, toro}) {
    const auto info = readG2o(path).edges.front().information;
    EXPECT_EQ(info(0, 0), 11);
    EXPECT_EQ(info(0, 1), 12);
    EXPECT_EQ(info(0, 5), 13);
    EXPECT_EQ(info(1, 1), 22);
    EXPECT_EQ(info(1, 5), 23);
    EXPECT_EQ(info(5, 5), 33);
    EXPECT_EQ(info(2, 2), 33);
  }
  // A planar graph is written back as planar, in g2o's order.
  writeG2o(dir.file("b.g2o"), readG2o(toro));
  std::ifstream in(dir.file("b.g2o"));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // The angle goes through a rotation matrix (0.1 may come back 1 ulp off); information exact.
  EXPECT_NE(text.find("EDGE_SE2 0 1 1 2 "), std::string::npos) << text;
  EXPECT_NE(text.find(" 11 12 13 22 23 33\n"), std::string::npos) << text;
  EXPECT_NE(text.find("VERTEX_SE2 0 0 0 0\n"), std::string::npos) << text;
  EXPECT_EQ(text.find("SE3"), std::string::npos) << text;
}

TEST(G2o, ToroEulerAnglesAndMissingInformation) {
  test::TempDir dir;
  const std::string path = dir.write("a.graph",
                                     "VERTEX3 0 1 2 3 0.1 0.2 0.3\n"
                                     "VERTEX3 1 0 0 0 0 0 0\n"
                                     "EDGE3 0 1 1 0 0 0 0 0.5\n");
  const G2oGraph graph = readG2o(path);
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  EXPECT_LE((graph.vertices.at(0).linear() - R).norm(), 1e-15);
  EXPECT_EQ(graph.vertices.at(0).translation(), Eigen::Vector3d(1, 2, 3));
  EXPECT_TRUE(graph.edges.front().information == core::Matrix6d::Identity());
  EXPECT_FALSE(graph.is_2d);
}

/// x, y, theta of a planar pose.
struct Pose2 {
  double x = 0, y = 0, theta = 0;
};

Pose2 compose(const Pose2& a, const Pose2& d) {
  return {a.x + std::cos(a.theta) * d.x - std::sin(a.theta) * d.y,
          a.y + std::sin(a.theta) * d.x + std::cos(a.theta) * d.y, a.theta + d.theta};
}

/// Odometry (id -> id + 1) measurements of an EDGE_SE2 file, by source id.
std::map<std::uint64_t, Pose2> odometryOf(const std::string& path) {
  std::map<std::uint64_t, Pose2> odometry;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::string tag;
    std::uint64_t from = 0, to = 0;
    Pose2 d;
    if (words >> tag >> from >> to >> d.x >> d.y >> d.theta && to == from + 1) {
      odometry.emplace(from, d);  // the first, as chaining uses
    }
  }
  return odometry;
}

void expectPlanarPose(const Eigen::Isometry3d& T, const Pose2& p, double tol,
                      const std::string& what) {
  EXPECT_NEAR(T.translation().x(), p.x, tol) << what;
  EXPECT_NEAR(T.translation().y(), p.y, tol) << what;
  EXPECT_NEAR(T.translation().z(), 0.0, tol) << what;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(p.theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  EXPECT_LE((T.linear() - R).norm(), tol) << what;
}

TEST(G2o, EdgesOnlyGraphsGetChainedOdometry) {
  for (const char* file :
       {"2d/CSAIL.g2o", "2d/manhattan.g2o", "2d/kitti_00.g2o", "2d/kitti_08.g2o"}) {
    const std::string path = kGraphs + "/" + file;
    const G2oGraph graph = readG2o(path);
    ASSERT_TRUE(graph.chained) << file;
    const auto odometry = odometryOf(path);
    Pose2 pose;
    EXPECT_TRUE(graph.vertices.at(0).isApprox(Eigen::Isometry3d::Identity())) << file;
    for (std::uint64_t id = 1; id < 4; ++id) {
      pose = compose(pose, odometry.at(id - 1));
      expectPlanarPose(graph.vertices.at(id), pose, 1e-12,
                       std::string(file) + " " + std::to_string(id));
    }
    for (std::uint64_t id = 4; odometry.contains(id - 1); ++id)
      pose = compose(pose, odometry.at(id - 1));
    const auto last = graph.vertices.rbegin();
    ASSERT_EQ(last->first, odometry.rbegin()->first + 1) << file;
    expectPlanarPose(last->second, pose, 1e-6, std::string(file) + " last");
  }
}

TEST(G2o, ChainingHandlesGapsReversedEdgesAndComponents) {
  test::TempDir dir;
  const std::string info = " 1 0 0 1 0 1\n";
  const std::string path = dir.write("gaps.g2o",
                                     "EDGE_SE2 0 1 1 0 0" + info +  // odometry
                                         "EDGE_SE2 1 2 1 0 1.5707963267948966" + info +
                                         "EDGE_SE2 2 4 2 0 0" + info +  // gap in the numbering
                                         "EDGE_SE2 6 5 0 1 0" + info +  // other component, reversed
                                         "EDGE_SE2 0 8 0 -3 0" + info);  // reached by a loop only
  const G2oGraph graph = readG2o(path);
  ASSERT_EQ(graph.vertices.size(), 7u);
  const auto at = [&](std::uint64_t id) { return graph.vertices.at(id).translation(); };
  EXPECT_TRUE(at(0).isApprox(Eigen::Vector3d(0, 0, 0)));
  EXPECT_TRUE(at(1).isApprox(Eigen::Vector3d(1, 0, 0)));
  EXPECT_TRUE(at(2).isApprox(Eigen::Vector3d(2, 0, 0)));
  EXPECT_TRUE(at(4).isApprox(Eigen::Vector3d(2, 2, 0), 1e-12));  // 2 m along the turned heading
  EXPECT_TRUE(at(5).isApprox(at(4)));                            // new component starts where 4 is
  EXPECT_TRUE(graph.vertices.at(5).linear().isApprox(graph.vertices.at(4).linear()));
  // T_6_5 = (0, 1): 5 is 1 m to the left of 6, so 6 is 1 m to the right of 5 (heading +90 deg).
  EXPECT_TRUE(at(6).isApprox(Eigen::Vector3d(3, 2, 0), 1e-12)) << at(6).transpose();
  EXPECT_TRUE(at(8).isApprox(Eigen::Vector3d(0, -3, 0), 1e-12)) << at(8).transpose();

  G2oReadOptions options;
  options.chain_missing_vertices = false;
  EXPECT_TRUE(readG2o(path, options).vertices.empty());
}

TEST(G2o, MultiRobotGraphsReportRobotsAndInterRobotEdges) {
  const std::string folder = kGraphs + "/multi_robot/distributed_mapper/example_4robots/";
  std::vector<G2oGraph> graphs;
  for (int robot = 0; robot < 4; ++robot)
    graphs.push_back(readG2o(folder + std::to_string(robot) + ".g2o"));
  for (std::size_t robot = 0; robot < graphs.size(); ++robot) {
    const G2oGraph& graph = graphs[robot];
    for (const auto& [id, pose] : graph.vertices) {
      const auto key = vertexKey(id);
      ASSERT_TRUE(key.has_value());
      EXPECT_EQ(key->robot.value(), robot);
      EXPECT_EQ(key->pack(), id);
    }
    const auto inter = interRobotEdges(graph);
    EXPECT_FALSE(inter.empty());
    EXPECT_EQ(robotsOf(graph).count(core::RobotId(static_cast<std::uint8_t>(robot))), 1u);
    for (const auto& e : inter) {
      // One end is this robot's vertex, the other a neighbour's that this file does not hold.
      EXPECT_NE(graph.hasVertex(e.from), graph.hasVertex(e.to));
      const auto other = vertexKey(graph.hasVertex(e.from) ? e.to : e.from)->robot.value();
      EXPECT_NE(other, robot);
      EXPECT_TRUE(graphs[other].hasVertex(graph.hasVertex(e.from) ? e.to : e.from));
    }
    for (const auto& e : graph.edges) {
      EXPECT_TRUE(isInterRobot(e) || (graph.hasVertex(e.from) && graph.hasVertex(e.to)));
    }
  }
  const std::string blocks = kGraphs + "/multi_robot/distributed_mapper/blocks_world/2robots/";
  const G2oGraph first = readG2o(blocks + "0.g2o");
  EXPECT_EQ(robotsOf(first), (std::set<core::RobotId>{core::RobotId(0), core::RobotId(1)}));
  EXPECT_FALSE(interRobotEdges(first).empty());
  // The centralized graph numbers its vertices with plain integers.
  const G2oGraph full = readG2o(blocks + "fullGraph.g2o");
  EXPECT_TRUE(robotsOf(full).empty());
  EXPECT_TRUE(interRobotEdges(full).empty());

  // Kimera-RPGO's graph: integer poses plus three 'u' symbols (robot 20 by the encoding);
  // edges between an integer id and a symbol are not inter-robot.
  const G2oGraph mixed = readG2o(kGraphs + "/multi_robot/kimera_rpgo/ordered.g2o");
  EXPECT_EQ(robotsOf(mixed), std::set<core::RobotId>{core::RobotId('u' - 'a')});
  EXPECT_TRUE(interRobotEdges(mixed).empty());
  const G2oGraph robot_b = readG2o(kGraphs + "/multi_robot/kimera_rpgo/robot_b.g2o");
  EXPECT_EQ(robotsOf(robot_b), std::set<core::RobotId>{core::RobotId(1)});
  EXPECT_TRUE(interRobotEdges(robot_b).empty());
}

TEST(G2o, SymbolHelpers) {
  const core::PoseKey key{core::RobotId(2), core::KeyframeId(17)};
  ASSERT_TRUE(vertexKey(key.pack()).has_value());
  EXPECT_EQ(*vertexKey(key.pack()), key);
  EXPECT_FALSE(vertexKey(17).has_value());
  EXPECT_EQ(vertexKey(6989586621679009792ull)->robot, core::RobotId(0));  // 'a' << 56
  const core::PoseKey other{core::RobotId(3), core::KeyframeId(0)};
  EXPECT_TRUE(isInterRobot({key.pack(), other.pack()}));
  EXPECT_FALSE(isInterRobot({key.pack(), key.pack() + 1}));
  EXPECT_FALSE(isInterRobot({1, 2}));
  // A 27th robot and on: the bytes past 'z' ('{' for robot 26), as runs of 27
  // robots write their graphs.
  for (const int robot : {26, 100, 158}) {
    const core::PoseKey far{core::RobotId(static_cast<std::uint8_t>(robot)), core::KeyframeId(5)};
    ASSERT_TRUE(vertexKey(far.pack()).has_value()) << robot;
    EXPECT_EQ(*vertexKey(far.pack()), far) << robot;
    EXPECT_TRUE(isInterRobot({far.pack(), key.pack()})) << robot;
  }
}

TEST(G2o, DuplicatedFixAndEquivLinesAreKept) {
  const G2oGraph w100 = readG2o(kGraphs + "/2d/w100.graph");
  EXPECT_EQ(w100.equivalences.size(), 40u);
  EXPECT_EQ(w100.equivalences.front(), (std::pair<std::uint64_t, std::uint64_t>{21, 1}));
  test::TempDir dir;
  const std::string path = dir.write("fix.g2o", "VERTEX_SE3:QUAT 3 0 0 0 0 0 0 1\nFIX 3\n");
  EXPECT_EQ(readG2o(path).fixed, std::set<std::uint64_t>{3});
}

TEST(G2o, KnownCorruptDataFileNamesLineAndTag) {
  const std::string path =
      kGraphs +
      "/multi_robot_outliers/robust_distributed_mapper/"
      "pairwise_consistency_maximization/spoiled/simulation/example_2robots/1.g2o";
  const std::string message = test::fileError([&] { readG2o(path); });
  EXPECT_NE(message.find(path + ":16:"), std::string::npos) << message;
  EXPECT_NE(message.find("unknown tag '0410268'"), std::string::npos) << message;
  G2oReadOptions options;
  options.skip_unknown_tags = true;
  const G2oGraph graph = readG2o(path, options);
  EXPECT_EQ(graph.skipped_lines, std::vector<std::size_t>{16});
  EXPECT_EQ(graph.vertices.size(), 21u);
  EXPECT_EQ(graph.edges.size(), 40u);
}

struct CorruptG2o {
  std::string name;
  std::string content;
  std::vector<std::string> expected;
};

const std::string kVertex = "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n";
const std::string kEdge =
    "EDGE_SE3:QUAT 0 1 0.341895 -0.0416997 0.0330394 -0.00189341 0.00395691 0.0899835 0.995934 "
    "10 0 0 0 0 0 10 0 0 0 0 10 0 0 0 400.021 0.00193512 2.06612 399.993 0.496977 99.203\n";

std::string repeat(const std::string& text, std::size_t times) {
  std::string out;
  for (std::size_t i = 0; i < times; ++i) out += text;
  return out;
}

std::vector<CorruptG2o> corruptGraphs() {
  return {
      {"empty", "", {":1:", "no vertices or edges"}},
      {"comments_only", "# nothing\n\n", {":3:", "no vertices or edges"}},
      {"unknown_tag", kVertex + "VERTEX_XYZ 1 0 0 0\n", {":2:", "unknown tag 'VERTEX_XYZ'"}},
      {"cut_mid_line", kVertex + kEdge.substr(0, 60), {":2:", "EDGE_SE3:QUAT needs 30", "found 6"}},
      {"cut_mid_info", kVertex + kEdge.substr(0, kEdge.size() - 7) + "\n", {":2:", "found 29"}},
      {"cut_mid_number",
       kVertex + kEdge.substr(0, kEdge.size() - 4) + "e\n",
       {":2:", "'I66'", "'99.e'"}},
      {"too_many", kVertex + kEdge.substr(0, kEdge.size() - 1) + " 1\n", {":2:", "found 31"}},
      {"word", "VERTEX_SE3:QUAT 0 0 zero 0 0 0 0 1\n", {":1:", "field 'y'", "'zero'"}},
      {"nan", kVertex + "VERTEX_SE3:QUAT 1 nan 0 0 0 0 0 1\n", {":2:", "field 'x'", "not finite"}},
      {"inf_info", "EDGE_SE2 0 1 1 0 0 1 0 0 inf 0 1\n", {":1:", "field 'I22'", "not finite"}},
      {"negative_id", "VERTEX_SE2 -1 0 0 0\n", {":1:", "field 'id'", "'-1' is not a vertex id"}},
      {"float_id", "EDGE_SE2 0 1.5 1 0 0 1 0 0 1 0 1\n", {":1:", "field 'to'"}},
      {"duplicate", kVertex + kVertex, {":2:", "vertex 0 is defined twice"}},
      {"self_loop", "EDGE_SE2 4 4 1 0 0 1 0 0 1 0 1\n", {":1:", "to itself"}},
      {"mixed", kVertex + "VERTEX_SE2 1 0 0 0\n", {":2:", "mixes 2D and 3D", "line 1 was 3D"}},
      {"zero_quaternion", "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 0\n", {":1:", "quaternion norm 0"}},
      {"edge3_count", "EDGE3 0 1 0 0 0 0 0 0 1 2 3\n", {":1:", "EDGE3 needs 8", "found 11"}},
      {"fix_without_id", kVertex + "FIX\n", {":2:", "FIX needs 1"}},
      {"equiv_cut", kVertex + "EQUIV 3\n", {":2:", "EQUIV needs 2"}},
      {"zero_information",
       kVertex + "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1" + repeat(" 0", 21) + "\n",
       {":2:", "field 'information'", "information matrix is zero"}},
      {"zero_planar_information",  // zero before the off-plane axes are filled in
       "EDGE_SE2 0 1 1 0 0 0 0 0 0 0 0\n",
       {":1:", "field 'information'", "is zero"}},
      {"negative_information",
       "EDGE_SE2 0 1 1 0 0 -1 0 0 -1 0 -1\n",
       {":1:", "field 'information'", "not positive semi-definite", "eigenvalue -1"}},
      {"indefinite_information",  // positive diagonal, eigenvalues 3, -1, 1
       "EDGE_SE2 0 1 1 0 0 1 2 0 1 0 1\n",
       {":1:", "field 'information'", "not positive semi-definite", "eigenvalue -0.99"}},
      {"indefinite_toro_information",
       "EDGE3 0 1 0 0 0 0 0 0 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 -5 0 1\n",
       {":1:", "field 'information'", "eigenvalue -5"}},
  };
}

TEST(G2o, CorruptFilesNameFileLineAndField) {
  test::TempDir dir;
  for (const auto& c : corruptGraphs()) {
    const std::string path = dir.write(c.name + ".g2o", c.content);
    const std::string message = test::fileError([&] { readG2o(path); });
    EXPECT_NE(message.find(path), std::string::npos) << c.name << ": " << message;
    for (const auto& part : c.expected) {
      EXPECT_NE(message.find(part), std::string::npos) << c.name << ": " << message;
    }
  }
  EXPECT_NE(test::fileError([&] { readG2o(dir.file("missing.g2o")); }).find("missing.g2o"),
            std::string::npos);
}

TEST(G2o, SemiDefiniteInformationIsKeptAndLinesAreRecorded) {
  test::TempDir dir;
  // No rotation information in the plane; nothing about z, roll and pitch in 3D
  // (a planar graph written as 3D); an eigenvalue of -1e-7 that is rounding.
  const std::string path = dir.write(
      "semi.g2o", kVertex + "VERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n# comment\n" +
                      "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 4 0 0 0 0 0 4 0 0 0 0" + repeat(" 0", 9) +
                      " 9\n" + "EDGE_SE3:QUAT 1 0 1 0 0 0 0 0 1 1 1.0000001 0 0 0 0 1" +
                      repeat(" 0", 13) + " 1\n");
  const G2oGraph graph = readG2o(path);
  ASSERT_EQ(graph.edges.size(), 2u);
  EXPECT_EQ(graph.edges[0].information(2, 2), 0.0);
  EXPECT_EQ(graph.edges[0].information(5, 5), 9.0);
  EXPECT_EQ(graph.edges[0].line, 4u);
  EXPECT_EQ(graph.edges[1].line, 5u);
  EXPECT_EQ(graph.vertex_lines, (std::map<std::uint64_t, std::size_t>{{0, 1}, {1, 2}}));
  const std::string planar = dir.write("planar.g2o", "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 0\n");
  EXPECT_EQ(readG2o(planar).edges.front().information(5, 5), 0.0);
  EXPECT_TRUE(readG2o(planar).vertex_lines.empty());  // chained
}

TEST(G2o, TruncatedOrCorruptedAnywhereNeverCrashes) {
  test::TempDir dir;
  const std::string text = kVertex + "VERTEX_SE3:QUAT 1 0.3 0 0 0 0 0 1\n" + kEdge;
  const std::string path = dir.file("fuzz.g2o");
  const auto check = [&](const std::string& content) {
    { std::ofstream(path, std::ios::binary | std::ios::trunc) << content; }
    try {
      static_cast<void>(readG2o(path));
    } catch (const core::FileError& e) {
      const std::string message = e.what();
      ASSERT_EQ(message.rfind(path + ":", 0), 0u) << message;
      ASSERT_TRUE(e.location().line.has_value()) << message;
    }
  };
  for (std::size_t cut = 0; cut <= text.size(); ++cut) check(text.substr(0, cut));
  for (std::size_t i = kVertex.size(); i < text.size(); i += 2) {
    std::string corrupted = text;
    corrupted[i] = i % 4 == 0 ? 'x' : '\n';
    check(corrupted);
  }
}

}  // namespace
}  // namespace dcl::io
