// A ROS 1 node through roscpp (ros1_node.hpp). Messages travel as bytes in
// topic_tools::ShapeShifter, roscpp's type-erased message, with the type's
// name, MD5 sum and definition from ros1_messages.hpp: no generated ROS 1
// message header is compiled. roscpp's threads read the sockets; callbacks
// wait in this node's own queue until spin().
#include <atomic>
#include <thread>

#include <fmt/format.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <topic_tools/shape_shifter.h>

#include <dcl/ros/ros1_node.hpp>

namespace dcl::ros1 {

namespace {

using core::Error;

/// One node per process: roscpp keeps its connection to the master, its
/// threads and its topics in globals.
std::atomic<bool> node_alive{false};

std::uint32_t queueSize(Qos qos, std::int32_t depth) {
  if (depth > 0) return static_cast<std::uint32_t>(depth);
  switch (qos) {
    case Qos::sensor_data:
      return 5;
    case Qos::reliable:
      return 100;
    case Qos::transient_local:
      return 1;
  }
  return 1;
}

}  // namespace

bool available() {
  return true;
}

struct Node::Impl {
  ::ros::CallbackQueue queue;
  std::unique_ptr<::ros::NodeHandle> handle;
  struct Publication {
    ::ros::Publisher publisher;
    const MessageType* type = nullptr;
    bool latch = false;
  };
  std::map<std::string, Publication> publications;
  struct Subscription {
    ::ros::Subscriber subscriber;
    const MessageType* type = nullptr;
    std::function<void(std::span<const std::uint8_t>)> take;
  };
  std::map<std::string, std::unique_ptr<Subscription>> subscriptions;
  std::map<std::string, std::pair<std::size_t, std::string>> refused;
  std::size_t delivered = 0;
  std::vector<std::uint8_t> buffer;

  void refuse(const std::string& topic, std::string why) {
    auto& [count, last] = refused[topic];
    ++count;
    last = std::move(why);
  }

  void deliver(const std::string& topic, Subscription& s,
               const topic_tools::ShapeShifter::ConstPtr& m) {
    if (m->getDataType() != s.type->name) {
      refuse(topic, fmt::format("a {}, not a {}", m->getDataType(), s.type->name));
      return;
    }
    if (m->getMD5Sum() != s.type->md5sum) {
      refuse(topic, fmt::format("{} of another definition (MD5 {}, not {})", s.type->name,
                                m->getMD5Sum(), s.type->md5sum));
      return;
    }
    buffer.resize(m->size());
    ::ros::serialization::OStream out(buffer.data(), static_cast<std::uint32_t>(buffer.size()));
    m->write(out);
    try {
      s.take(buffer);
      ++delivered;
    } catch (const Error& e) {
      refuse(topic, e.what());
    }
  }
};

Node::Node(const NodeConfig& config) : impl_(std::make_unique<Impl>()) {
  if (node_alive.exchange(true)) throw Error("ROS 1: one node per process");
  try {
    checkTopicName(config.name);
    if (config.name.find('/') != std::string::npos) {
      throw Error(fmt::format("ROS 1 node name '{}': no '/' in a node's name", config.name));
    }
    ::ros::M_string remappings;
    if (!config.master_uri.empty()) remappings["__master"] = config.master_uri;
    if (!::ros::isInitialized()) {
      ::ros::init(remappings, config.name,
                  ::ros::init_options::NoSigintHandler | ::ros::init_options::NoRosout);
    }
    // Asked without retrying: a master that does not answer is waited for,
    // a bounded time, here rather than in roscpp's endless retries.
    const auto deadline =
        std::chrono::steady_clock::now() + std::chrono::duration<double>(config.master_wait);
    while (!::ros::master::check()) {
      if (std::chrono::steady_clock::now() > deadline) {
        throw Error(fmt::format(
            "ROS 1: no master answers at {} after {:g} s (start roscore, or set ROS_MASTER_URI)",
            ::ros::master::getURI(), config.master_wait));
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    impl_->handle = std::make_unique<::ros::NodeHandle>();
    impl_->handle->setCallbackQueue(&impl_->queue);
  } catch (const ::ros::Exception& e) {
    node_alive = false;
    throw Error(fmt::format("ROS 1: {}", e.what()));
  } catch (...) {
    node_alive = false;
    throw;
  }
}

Node::~Node() {
  impl_->subscriptions.clear();
  impl_->publications.clear();
  impl_->handle.reset();
  ::ros::shutdown();
  node_alive = false;
}

void Node::advertiseBytes(const std::string& topic, const MessageType& type, Qos qos) {
  checkTopicName(topic);
  if (impl_->publications.count(topic) != 0) {
    throw Error(fmt::format("ROS 1: {} is advertised already", topic));
  }
  ::ros::AdvertiseOptions options(topic, queueSize(qos, 0), std::string(type.md5sum),
                                  std::string(type.name), std::string(type.definition));
  options.latch = qos == Qos::transient_local;
  options.callback_queue = &impl_->queue;
  Impl::Publication p;
  p.publisher = impl_->handle->advertise(options);
  if (!p.publisher) throw Error(fmt::format("ROS 1: cannot advertise {}", topic));
  p.type = &type;
  p.latch = options.latch;
  impl_->publications.emplace(topic, std::move(p));
}

void Node::publishBytes(const std::string& topic, const std::vector<std::uint8_t>& bytes) {
  const auto it = impl_->publications.find(topic);
  if (it == impl_->publications.end()) {
    throw Error(fmt::format("ROS 1: {} was not advertised", topic));
  }
  const MessageType& type = *it->second.type;
  topic_tools::ShapeShifter shape;
  shape.morph(std::string(type.md5sum), std::string(type.name), std::string(type.definition),
              it->second.latch ? "1" : "0");
  ::ros::serialization::IStream in(const_cast<std::uint8_t*>(bytes.data()),
                                   static_cast<std::uint32_t>(bytes.size()));
  shape.read(in);
  it->second.publisher.publish(shape);
}

void Node::subscribeBytes(const std::string& topic, const MessageType& type, Qos qos,
                          std::int32_t depth,
                          std::function<void(std::span<const std::uint8_t>)> take) {
  checkTopicName(topic);
  if (impl_->subscriptions.count(topic) != 0) {
    throw Error(fmt::format("ROS 1: {} is subscribed already", topic));
  }
  auto s = std::make_unique<Impl::Subscription>();
  s->type = &type;
  s->take = std::move(take);
  Impl::Subscription* raw = s.get();
  Impl* impl = impl_.get();
  ::ros::SubscribeOptions options;
  options.init<topic_tools::ShapeShifter>(
      topic, queueSize(qos, depth),
      [impl, raw, topic](const topic_tools::ShapeShifter::ConstPtr& m) {
        impl->deliver(topic, *raw, m);
      });
  options.callback_queue = &impl_->queue;
  if (qos == Qos::sensor_data) options.transport_hints = ::ros::TransportHints().tcpNoDelay();
  s->subscriber = impl_->handle->subscribe(options);
  if (!s->subscriber) throw Error(fmt::format("ROS 1: cannot subscribe to {}", topic));
  impl_->subscriptions.emplace(topic, std::move(s));
}

std::size_t Node::spin(std::chrono::milliseconds timeout) {
  const std::size_t before = impl_->delivered;
  impl_->queue.callAvailable(::ros::WallDuration(static_cast<double>(timeout.count()) / 1000.0));
  return impl_->delivered - before;
}

std::map<std::string, std::pair<std::size_t, std::string>> Node::refused() const {
  return impl_->refused;
}

std::size_t Node::matched(const std::string& topic) const {
  if (const auto p = impl_->publications.find(topic); p != impl_->publications.end()) {
    return p->second.publisher.getNumSubscribers();
  }
  if (const auto s = impl_->subscriptions.find(topic); s != impl_->subscriptions.end()) {
    return s->second->subscriber.getNumPublishers();
  }
  return 0;
}

}  // namespace dcl::ros1
