// The ROS 2 node on DDS: two nodes of this process on loopback, in a domain of
// their own (70), exchange each kind of message with ROS 2's QoS profiles.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/point_cloud2.hpp>
#include <dcl/ros/ros2_node.hpp>

#include "../common/kitti_test_data.hpp"
#include "nav_msgs.h"
#include "rmw_dds_common.h"

namespace dcl::ros2 {
namespace {

using namespace std::chrono_literals;

/// The domain of this file's nodes and plain DDS readers.
constexpr std::uint32_t kDomain = 70;

NodeConfig loopback() {
  NodeConfig config;
  config.domain = kDomain;
  config.interface = "lo";
  return config;
}

/// A topic of this test process alone (ctest runs test processes in parallel).
std::string topic(const std::string& name) {
  return "/dcl_test_" + std::to_string(::getpid()) + "/" + name;
}

/// Spins `receiver` (publishing with `publish` every 50 ms) until `done` or 20 s.
bool exchange(Node& receiver, const std::function<void()>& publish,
              const std::function<bool()>& done) {
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (std::chrono::steady_clock::now() < deadline) {
    publish();
    receiver.spin(50ms);
    if (done()) return true;
  }
  return false;
}

TEST(Ros2Node, TopicNamesAreRos2s) {
  EXPECT_EQ(ddsTopicName("/velodyne_points"), "rt/velodyne_points");
  EXPECT_EQ(ddsTopicName("a/odom"), "rt/a/odom");
  for (const char* bad : {"", "/", "//odom", "/a//odom", "/odom/", "/2d", "/a b", "/o-dom"}) {
    EXPECT_THROW(ddsTopicName(bad), core::Error) << bad;
  }
}

TEST(Ros2Node, TwoNodesExchangeOdometryAndAFullScan) {
  Node a(loopback()), b(loopback());
  Odometry sent;
  sent.header = {1317384506.25, "odom"};
  sent.child_frame_id = "base_link";
  sent.pose = core::makePose(Eigen::Vector3d(1, 2, 3),
                             Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ())));
  sent.linear_velocity = {8, 0, 0};
  a.advertise<Odometry>(topic("odom"), Qos::reliable);
  std::optional<Odometry> got;
  b.subscribe<Odometry>(topic("odom"), Qos::reliable, [&](Odometry&& m) { got = std::move(m); });
  ASSERT_TRUE(exchange(
      b, [&] { a.publish(topic("odom"), sent); }, [&] { return got.has_value(); }));
  EXPECT_EQ(got->header.stamp, sent.header.stamp);
  EXPECT_EQ(got->header.frame_id, "odom");
  EXPECT_EQ(got->child_frame_id, "base_link");
  EXPECT_TRUE(got->pose.isApprox(sent.pose, 1e-12));
  EXPECT_EQ(got->linear_velocity, sent.linear_velocity);
  EXPECT_GE(a.matched(topic("odom")), 1u);

  // A whole HDL-64 scan (about 2.9 MB) as a driver sends it, best effort.
  const core::PointCloud scan = test::kittiScan(0);
  const PointCloud2 cloud = toPointCloud2(scan, {1317384506.5, "velodyne"});
  a.advertise<PointCloud2>(topic("points"), Qos::sensor_data);
  std::optional<core::PointCloud> received;
  b.subscribe<PointCloud2>(topic("points"), Qos::sensor_data, [&](PointCloud2&& m) {
    received = io::decodePointCloud2(m.view(), m.header.stamp, true);
  });
  ASSERT_TRUE(exchange(
      b, [&] { a.publish(topic("points"), cloud); }, [&] { return received.has_value(); }));
  ASSERT_EQ(received->size(), scan.size());
  EXPECT_EQ(received->points, scan.points);
  EXPECT_EQ(received->intensity, scan.intensity);
}

TEST(Ros2Node, ALatchedPathReachesALateSubscriber) {
  Node a(loopback());
  Path path;
  path.header = {10.0, "map"};
  for (int i = 0; i < 5; ++i) {
    path.poses.push_back(
        {{10.0 + i, "map"},
         core::makePose(Eigen::Vector3d(i, 0, 0), Eigen::Quaterniond::Identity())});
  }
  a.advertise<Path>(topic("path"), Qos::transient_local);
  a.publish(topic("path"), path);
  Node b(loopback());  // joins after the path was published, once
  std::optional<Path> got;
  b.subscribe<Path>(topic("path"), Qos::transient_local, [&](Path&& m) { got = std::move(m); });
  ASSERT_TRUE(exchange(
      b, [] {}, [&] { return got.has_value(); }));
  ASSERT_EQ(got->poses.size(), 5u);
  EXPECT_EQ(got->poses[4].header.stamp, 14.0);
}

TEST(Ros2Node, AMessageItsTypeCannotHoldIsCountedNotDelivered) {
  Node a(loopback()), b(loopback());
  TFMessage bad;
  bad.transforms.resize(1);
  bad.transforms[0].header = {1.0, "map"};
  bad.transforms[0].child_frame_id = "odom";
  bad.transforms[0].transform.translation().x() = std::numeric_limits<double>::quiet_NaN();
  a.advertise<TFMessage>(topic("tf"), Qos::reliable);
  std::size_t delivered = 0;
  b.subscribe<TFMessage>(topic("tf"), Qos::reliable, [&](TFMessage&&) { ++delivered; });
  ASSERT_TRUE(exchange(
      b, [&] { a.publish(topic("tf"), bad); }, [&] { return b.refused().count(topic("tf")) > 0; }));
  EXPECT_EQ(delivered, 0u);
  EXPECT_NE(b.refused().at(topic("tf")).second.find("not finite"), std::string::npos);
}

TEST(Ros2Node, SamplesGoOnTheWireAsRos2sPlainLittleEndianCdr) {
  // A plain DDS reader of "rt/<topic>" with ROS 2's type takes the sample as
  // it travelled: the encapsulation says CDR little-endian (XCDR1), and the
  // bytes after it are the byte codec's.
  Node a(loopback());
  const std::string name = topic("wire");
  a.advertise<Odometry>(name, Qos::reliable);
  const dds_entity_t participant = dds_create_participant(kDomain, nullptr, nullptr);
  ASSERT_GT(participant, 0);
  const dds_entity_t t = dds_create_topic(participant, &nav_msgs_msg_dds__Odometry__desc,
                                          ddsTopicName(name).c_str(), nullptr, nullptr);
  ASSERT_GT(t, 0);
  const dds_entity_t reader = dds_create_reader(participant, t, nullptr, nullptr);
  ASSERT_GT(reader, 0);
  Odometry sent;
  sent.header = {5.5, "odom"};
  sent.child_frame_id = "base_link";
  std::vector<unsigned char> wire;
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (wire.empty() && std::chrono::steady_clock::now() < deadline) {
    a.publish(name, sent);
    std::this_thread::sleep_for(50ms);
    ddsi_serdata* sample = nullptr;
    dds_sample_info_t info;
    if (dds_takecdr(reader, &sample, 1, &info, DDS_ANY_STATE) == 1) {
      if (info.valid_data) {
        wire.resize(ddsi_serdata_size(sample));
        ddsi_serdata_to_ser(sample, 0, wire.size(), wire.data());
      }
      ddsi_serdata_unref(sample);
    }
  }
  dds_delete(participant);
  ASSERT_GE(wire.size(), 4u);
  EXPECT_EQ(wire[0], 0x00);
  EXPECT_EQ(wire[1], 0x01);
  const std::vector<std::uint8_t> ours = encode(sent);
  // The wire pads the payload to a multiple of 4 and says so in the options.
  ASSERT_GE(wire.size(), ours.size());
  EXPECT_TRUE(std::equal(ours.begin() + 4, ours.end(), wire.begin() + 4));
}

TEST(Ros2Node, ItNamesItselfAndItsEntitiesOnRosDiscoveryInfo) {
  // What rmw_cyclonedds reads to list nodes (ros2 node list, rqt_graph): the
  // participant's GUID, the node's name, and its readers' and writers' GUIDs.
  NodeConfig config = loopback();
  config.name = "dcl_test_node_" + std::to_string(::getpid());
  Node a(config);
  a.advertise<Odometry>(topic("announced_odometry"), Qos::reliable);
  a.advertise<Path>(topic("announced_path"), Qos::transient_local);
  a.subscribe<PointCloud2>(topic("announced_points"), Qos::sensor_data, [](PointCloud2&&) {});
  const dds_entity_t participant = dds_create_participant(kDomain, nullptr, nullptr);
  ASSERT_GT(participant, 0);
  const dds_entity_t t =
      dds_create_topic(participant, &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc,
                       "ros_discovery_info", nullptr, nullptr);
  ASSERT_GT(t, 0);
  // Transient local, as the writer: the node's last word reaches a late reader.
  // Every sample kept: the topic has no key, and the nodes of tests running
  // beside this one in the domain publish on it too; a history of one would
  // keep only the last of theirs.
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_durability(qos, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);
  const dds_entity_t reader = dds_create_reader(participant, t, qos, nullptr);
  dds_delete_qos(qos);
  ASSERT_GT(reader, 0);
  bool found = false;
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (!found && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(50ms);
    void* samples[8] = {};
    dds_sample_info_t infos[8];
    const dds_return_t n = dds_take(reader, samples, infos, 8, 8);
    for (dds_return_t i = 0; i < n; ++i) {
      const auto& info =
          *static_cast<const rmw_dds_common_msg_dds__ParticipantEntitiesInfo_*>(samples[i]);
      if (!infos[i].valid_data || info.node_entities_info_seq._length != 1) continue;
      const auto& node = info.node_entities_info_seq._buffer[0];
      if (std::string(node.node_name) != config.name) continue;  // another test's node
      if (node.writer_gid_seq._length < 2 || node.reader_gid_seq._length < 1) continue;
      found = true;
      EXPECT_EQ(std::string(node.node_namespace), "/");
      EXPECT_EQ(node.writer_gid_seq._length, 2u);
      EXPECT_EQ(node.reader_gid_seq._length, 1u);
      // A GUID's 16 bytes, then zeros; the participant's prefix starts its entities'.
      for (int k = 16; k < 24; ++k) EXPECT_EQ(info.gid.data[k], 0);
      for (int k = 0; k < 12; ++k)
        EXPECT_EQ(node.writer_gid_seq._buffer[0].data[k], info.gid.data[k]);
    }
    if (n > 0) dds_return_loan(reader, samples, n);
  }
  dds_delete(participant);
  EXPECT_TRUE(found);
}

TEST(Ros2Node, MisuseIsAnError) {
  Node a(loopback());
  EXPECT_THROW(a.publish(topic("never"), Path{}), core::Error);  // not advertised
  a.advertise<Path>(topic("p"), Qos::reliable);
  EXPECT_THROW(a.advertise<Path>(topic("p"), Qos::sensor_data), core::Error);
  EXPECT_THROW(a.advertise<Odometry>(topic("p"), Qos::reliable), core::Error);
  NodeConfig far = loopback();
  far.domain = 400;
  EXPECT_THROW(Node{far}, core::Error);
}

}  // namespace
}  // namespace dcl::ros2
