// Multi-robot graphs (one file, or a folder of per-robot files) and their
// outlier-free references, the inputs of PCM's evaluation, on the benchmarks'
// real graphs and on small broken folders.

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include <dcl/backend/pcm.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/multi_robot_graph.hpp>

#include "../common/keys.hpp"

namespace dcl::io {
namespace {

namespace fs = std::filesystem;
using backend::Factor;
using backend::LoopId;
using backend::PoseGraph;

using dcl::test::key;

std::string outliersPath(const std::string& relative) {
  return std::string(DCL_DATA_DIR) + "/pose_graphs/multi_robot_outliers/" + relative;
}

TEST(MultiRobotGraph, RobotFoldersMergeAndReferencesAreMatchedByKey) {
  const PoseGraph graph =
      readMultiRobotGraph(outliersPath("mixrobust_real2d_split/INTEL/spilt_5_6_spoiled"));
  std::size_t inter = 0;
  for (const Factor& f : graph.factors()) inter += f.from.robot != f.to.robot;
  EXPECT_EQ(inter, 123U);  // each loop is in both robots' files, counted once
  EXPECT_EQ(graph.size(), 1228U);
  const std::set<LoopId> reference = readReferenceLoops(
      outliersPath("mixrobust_real2d_split/INTEL/spilt_5_6_spoiled/fullgraph_without_outliers.g2o"),
      graph);
  EXPECT_EQ(reference.size(), 23U);
  for (const LoopId& id : reference) {
    EXPECT_EQ(id.first.robot, core::RobotId(0));
    EXPECT_EQ(id.second.robot, core::RobotId(1));
  }
  // A centralized graph of another split is refused, naming the file.
  try {
    (void)readReferenceLoops(
        outliersPath("mixrobust_real2d_split/INTEL/spilt/fullgraph_without_outliers.g2o"),
        readMultiRobotGraph(outliersPath("mixrobust_real2d_split/CSAIL/spilt")));
    FAIL() << "a reference of another graph was accepted";
  } catch (const core::FileError& e) {
    EXPECT_NE(std::string(e.what()).find("not a reference of this graph"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("INTEL/spilt/fullgraph"), std::string::npos);
  }
}

TEST(MultiRobotGraph, DamagedAndMissingFilesAreNamed) {
  // One upstream robot file has a broken line 16.
  const std::string damaged = outliersPath(
      "robust_distributed_mapper/pairwise_consistency_maximization/spoiled/simulation/"
      "example_2robots");
  try {
    (void)readMultiRobotGraph(damaged);
    FAIL() << "a damaged line was accepted";
  } catch (const core::FileError& e) {
    EXPECT_NE(std::string(e.what()).find("1.g2o:16"), std::string::npos) << e.what();
  }
  const PoseGraph graph = readMultiRobotGraph(damaged, true);
  EXPECT_EQ(backend::runPcm(graph).loops(), 20U);

  const fs::path empty = fs::temp_directory_path() / "dcl_test_multi_robot_graph_empty_folder";
  fs::create_directories(empty);
  std::ofstream(empty / "notes.txt") << "no graph here\n";
  EXPECT_THROW((void)readMultiRobotGraph(empty.string()), core::FileError);
  fs::remove_all(empty);
  EXPECT_THROW((void)readMultiRobotGraph(outliersPath("no_such_graph")), core::FileError);
}

/// Text of small split graphs: robot r's keyframe k is the symbol ('a' + r, k).
std::string symbol(int robot, int keyframe) {
  return std::to_string(key(robot, keyframe).pack());
}

std::string vertexLine(int robot, int keyframe) {
  return "VERTEX_SE3:QUAT " + symbol(robot, keyframe) + " 0 0 0 0 0 0 1\n";
}

std::string edgeLine(int robot_a, int keyframe_a, int robot_b, int keyframe_b) {
  return "EDGE_SE3:QUAT " + symbol(robot_a, keyframe_a) + " " + symbol(robot_b, keyframe_b) +
         " 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
}

/// A scratch folder for one case, emptied first.
fs::path scratchFolder(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() /
                       ("dcl_test_multi_robot_graph_" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

/// The message of the core::FileError `read` throws ("" and a failure otherwise).
template <class F>
std::string fileError(F&& read) {
  try {
    read();
  } catch (const core::FileError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no core::FileError";
  return {};
}

TEST(MultiRobotGraph, EveryDataGraphReadsWhole) {
  // Every split folder, and every other graph file as one graph: each edge's
  // ends are vertices, each robot's vertices in one file.
  const fs::path root = fs::path(DCL_DATA_DIR) / "pose_graphs";
  const std::regex robot_file("[0-9]+\\.g2o");
  std::set<fs::path> folders;
  std::size_t files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(root)) {
    const std::string name = entry.path().filename().string();
    const bool graph = name.ends_with(".g2o") || name.ends_with(".graph");
    if (!entry.is_regular_file() || !graph) continue;
    if (std::regex_match(name, robot_file)) {
      folders.insert(entry.path().parent_path());
      continue;
    }
    SCOPED_TRACE(entry.path().string());
    EXPECT_NO_THROW((void)readMultiRobotGraph(entry.path().string()));
    ++files;
  }
  EXPECT_EQ(folders.size(), 32U);
  EXPECT_EQ(files, 42U);  // full graphs, single-robot benchmarks, Kimera-RPGO's
  for (const fs::path& folder : folders) {
    SCOPED_TRACE(folder.string());
    const bool damaged = folder.string().ends_with("spoiled/simulation/example_2robots");
    EXPECT_NO_THROW((void)readMultiRobotGraph(folder.string(), damaged));
  }
}

TEST(MultiRobotGraph, SplitGraphFoldersAreCheckedFileByFile) {
  struct Case {
    std::string name;
    std::map<std::string, std::string> files;  ///< a content of "/" makes a folder
    std::vector<std::string> expected;
  };
  const std::string a01 = vertexLine(0, 0) + vertexLine(0, 1) + edgeLine(0, 0, 0, 1);
  const std::string b01 = vertexLine(1, 0) + vertexLine(1, 1) + edgeLine(1, 0, 1, 1);
  const std::vector<Case> cases = {
      {"gap", {{"0.g2o", a01}, {"2.g2o", b01}}, {"gap: 1.g2o is missing", "the next is 2.g2o"}},
      {"folder_named_g2o", {{"0.g2o", a01}, {"1.g2o", "/"}}, {"1.g2o: is not a regular file"}},
      {"number_twice",
       {{"0.g2o", a01}, {"1.g2o", b01}, {"01.g2o", b01}},
       {"are both robot graph 1"}},
      {"vertex_twice",
       {{"0.g2o", a01}, {"1.g2o", vertexLine(1, 0) + vertexLine(0, 1)}},
       {"1.g2o:2: field 'id': vertex a1 is defined in 0.g2o line 2 already"}},
      {"vertex_of_another_robot",
       {{"0.g2o", a01}, {"1.g2o", vertexLine(1, 0) + vertexLine(0, 2)}},
       {"1.g2o:2: field 'id': vertex a2 is robot a's, but this file holds robot b's (line 1)"}},
      {"robot_in_two_files",
       {{"0.g2o", a01}, {"1.g2o", vertexLine(0, 2) + edgeLine(0, 1, 0, 2)}},
       {"1.g2o:1: field 'id': robot a's vertices are in 0.g2o line 1 already"}},
      {"edge_to_nowhere",
       {{"0.g2o", a01 + edgeLine(0, 1, 1, 5)}, {"1.g2o", b01}},
       {"0.g2o:4: field 'to': edge to vertex b5, which no robot graph of the folder defines"}},
      {"robot_file_without_vertices",  // not chained: its edges' ends are defined nowhere
       {{"0.g2o", a01}, {"1.g2o", edgeLine(1, 0, 1, 1)}},
       {"1.g2o:1: field 'from': edge to vertex b0, which no robot graph"}},
  };
  for (const Case& c : cases) {
    const fs::path dir = scratchFolder(c.name);
    for (const auto& [name, content] : c.files) {
      if (content == "/") {
        fs::create_directory(dir / name);
      } else {
        std::ofstream(dir / name) << content;
      }
    }
    const std::string message = fileError([&] { (void)readMultiRobotGraph(dir.string()); });
    for (const std::string& part : c.expected) {
      EXPECT_NE(message.find(part), std::string::npos) << c.name << ": " << message;
    }
  }
  // The same robots, well formed: each loop once, whichever files hold it.
  const fs::path dir = scratchFolder("well_formed");
  std::ofstream(dir / "0.g2o") << a01 + edgeLine(0, 1, 1, 0);
  std::ofstream(dir / "1.g2o") << b01 + edgeLine(0, 1, 1, 0);
  std::ofstream(dir / "notes.txt") << "not a graph\n";
  const PoseGraph graph = readMultiRobotGraph(dir.string());
  EXPECT_EQ(graph.size(), 4U);
  EXPECT_EQ(graph.factors().size(), 3U);
  fs::remove_all(dir.parent_path());
}

TEST(MultiRobotGraph, AnEdgeToAVertexTheFileDoesNotDefineIsRefused) {
  const fs::path dir = scratchFolder("one_file");
  const fs::path file = dir / "graph.g2o";
  std::ofstream(file) << vertexLine(0, 0) + vertexLine(0, 1) + edgeLine(0, 0, 0, 1) +
                             edgeLine(0, 1, 1, 3);
  const std::string message = fileError([&] { (void)readMultiRobotGraph(file.string()); });
  EXPECT_NE(message.find("graph.g2o:4: field 'to': edge to vertex b3, which the file does not "
                         "define"),
            std::string::npos)
      << message;
  // Without vertex lines the vertices are chained from the edges: all defined.
  std::ofstream(file) << edgeLine(0, 0, 0, 1) + edgeLine(0, 1, 1, 3);
  EXPECT_EQ(readMultiRobotGraph(file.string()).size(), 3U);
  fs::remove_all(dir.parent_path());
}

}  // namespace
}  // namespace dcl::io
