#pragma once

/// Transport over Eclipse Cyclone DDS (C API), one participant per robot
/// process (DESIGN.md §4). Peers are found by DDS discovery on the local
/// network; every message travels as one sample of a single envelope type
/// (idl/envelope.idl: sender, receiver, kind, the encoded message's bytes) on
/// one of two topics: reliable QoS for measurements, optimisation and
/// summaries, best effort for heartbeats and descriptors (qosOf). The swarm
/// name is the DDS partition and the domain id the DDS domain, so separate
/// swarms on one network stay apart. DDS delivers every sample to every
/// reader; samples addressed to another robot are dropped here, unseen by
/// the Messenger above.
///
/// Cyclone's own configuration (network interface, multicast, peers) comes
/// from the CYCLONEDDS_URI environment variable as usual; `interface`
/// overrides it with a one-interface configuration (e.g. "lo" for robots on
/// one machine).

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <dcl/comm/transport.hpp>
#include <dcl/core/ids.hpp>

namespace dcl::comm {

/// Whether `text` holds only ASCII letters, digits and the characters of `extra`.
inline bool isPlainName(std::string_view text, std::string_view extra) {
  return std::all_of(text.begin(), text.end(), [&](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           extra.find(c) != std::string_view::npos;
  });
}

struct DdsConfig {
  static constexpr std::uint32_t kMaxDomain = 232;     ///< DDSI ports: 7400 + 250 * domain < 65536
  static constexpr std::uint32_t kMaxHistory = 65536;  ///< samples kept at most
  static constexpr std::size_t kMaxSwarmChars = 64;    ///< swarm name length at most
  static constexpr std::size_t kMaxInterfaceChars = 15;  ///< IFNAMSIZ - 1 on Linux

  /// DDS domain id (0..232).
  std::uint32_t domain = 0;
  /// Swarm name: the DDS partition. Robots of other swarms are never heard.
  std::string swarm = "dcl";
  /// Network interface to use, with multicast discovery on it (e.g. "lo");
  /// empty: Cyclone's default or CYCLONEDDS_URI.
  std::string interface;
  /// Samples kept per reader and writer (KEEP_LAST depth).
  std::uint32_t history = 256;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("domain", domain, "DDS domain id (0..232)").atMost(kMaxDomain);
    // Partition names match with wildcards ('*', '?'): a swarm named "*" would hear every swarm.
    v.field("swarm", swarm, "swarm name: the DDS partition")
        .rule(!swarm.empty() && swarm.size() <= kMaxSwarmChars && isPlainName(swarm, "_-.:/"),
              "must be 1..64 letters, digits or '_', '-', '.', ':', '/'");
    v.field("interface", interface, "network interface with multicast discovery (empty: default)")
        .rule(interface.size() <= kMaxInterfaceChars && isPlainName(interface, "_-.:"),
              "must be empty or a network interface name (up to 15 letters, digits or '_', '-', "
              "'.', ':')");
    v.field("history", history, "samples kept per reader and writer").within(1, kMaxHistory);
  }
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const DdsConfig& config);

class DdsTransport final : public Transport {
 public:
  /// Joins the swarm as robot `self`. Throws core::Error when DDS cannot
  /// create the participant, topics, readers or writers (the message names
  /// the call and DDS' reason).
  DdsTransport(core::RobotId self, const DdsConfig& config = {});
  ~DdsTransport() override;
  DdsTransport(const DdsTransport&) = delete;
  DdsTransport& operator=(const DdsTransport&) = delete;

  [[nodiscard]] core::RobotId self() const override;
  void send(std::optional<core::RobotId> to, MessageKind kind,
            std::span<const std::uint8_t> bytes) override;
  std::vector<Datagram> receive() override;

  /// Blocks until a sample arrives or `timeout` passes; true when one arrived.
  bool wait(std::chrono::milliseconds timeout);

  /// Samples DDS refused to write (a full history, a deleted entity).
  [[nodiscard]] std::size_t failedWrites() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dcl::comm
