// The ROS 1 node's checks that need no master: graph names, and a master that
// does not answer (roscore itself is run by cli.Ros1Robot).

#include <chrono>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/ros/ros1_node.hpp>

namespace dcl::ros1 {
namespace {

TEST(Ros1Names, TakesGraphNamesAndRefusesTheRest) {
  for (const std::string name : {"/points", "points", "/a/odometry", "a_1/b2/c", "/tf"}) {
    EXPECT_NO_THROW(checkTopicName(name)) << name;
  }
  for (const std::string& name : std::vector<std::string>{
           "", "/", "//a", "/a/", "/1a", "a b", "/a/-b", "a//b", "~a", std::string(256, 'a')}) {
    EXPECT_THROW(checkTopicName(name), core::Error) << name;
  }
  try {
    checkTopicName("/a b");
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("'/a b'"), std::string::npos) << e.what();
  }
}

TEST(Ros1Node, AMasterThatDoesNotAnswerIsNamedInBoundedTime) {
  if (!available()) GTEST_SKIP() << "built without roscpp";
  // Port 1 on loopback: nothing listens there.
  const auto start = std::chrono::steady_clock::now();
  try {
    Node node({.name = "dcl_test", .master_uri = "http://127.0.0.1:1", .master_wait = 0.5});
    FAIL() << "a node joined without a master";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("http://127.0.0.1:1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("roscore"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(20));
}

}  // namespace
}  // namespace dcl::ros1
