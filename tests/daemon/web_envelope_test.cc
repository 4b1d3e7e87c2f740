// The gateway's request parsing without a daemon: the WebSocket envelope (a table of good and
// malformed messages, then a deterministic mutation fuzz whose every result must be a parsed
// message or INVALID_ARGUMENT in words), and the static file paths (a table of escapes).
#include <gtest/gtest.h>

#include <random>

#include "daemon/web/envelope.h"
#include "daemon/web/static_files.h"

namespace rheo::daemon::web {
namespace {

TEST(WebEnvelope, ParsesEachKindOfMessage) {
  ClientMessage m;
  ASSERT_TRUE(ParseTextMessage(
                  R"({"id":3,"method":"rheo.v1.SceneService/GetScene","request":{"a":[1,2]}})", &m)
                  .ok());
  EXPECT_EQ(m.kind, ClientMessage::Kind::kOpen);
  EXPECT_EQ(m.id, 3u);
  EXPECT_EQ(m.method, "rheo.v1.SceneService/GetScene");
  EXPECT_TRUE(m.has_payload);
  EXPECT_EQ(m.payload, R"({"a":[1,2]})");
  EXPECT_FALSE(m.stream);
  EXPECT_FALSE(m.binary);

  ASSERT_TRUE(ParseTextMessage(R"({"id":4,"method":"x/y","stream":true,"binary":true})", &m).ok());
  EXPECT_TRUE(m.stream);
  EXPECT_TRUE(m.binary);
  EXPECT_FALSE(m.has_payload);

  ASSERT_TRUE(ParseTextMessage(R"({"id":4,"write":{"leaseId":"L"}})", &m).ok());
  EXPECT_EQ(m.kind, ClientMessage::Kind::kWrite);
  EXPECT_EQ(m.payload, R"({"leaseId":"L"})");
  ASSERT_TRUE(ParseTextMessage(R"({"end":true,"id":4})", &m).ok());
  EXPECT_EQ(m.kind, ClientMessage::Kind::kEnd);
  ASSERT_TRUE(ParseTextMessage(R"({"id":2147483647,"cancel":true})", &m).ok());
  EXPECT_EQ(m.kind, ClientMessage::Kind::kCancel);
  EXPECT_EQ(m.id, kMaxCallId);

  ASSERT_TRUE(ParseBinaryMessage(std::string("\x05\x01\0\0pb", 6), &m).ok());
  EXPECT_EQ(m.id, 261u);
  EXPECT_TRUE(m.payload_is_binary);
  EXPECT_EQ(m.payload, "pb");
}

TEST(WebEnvelope, RefusesMalformedMessagesSayingWhat) {
  struct Case {
    const char* text;
    const char* words;
  };
  const Case cases[] = {
      {"", "not JSON"},
      {"{", "not JSON"},
      {"\xff\xfe", "not JSON"},
      {"null", "JSON object"},
      {"\"id\"", "JSON object"},
      {R"({"id":"1","method":"a"})", "\"id\" must be"},
      {R"({"id":0,"method":"a"})", "\"id\" must be"},
      {R"({"id":2147483648,"method":"a"})", "\"id\" must be"},
      {R"({"id":true,"method":"a"})", "\"id\" must be"},
      {R"({"id":1,"write":{},"end":true})", "exactly one of"},
      {R"({"id":1,"method":null})", "\"method\" must be"},
      {R"({"id":1,"method":"a","request":"x"})", "JSON object"},
      {R"({"id":1,"method":"a","stream":1})", "true or false"},
      {R"({"id":1,"end":"yes"})", "true or false"},
      {R"({"id":1,"end":false})", "must be true"},
      {R"({"id":1,"write":5})", "JSON object"},
      {R"({"id":1,"write":{},"binary":true})", "only \"id\" and \"write\""},
      {R"({"id":1,"method":"a","requests":{}})", "unknown field \"requests\""},
  };
  for (const Case& c : cases) {
    ClientMessage m;
    grpc::Status s = ParseTextMessage(c.text, &m);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << c.text;
    EXPECT_NE(s.error_message().find(c.words), std::string::npos)
        << c.text << " -> " << s.error_message();
  }
  ClientMessage m;
  EXPECT_FALSE(ParseBinaryMessage("abc", &m).ok());
  EXPECT_FALSE(ParseBinaryMessage(std::string("\0\0\0\0", 4), &m).ok());
  EXPECT_FALSE(ParseBinaryMessage(std::string("\xff\xff\xff\xff", 4), &m).ok());
}

TEST(WebEnvelope, MutatedMessagesAreParsedOrRefusedNeverAnythingElse) {
  const std::vector<std::string> seeds = {
      R"({"id":1,"method":"rheo.v1.ObjectService/CreateObject","request":{"name":"a","sketch":{"strokesJson":"{\"width\":10,\"height\":10,\"strokes\":[[[1,2],[3,4]]]}"}}})",
      R"({"id":22,"method":"rheo.v1.DeviceService/ToolStream","stream":true,"binary":false})",
      R"({"id":7,"write":{"leaseId":"abc","pose":{"position":{"x":0.1,"y":-2e-3,"z":1e300}}}})",
      R"({"id":7,"end":true})", R"({"id":7,"cancel":true})"};
  const std::string alphabet = "{}[]\":,0123456789-+.eE truefalsnl\\u00\xc3\xa9\x00\xff";
  std::mt19937 rng(20261202);
  int parsed = 0, refused = 0;
  for (int i = 0; i < 60000; ++i) {
    std::string s = seeds[rng() % seeds.size()];
    const int ops = 1 + static_cast<int>(rng() % 4);
    for (int k = 0; k < ops && !s.empty(); ++k) {
      const size_t at = rng() % s.size();
      switch (rng() % 5) {
        case 0: s[at] = alphabet[rng() % alphabet.size()]; break;
        case 1: s.erase(at, 1 + rng() % 8); break;
        case 2: s.insert(at, 1, alphabet[rng() % alphabet.size()]); break;
        case 3: s.resize(at); break;
        case 4: s.insert(at, s.substr(at, rng() % 32)); break;
      }
    }
    ClientMessage m;
    grpc::Status st = ParseTextMessage(s, &m);
    if (st.ok()) {
      ++parsed;
      ASSERT_GE(m.id, 1u);
      ASSERT_LE(m.id, kMaxCallId);
      if (m.kind == ClientMessage::Kind::kOpen) {
        ASSERT_FALSE(m.method.empty()) << s;
      }
      if (m.kind == ClientMessage::Kind::kWrite) {
        ASSERT_TRUE(m.has_payload) << s;
      }
    } else {
      ++refused;
      ASSERT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << s;
      ASSERT_FALSE(st.error_message().empty()) << s;
      ASSERT_LE(m.id, kMaxCallId);
    }
    // The status reply to it is valid JSON whatever bytes the message held.
    const std::string reply = FormatStatus(m.id, st);
    ASSERT_EQ(reply.front(), '{');
    ASSERT_EQ(reply.back(), '}');
  }
  EXPECT_GT(parsed, 1000);
  EXPECT_GT(refused, 1000);
}

TEST(WebEnvelope, ReplyFormats) {
  EXPECT_EQ(FormatMessage(5, R"({"a":1})"), R"({"id":5,"message":{"a":1}})");
  EXPECT_EQ(FormatStatus(5, grpc::Status(grpc::StatusCode::NOT_FOUND, "no \"x\"")),
            R"({"id":5,"status":{"code":5,"message":"no \"x\"","name":"NOT_FOUND"}})");
  // A message with bytes that are not UTF-8 still makes valid JSON (they are replaced).
  const std::string bad =
      FormatStatus(1, grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "bad \xff byte"));
  EXPECT_NE(bad.find("bad"), std::string::npos);
  EXPECT_EQ(bad.find('\xff'), std::string::npos);
  const std::string b = FormatBinaryMessage(0x01020304, "xy");
  EXPECT_EQ(b, std::string("\x04\x03\x02\x01xy", 6));
}

TEST(WebStaticFiles, MapsPathsInsideTheRootAndRefusesTheRest) {
  const std::filesystem::path root = "/srv/web";
  auto r = [&](const std::string& t) { return StaticFiles::Resolve(root, t); };
  EXPECT_EQ(r("/"), root / "index.html");
  EXPECT_EQ(r("/?view"), root / "index.html");
  EXPECT_EQ(r("/js/main.js?v=2#x"), root / "js/main.js");
  EXPECT_EQ(r("/a%20b.png"), root / "a b.png");
  EXPECT_EQ(r("/vendor/three/build/three.module.js"),
            root / "node_modules/three/build/three.module.js");
  for (const char* bad : {"",
                          "index.html",
                          "/..",
                          "/../x",
                          "/a/../../x",
                          "/%2e%2e/x",
                          "/%2E%2E/x",
                          "/a/./b",
                          "/a//b",
                          "/a/",
                          "/a%2f..%2f..%2fx",
                          "/a\\b",
                          "/a%5c..",
                          "/%00",
                          "/%",
                          "/%4",
                          "/%zz",
                          "/node_modules/three/build/three.module.js",
                          "/vendor/other/x.js",
                          "/vendor",
                          "/vendor/"})
    EXPECT_FALSE(r(bad).has_value()) << bad;
  EXPECT_STREQ(StaticFiles::ContentType("a.js"), "text/javascript; charset=utf-8");
  EXPECT_STREQ(StaticFiles::ContentType("a.unknown"), "application/octet-stream");
}

}  // namespace
}  // namespace rheo::daemon::web
