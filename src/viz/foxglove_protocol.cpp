// The Foxglove WebSocket protocol's messages (foxglove.websocket.v1): what
// the server says, and what it reads from a client, checked field by field.
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/core/error.hpp>
#include <dcl/viz/foxglove.hpp>

namespace dcl::viz {
namespace {

using Json = nlohmann::json;

/// An id of the protocol: a whole number in [0, 2^32).
std::uint32_t idOf(const Json& value, const char* what) {
  if (!value.is_number_unsigned() && !(value.is_number_integer() && value.get<std::int64_t>() >= 0))
    throw core::Error(fmt::format("client message: {} is not a whole number >= 0", what));
  const auto v = value.get<std::uint64_t>();
  if (v > 0xFFFFFFFFULL)
    throw core::Error(fmt::format("client message: {} {} is beyond 32 bits", what, v));
  return static_cast<std::uint32_t>(v);
}

const Json& arrayField(const Json& message, const char* name) {
  const auto it = message.find(name);
  if (it == message.end() || !it->is_array())
    throw core::Error(fmt::format("client message: no array '{}'", name));
  if (it->size() > kMaxSubscriptions)
    throw core::Error(fmt::format("client message: {} entries in '{}', at most {}", it->size(),
                                  name, kMaxSubscriptions));
  return *it;
}

}  // namespace

std::string serverInfo(const std::string& name) {
  return Json{{"op", "serverInfo"},
              {"name", name},
              {"capabilities", Json::array()},
              {"supportedEncodings", Json::array()},
              {"metadata", Json::object()}}
      .dump();
}

std::string advertise(const std::vector<Channel>& channels, const std::vector<std::uint32_t>& ids) {
  if (ids.size() != channels.size())
    throw core::Error(
        fmt::format("advertise: {} ids for {} channels", ids.size(), channels.size()));
  Json list = Json::array();
  for (std::size_t i = 0; i < channels.size(); ++i) {
    list.push_back({{"id", ids[i]},
                    {"topic", channels[i].topic},
                    {"encoding", "json"},
                    {"schemaName", channels[i].schema_name},
                    {"schema", channels[i].schema}});
  }
  return Json{{"op", "advertise"}, {"channels", list}}.dump();
}

std::string messageData(std::uint32_t subscription, std::uint64_t stamp_ns,
                        std::string_view payload) {
  std::string frame;
  frame.reserve(13 + payload.size());
  frame.push_back('\x01');
  for (int k = 0; k < 4; ++k) frame.push_back(static_cast<char>((subscription >> (8 * k)) & 0xFF));
  for (int k = 0; k < 8; ++k) frame.push_back(static_cast<char>((stamp_ns >> (8 * k)) & 0xFF));
  frame.append(payload);
  return frame;
}

ClientRequest parseClientMessage(std::string_view text) {
  if (text.size() > kMaxClientMessage)
    throw core::Error(
        fmt::format("client message: {} bytes, at most {}", text.size(), kMaxClientMessage));
  const Json message = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (message.is_discarded()) throw core::Error("client message: not JSON");
  if (!message.is_object()) throw core::Error("client message: not a JSON object");
  const auto op = message.find("op");
  if (op == message.end() || !op->is_string()) throw core::Error("client message: no 'op'");
  ClientRequest request;
  if (*op == "subscribe") {
    for (const Json& s : arrayField(message, "subscriptions")) {
      if (!s.is_object() || !s.contains("id") || !s.contains("channelId"))
        throw core::Error("client message: a subscription without 'id' and 'channelId'");
      request.subscribe.emplace_back(idOf(s["id"], "a subscription id"),
                                     idOf(s["channelId"], "a channel id"));
    }
  } else if (*op == "unsubscribe") {
    for (const Json& id : arrayField(message, "subscriptionIds"))
      request.unsubscribe.push_back(idOf(id, "a subscription id"));
  } else {
    request.ignored = true;  // operations of capabilities this server does not offer
  }
  return request;
}

}  // namespace dcl::viz
