// The Foxglove WebSocket server on websocketpp and standalone Asio (Debian's
// libwebsocketpp-dev and libasio-dev). websocketpp 0.8 is not C++20, so this
// file alone is compiled as C++17 (src/viz/CMakeLists.txt); the network runs
// in a thread of its own, and everything of a connection is touched there.
#ifndef ASIO_STANDALONE
#define ASIO_STANDALONE
#endif
#include <atomic>
#include <map>
#include <thread>

#include <websocketpp/config/asio_no_tls.hpp>
#include <websocketpp/server.hpp>

#include <dcl/core/error.hpp>
#include <dcl/viz/foxglove.hpp>

namespace dcl::viz {
namespace {

using Endpoint = websocketpp::server<websocketpp::config::asio>;
using Handle = websocketpp::connection_hdl;

constexpr const char* kSubprotocol = "foxglove.websocket.v1";
/// Bytes waiting to go to a client beyond which it misses messages.
constexpr std::size_t kMaxBuffered = 8 * 1024 * 1024;

}  // namespace

struct Server::Impl {
  Endpoint endpoint;
  std::thread thread;
  std::vector<Channel> channels;
  /// Per client: its subscriptions, subscription id -> channel (index).
  std::map<Handle, std::map<std::uint32_t, std::size_t>, std::owner_less<Handle>> clients;
  std::atomic<std::size_t> connected{0};
  /// Per channel: how many subscriptions it has, over every client.
  std::unique_ptr<std::atomic<std::size_t>[]> subscribers;
  std::atomic<std::size_t> refused{0};
  std::atomic<std::size_t> dropped{0};
  std::string info;
  std::string advertised;

  void onOpen(Handle h) {
    clients[h];
    connected = clients.size();
    std::error_code ec;
    endpoint.send(h, info, websocketpp::frame::opcode::text, ec);
    endpoint.send(h, advertised, websocketpp::frame::opcode::text, ec);
  }

  void onClose(Handle h) {
    clients.erase(h);
    connected = clients.size();
    recount();
  }

  void recount() {
    std::vector<std::size_t> count(channels.size(), 0);
    for (const auto& [h, subscriptions] : clients)
      for (const auto& [subscription, channel] : subscriptions) ++count[channel];
    for (std::size_t c = 0; c < count.size(); ++c) subscribers[c] = count[c];
  }

  void onMessage(Handle h, Endpoint::message_ptr message) {
    const auto client = clients.find(h);
    if (client == clients.end()) return;
    try {
      if (message->get_opcode() != websocketpp::frame::opcode::text)
        throw core::Error("client message: binary operations are not offered");
      const ClientRequest request = parseClientMessage(message->get_payload());
      for (const auto& [subscription, channel] : request.subscribe) {
        // Channel ids are 1..n: index + 1.
        if (channel == 0 || channel > channels.size())
          throw core::Error("client message: no channel " + std::to_string(channel));
        if (client->second.size() >= kMaxSubscriptions)
          throw core::Error("client message: too many subscriptions");
        client->second[subscription] = channel - 1;
      }
      for (const std::uint32_t subscription : request.unsubscribe)
        client->second.erase(subscription);
    } catch (const std::exception&) {
      ++refused;  // a client's mistake never stops the server or the run
    }
    recount();
  }

  void send(std::size_t channel, std::uint64_t stamp_ns, const std::string& payload) {
    for (auto& [h, subscriptions] : clients) {
      std::error_code ec;
      const Endpoint::connection_ptr connection = endpoint.get_con_from_hdl(h, ec);
      if (ec) continue;
      for (const auto& [subscription, subscribed] : subscriptions) {
        if (subscribed != channel) continue;
        if (connection->get_buffered_amount() > kMaxBuffered) {
          ++dropped;
          continue;
        }
        endpoint.send(h, messageData(subscription, stamp_ns, payload),
                      websocketpp::frame::opcode::binary, ec);
      }
    }
  }
};

Server::Server(const std::string& name, std::uint16_t port, const std::vector<Channel>& channels,
               const std::string& address)
    : impl_(std::make_unique<Impl>()) {
  Impl& i = *impl_;
  i.channels = channels;
  i.subscribers = std::make_unique<std::atomic<std::size_t>[]>(channels.size());
  std::vector<std::uint32_t> ids;
  for (std::size_t k = 0; k < channels.size(); ++k)
    ids.push_back(static_cast<std::uint32_t>(k + 1));
  i.info = serverInfo(name);
  i.advertised = advertise(channels, ids);
  Endpoint& e = i.endpoint;
  e.clear_access_channels(websocketpp::log::alevel::all);
  e.clear_error_channels(websocketpp::log::elevel::all);
  std::error_code ec;
  e.init_asio(ec);
  if (ec) throw core::Error("--viz: cannot start the network: " + ec.message());
  e.set_reuse_addr(true);
  e.set_validate_handler([&e](Handle h) {
    std::error_code ec;
    const Endpoint::connection_ptr connection = e.get_con_from_hdl(h, ec);
    if (ec) return false;
    for (const std::string& p : connection->get_requested_subprotocols()) {
      if (p == kSubprotocol) {
        connection->select_subprotocol(kSubprotocol, ec);
        return !ec;
      }
    }
    return false;  // not a Foxglove client
  });
  e.set_open_handler([&i](Handle h) { i.onOpen(h); });
  e.set_close_handler([&i](Handle h) { i.onClose(h); });
  e.set_fail_handler([&i](Handle h) { i.onClose(h); });
  e.set_message_handler([&i](Handle h, Endpoint::message_ptr m) { i.onMessage(h, m); });
  asio::error_code aec;
  const asio::ip::address ip = asio::ip::make_address(address, aec);
  if (aec) throw core::Error("--viz: '" + address + "' is not an IP address");
  e.listen(asio::ip::tcp::endpoint(ip, port), ec);
  if (ec) {
    throw core::Error("--viz: cannot listen on " + address + " port " + std::to_string(port) +
                      ": " + ec.message());
  }
  e.start_accept(ec);
  if (ec) throw core::Error("--viz: cannot accept connections: " + ec.message());
  i.thread = std::thread([&e] {
    try {
      e.run();
    } catch (const std::exception&) {
      // The server ends; the run goes on without it.
    }
  });
}

Server::~Server() {
  Impl& i = *impl_;
  asio::post(i.endpoint.get_io_service(), [&i] {
    std::error_code ec;
    i.endpoint.stop_listening(ec);
    for (auto& [h, subscriptions] : i.clients) {
      i.endpoint.close(h, websocketpp::close::status::going_away, "the run ended", ec);
    }
  });
  // The clients get a moment to hear the close; then the network stops.
  asio::post(i.endpoint.get_io_service(), [&i] { i.endpoint.stop(); });
  if (i.thread.joinable()) i.thread.join();
}

std::uint16_t Server::port() const {
  std::error_code ec;
  const auto local = impl_->endpoint.get_local_endpoint(ec);
  return ec ? 0 : local.port();
}

std::size_t Server::clients() const {
  return impl_->connected;
}

bool Server::subscribed(std::size_t channel) const {
  return channel < impl_->channels.size() && impl_->subscribers[channel] > 0;
}

void Server::publish(std::size_t channel, std::uint64_t stamp_ns, std::string payload) {
  if (channel >= impl_->channels.size())
    throw core::Error("viz: no channel " + std::to_string(channel));
  Impl& i = *impl_;
  asio::post(i.endpoint.get_io_service(), [&i, channel, stamp_ns, payload = std::move(payload)] {
    i.send(channel, stamp_ns, payload);
  });
}

std::size_t Server::refused() const {
  return impl_->refused;
}

std::size_t Server::dropped() const {
  return impl_->dropped;
}

}  // namespace dcl::viz
