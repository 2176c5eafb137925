// g2o graphs as the back-end's PoseGraph and back.

#include <string>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/io/g2o.hpp>
#include <dcl/io/pose_graph_g2o.hpp>

#include "../common/keys.hpp"
#include "io_test_util.hpp"

namespace dcl::io {
namespace {

using backend::Factor;
using backend::FactorKind;
using backend::PoseGraph;

using dcl::test::key;

Eigen::Isometry3d pose(double x, double y, double z, double yaw) {
  Eigen::Isometry3d T = core::makePose2d(x, y, yaw);
  T.translation().z() = z;
  return T;
}

std::string dataPath(const std::string& relative) {
  return std::string(DCL_DATA_DIR) + "/pose_graphs/" + relative;
}

TEST(PoseGraphG2o, ToPoseGraphKeepsVerticesEdgesAndKinds) {
  const G2oGraph g2o = readG2o(dataPath("3d/tinyGrid3D.g2o"));
  const PoseGraph graph = toPoseGraph(g2o);
  EXPECT_EQ(graph.size(), g2o.vertices.size());
  ASSERT_EQ(graph.factors().size(), g2o.edges.size());
  std::size_t odometry = 0;
  for (std::size_t i = 0; i < g2o.edges.size(); ++i) {
    const Factor& f = graph.factors()[i];
    EXPECT_EQ(f.from, key(0, static_cast<int>(g2o.edges[i].from)));
    EXPECT_TRUE(f.T_from_to.isApprox(g2o.edges[i].T_from_to));
    EXPECT_EQ(f.information, g2o.edges[i].information);
    const bool consecutive = g2o.edges[i].to == g2o.edges[i].from + 1;
    EXPECT_EQ(f.kind, consecutive ? FactorKind::odometry : FactorKind::intra_loop);
    odometry += f.kind == FactorKind::odometry ? 1 : 0;
  }
  EXPECT_EQ(odometry, g2o.vertices.size() - 1);  // tinyGrid3D is one odometry chain plus loops
  EXPECT_GT(graph.factors().size(), odometry);
}

TEST(PoseGraphG2o, SymbolIdsGiveRobotsAndInterRobotLoops) {
  G2oGraph g2o;
  const core::PoseKey a0 = key(0, 0), a1 = key(0, 1), b0 = key(1, 0);
  g2o.vertices = {
      {a0.pack(), pose(0, 0, 0, 0)}, {a1.pack(), pose(1, 0, 0, 0)}, {b0.pack(), pose(1, 1, 0, 0)}};
  g2o.edges = {{a0.pack(), a1.pack(), pose(1, 0, 0, 0), core::Matrix6d::Identity()},
               {a1.pack(), b0.pack(), pose(0, 1, 0, 0), core::Matrix6d::Identity()}};
  g2o.fixed = {a0.pack()};
  const PoseGraph graph = toPoseGraph(g2o);
  EXPECT_TRUE(graph.hasNode(b0));
  EXPECT_TRUE(graph.isFixed(a0));
  EXPECT_EQ(graph.factors()[0].kind, FactorKind::odometry);
  EXPECT_EQ(graph.factors()[1].kind, FactorKind::inter_loop);
  // Several robots: symbols by default; plain ids cannot name them.
  const G2oGraph back = toG2o(graph);
  EXPECT_EQ(back.vertices.size(), 3u);
  EXPECT_TRUE(back.hasVertex(b0.pack()));
  EXPECT_TRUE(back.fixed.contains(a0.pack()));
  EXPECT_EQ(back.edges[1].to, b0.pack());
  EXPECT_THROW((void)toG2o(graph, VertexIds::plain), core::Error);
}

TEST(PoseGraphG2o, RoundTripsThroughG2oWithPlainIds) {
  const G2oGraph g2o = readG2o(dataPath("3d/smallGrid3D.g2o"));
  const G2oGraph back = toG2o(toPoseGraph(g2o));
  ASSERT_EQ(back.vertices.size(), g2o.vertices.size());
  ASSERT_EQ(back.edges.size(), g2o.edges.size());
  for (const auto& [id, T] : g2o.vertices) EXPECT_TRUE(back.vertices.at(id).isApprox(T));
  for (std::size_t i = 0; i < g2o.edges.size(); ++i) {
    EXPECT_EQ(back.edges[i].from, g2o.edges[i].from);
    EXPECT_EQ(back.edges[i].to, g2o.edges[i].to);
    EXPECT_EQ(back.edges[i].information, g2o.edges[i].information);
  }
}

TEST(PoseGraphG2o, AGraphWrittenReadsBackTheSame) {
  const PoseGraph graph = readPoseGraph(dataPath("3d/smallGrid3D.g2o"));
  const std::string path = (test::freshDir("pose_graph_g2o") / "graph.g2o").string();
  writePoseGraph(path, graph);
  const PoseGraph back = readPoseGraph(path);
  ASSERT_EQ(back.nodes().size(), graph.nodes().size());
  ASSERT_EQ(back.factors().size(), graph.factors().size());
  for (const auto& [key, T] : graph.nodes()) EXPECT_TRUE(back.estimate(key).isApprox(T));
  for (std::size_t i = 0; i < graph.factors().size(); ++i) {
    EXPECT_EQ(back.factors()[i].from, graph.factors()[i].from);
    EXPECT_EQ(back.factors()[i].kind, graph.factors()[i].kind);
    EXPECT_EQ(back.factors()[i].information, graph.factors()[i].information);
  }
  EXPECT_THROW((void)readPoseGraph(dataPath("no_such_graph.g2o")), core::FileError);
}

}  // namespace
}  // namespace dcl::io
