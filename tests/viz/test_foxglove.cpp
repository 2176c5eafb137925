#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <dcl/core/error.hpp>
#include <dcl/viz/foxglove.hpp>

namespace dcl::viz {
namespace {

using Json = nlohmann::json;

TEST(Foxglove, ServerInfoAndAdvertiseSayWhatTheProtocolAsks) {
  const Json info = Json::parse(serverInfo("dcl-slam"));
  EXPECT_EQ(info["op"], "serverInfo");
  EXPECT_EQ(info["name"], "dcl-slam");
  EXPECT_TRUE(info["capabilities"].is_array());
  const std::vector<Channel> channels{
      {"/a/path", "foxglove.PosesInFrame", "{}"},
      {"/a/counters", "dcl_slam.Counters", "{\"type\":\"object\"}"}};
  const Json ad = Json::parse(advertise(channels, {1, 2}));
  EXPECT_EQ(ad["op"], "advertise");
  ASSERT_EQ(ad["channels"].size(), 2u);
  EXPECT_EQ(ad["channels"][1]["id"], 2);
  EXPECT_EQ(ad["channels"][1]["topic"], "/a/counters");
  EXPECT_EQ(ad["channels"][1]["encoding"], "json");
  EXPECT_EQ(ad["channels"][1]["schemaName"], "dcl_slam.Counters");
  EXPECT_EQ(ad["channels"][1]["schema"], "{\"type\":\"object\"}");
  EXPECT_THROW(advertise(channels, {1}), core::Error);
}

TEST(Foxglove, MessageDataIsOpcodeSubscriptionStampPayloadLittleEndian) {
  const std::string frame = messageData(0x01020304U, 0x1122334455667788ULL, "{}");
  const std::string expected("\x01\x04\x03\x02\x01\x88\x77\x66\x55\x44\x33\x22\x11{}", 15);
  EXPECT_EQ(frame, expected);
}

TEST(Foxglove, ReadsSubscribeAndUnsubscribe) {
  const ClientRequest s = parseClientMessage(
      R"({"op":"subscribe","subscriptions":[{"id":0,"channelId":1},{"id":4294967295,"channelId":2}]})");
  ASSERT_EQ(s.subscribe.size(), 2u);
  EXPECT_EQ(s.subscribe[0], std::make_pair(0U, 1U));
  EXPECT_EQ(s.subscribe[1], std::make_pair(4294967295U, 2U));
  EXPECT_FALSE(s.ignored);
  const ClientRequest u = parseClientMessage(R"({"op":"unsubscribe","subscriptionIds":[3,7]})");
  EXPECT_EQ(u.unsubscribe, (std::vector<std::uint32_t>{3, 7}));
  // Operations of capabilities the server does not offer are passed over.
  EXPECT_TRUE(parseClientMessage(R"({"op":"getParameters","parameterNames":[]})").ignored);
}

TEST(Foxglove, RefusesWhatIsNotTheProtocolNamingWhy) {
  const auto why = [](const std::string& text) {
    try {
      parseClientMessage(text);
    } catch (const core::Error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(why("not json").find("not JSON"), std::string::npos);
  EXPECT_NE(why("[1,2]").find("not a JSON object"), std::string::npos);
  EXPECT_NE(why(R"({"op":3})").find("'op'"), std::string::npos);
  EXPECT_NE(why(R"({"op":"subscribe"})").find("'subscriptions'"), std::string::npos);
  EXPECT_NE(why(R"({"op":"subscribe","subscriptions":[{"id":1}]})").find("channelId"),
            std::string::npos);
  EXPECT_NE(why(R"({"op":"subscribe","subscriptions":[{"id":-1,"channelId":1}]})").find(">= 0"),
            std::string::npos);
  EXPECT_NE(why(R"({"op":"subscribe","subscriptions":[{"id":1.5,"channelId":1}]})").find(">= 0"),
            std::string::npos);
  EXPECT_NE(why(R"({"op":"unsubscribe","subscriptionIds":[4294967296]})").find("32 bits"),
            std::string::npos);
  EXPECT_NE(why(R"({"op":"unsubscribe","subscriptionIds":["1"]})").find(">= 0"), std::string::npos);
  std::string many = R"({"op":"unsubscribe","subscriptionIds":[0)";
  for (std::size_t i = 0; i < kMaxSubscriptions; ++i) many += ",0";
  EXPECT_NE(why(many + "]}").find("at most"), std::string::npos);
  EXPECT_NE(why(std::string(kMaxClientMessage + 1, ' ')).find("bytes"), std::string::npos);
}

TEST(Foxglove, ServerListensOnAFreePortAndNamesOneItCannotHave) {
  const std::vector<Channel> channels{{"/a/path", "foxglove.PosesInFrame", "{}"}};
  Server server("test", 0, channels);
  ASSERT_GT(server.port(), 0);
  EXPECT_EQ(server.clients(), 0u);
  server.publish(0, 1, "{}");  // nobody listens: nothing to send
  EXPECT_THROW(server.publish(1, 1, "{}"), core::Error);
  try {
    Server taken("test", server.port(), channels);
    FAIL() << "a second server on port " << server.port();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find(std::to_string(server.port())), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(Server("test", 0, channels, "not an address"), core::Error);
}

}  // namespace
}  // namespace dcl::viz
