#pragma once

/// Watching a run live in Foxglove (or Lichtblick): a server of the Foxglove
/// WebSocket protocol (subprotocol foxglove.websocket.v1), its channels
/// advertised to every client that connects, each message sent to the
/// clients subscribed to its channel. The protocol's pieces are plain
/// functions (what the server says, what it reads from a client); the
/// server runs its network in a thread of its own. This header stays C++17
/// so that the server's file can include websocketpp, which is not C++20.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace dcl::viz {

/// What a channel carries: JSON messages of a named schema (JSON Schema).
struct Channel {
  std::string topic;
  std::string schema_name;  ///< e.g. foxglove.PosesInFrame
  std::string schema;       ///< its JSON Schema, as text
};

// ---- the protocol -------------------------------------------------------------------

/// The serverInfo message a client gets first.
std::string serverInfo(const std::string& name);

/// The advertise message of `channels`, channel i's id being ids[i].
std::string advertise(const std::vector<Channel>& channels, const std::vector<std::uint32_t>& ids);

/// A binary messageData frame: opcode 1, the client's subscription id, the
/// stamp in ns, the payload.
std::string messageData(std::uint32_t subscription, std::uint64_t stamp_ns,
                        std::string_view payload);

/// What a client asked: subscriptions (subscription id, channel id) to add,
/// subscription ids to drop. Anything else a client may say (other
/// operations) is `ignored`.
struct ClientRequest {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> subscribe;
  std::vector<std::uint32_t> unsubscribe;
  bool ignored = false;
};

/// Reads a client's text message. Throws core::Error naming what is wrong
/// for text that is not the protocol's JSON (too long, not JSON, ids out of
/// range, more than kMaxSubscriptions at once).
ClientRequest parseClientMessage(std::string_view text);

inline constexpr std::size_t kMaxClientMessage = 64 * 1024;  ///< bytes of one client message
inline constexpr std::size_t kMaxSubscriptions = 1024;       ///< per message and per client

// ---- the server ---------------------------------------------------------------------

/// Serves `channels` on `port` (0: any free one) of `address` until destroyed.
/// Throws core::Error when it cannot listen there.
class Server {
 public:
  Server(const std::string& name, std::uint16_t port, const std::vector<Channel>& channels,
         const std::string& address = "127.0.0.1");
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// The port it listens on.
  [[nodiscard]] std::uint16_t port() const;
  /// Clients connected now.
  [[nodiscard]] std::size_t clients() const;
  /// Whether some client is subscribed to channel `channel` now: what only
  /// a subscriber would see need not be built.
  [[nodiscard]] bool subscribed(std::size_t channel) const;
  /// Sends `payload` (JSON) on channel `channel` (its index in the
  /// constructor's list) to every client subscribed to it. A client that
  /// does not keep up (more than a few MB waiting) misses messages.
  void publish(std::size_t channel, std::uint64_t stamp_ns, std::string payload);
  /// Client messages refused as not the protocol's, and messages not sent
  /// to a client that did not keep up.
  [[nodiscard]] std::size_t refused() const;
  [[nodiscard]] std::size_t dropped() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dcl::viz
