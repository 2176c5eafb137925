#pragma once

// The ROS 2 messages' generated C types (idl/ros2) and the conversions between
// them and dcl::ros2's values, shared by the byte codec and the DDS node.
// Private to the ros module.

#include <string>
#include <vector>

#include <dds/dds.h>

#include <dcl/ros/ros2_messages.hpp>

#include "builtin_interfaces.h"
#include "geometry_msgs.h"
#include "nav_msgs.h"
#include "sensor_msgs.h"
#include "std_msgs.h"
#include "tf2_msgs.h"
#include "visualization_msgs.h"

namespace dcl::ros2::detail {

/// Per message type M: its C type, its DDS type descriptor, `Out` (M as the C
/// type, pointing into M and into storage of its own: M must outlive it) and
/// `in` (the C type to M; throws core::Error on values M cannot hold).
template <class M>
struct Wire;

template <>
struct Wire<PointCloud2> {
  using C = sensor_msgs_msg_dds__PointCloud2_;
  static const dds_topic_descriptor_t& descriptor() {
    return sensor_msgs_msg_dds__PointCloud2__desc;
  }
  class Out {
   public:
    explicit Out(const PointCloud2& m);
    [[nodiscard]] const C* get() const { return &c_; }

   private:
    std::vector<sensor_msgs_msg_dds__PointField_> fields_;
    C c_{};
  };
  static PointCloud2 in(const C& c);
};

template <>
struct Wire<Imu> {
  using C = sensor_msgs_msg_dds__Imu_;
  static const dds_topic_descriptor_t& descriptor() { return sensor_msgs_msg_dds__Imu__desc; }

  class Out {
   public:
    explicit Out(const Imu& m);
    [[nodiscard]] const C* get() const { return &c_; }

   private:
    C c_{};
  };
  static Imu in(const C& c);
};

template <>
struct Wire<Odometry> {
  using C = nav_msgs_msg_dds__Odometry_;
  static const dds_topic_descriptor_t& descriptor() { return nav_msgs_msg_dds__Odometry__desc; }
  class Out {
   public:
    explicit Out(const Odometry& m);
    [[nodiscard]] const C* get() const { return &c_; }

   private:
    C c_{};
  };
  static Odometry in(const C& c);
};

template <>
struct Wire<PoseStamped> {
  using C = geometry_msgs_msg_dds__PoseStamped_;
  static const dds_topic_descriptor_t& descriptor() {
    return geometry_msgs_msg_dds__PoseStamped__desc;
  }
  class Out {
   public:
    explicit Out(const PoseStamped& m);
    [[nodiscard]] const C* get() const { return &c_; }

   private:
    C c_{};
  };
  static PoseStamped in(const C& c);
};

template <>
struct Wire<Path> {
  using C = nav_msgs_msg_dds__Path_;
  static const dds_topic_descriptor_t& descriptor() { return nav_msgs_msg_dds__Path__desc; }
  class Out {
   public:
    explicit Out(const Path& m);
    [[nodiscard]] const C* get() const { return &c_; }

   private:
    std::vector<geometry_msgs_msg_dds__PoseStamped_> poses_;
    C c_{};
  };
  static Path in(const C& c);
};

template <>
struct Wire<TFMessage> {
  using C = tf2_msgs_msg_dds__TFMessage_;
  static const dds_topic_descriptor_t& descriptor() { return tf2_msgs_msg_dds__TFMessage__desc; }
  class Out {
   public:
    explicit Out(const TFMessage& m);
    [[nodiscard]] const C* get() const { return &c_; }

   private:
    std::vector<geometry_msgs_msg_dds__TransformStamped_> transforms_;
    C c_{};
  };
  static TFMessage in(const C& c);
};

template <>
struct Wire<MarkerArray> {
  using C = visualization_msgs_msg_dds__MarkerArray_;
  static const dds_topic_descriptor_t& descriptor() {
    return visualization_msgs_msg_dds__MarkerArray__desc;
  }
  class Out {
   public:
    explicit Out(const MarkerArray& m);
    [[nodiscard]] const C* get() const { return &c_; }

   private:
    std::vector<std::vector<geometry_msgs_msg_dds__Point_>> points_;
    std::vector<std::vector<std_msgs_msg_dds__ColorRGBA_>> colors_;
    std::vector<visualization_msgs_msg_dds__Marker_> markers_;
    C c_{};
  };
  static MarkerArray in(const C& c);
};

}  // namespace dcl::ros2::detail
