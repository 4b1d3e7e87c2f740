#include "daemon/web/envelope.h"

#include <nlohmann/json.hpp>

namespace rheo::daemon::web {
namespace {

grpc::Status Bad(std::string message) {
  return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, std::move(message));
}

}  // namespace

grpc::Status ParseTextMessage(std::string_view text, ClientMessage* out) {
  *out = ClientMessage{};
  nlohmann::json j = nlohmann::json::parse(text.begin(), text.end(), nullptr, false);
  if (j.is_discarded())
    return Bad(
        "the message is not JSON; send one JSON object per WebSocket text message, e.g. "
        "{\"id\":1,\"method\":\"rheo.v1.DaemonService/GetStatus\",\"request\":{}}");
  if (!j.is_object())
    return Bad("the message must be a JSON object, not " + std::string(j.type_name()));
  // {"auth": "TOKEN"}: the token for every call opened from here on (the first message).
  if (auto a = j.find("auth"); a != j.end()) {
    if (j.size() != 1) return Bad("an \"auth\" message has only \"auth\": the access token");
    if (!a->is_string() || a->get_ref<const std::string&>().empty() ||
        a->get_ref<const std::string&>().size() > 512)
      return Bad("\"auth\" must be the access token, a string of 1 to 512 characters");
    const std::string& t = a->get_ref<const std::string&>();
    for (char c : t)
      if (c < 0x21 || c > 0x7e)
        return Bad("\"auth\" must be the access token: printable ASCII, no spaces");
    out->kind = ClientMessage::Kind::kAuth;
    out->payload = t;
    return grpc::Status::OK;
  }
  auto id = j.find("id");
  if (id == j.end()) return Bad("the message has no \"id\" (a positive integer naming the call)");
  if (!id->is_number_unsigned() || id->get<uint64_t>() == 0 || id->get<uint64_t>() > kMaxCallId)
    return Bad("\"id\" must be an integer from 1 to " + std::to_string(kMaxCallId) + ", got " +
               id->dump());
  out->id = static_cast<uint32_t>(id->get<uint64_t>());

  int kinds = 0;
  for (const char* k : {"method", "write", "end", "cancel"}) kinds += j.contains(k) ? 1 : 0;
  if (kinds != 1)
    return Bad(
        "the message must have exactly one of \"method\" (open a call), \"write\", "
        "\"end\" or \"cancel\"");
  auto flag = [&](const char* name, bool* value) -> grpc::Status {
    auto it = j.find(name);
    if (it == j.end()) return grpc::Status::OK;
    if (!it->is_boolean()) return Bad(std::string("\"") + name + "\" must be true or false");
    *value = it->get<bool>();
    return grpc::Status::OK;
  };
  if (auto m = j.find("method"); m != j.end()) {
    if (!m->is_string() || m->get_ref<const std::string&>().empty())
      return Bad("\"method\" must be a string such as \"rheo.v1.SceneService/GetScene\"");
    out->kind = ClientMessage::Kind::kOpen;
    out->method = m->get<std::string>();
    if (auto s = flag("stream", &out->stream); !s.ok()) return s;
    if (auto s = flag("binary", &out->binary); !s.ok()) return s;
    if (auto r = j.find("request"); r != j.end()) {
      if (out->stream)
        return Bad(
            "a call opened with \"stream\": true sends its requests as writes, not as "
            "\"request\"");
      if (!r->is_object()) return Bad("\"request\" must be a JSON object (the request message)");
      out->has_payload = true;
      out->payload = r->dump();
    }
    for (auto& [key, value] : j.items())
      if (key != "id" && key != "method" && key != "stream" && key != "binary" && key != "request")
        return Bad("unknown field \"" + key + "\" in a call's opening message");
    return grpc::Status::OK;
  }
  const char* kind = j.contains("write") ? "write" : j.contains("end") ? "end" : "cancel";
  if (j.size() != 2)
    return Bad(std::string("a \"") + kind + "\" message has only \"id\" and \"" + kind + "\"");
  if (j.contains("write")) {
    const auto& w = j["write"];
    if (!w.is_object()) return Bad("\"write\" must be a JSON object (the next request message)");
    out->kind = ClientMessage::Kind::kWrite;
    out->has_payload = true;
    out->payload = w.dump();
    return grpc::Status::OK;
  }
  bool yes = false;
  if (auto s = flag(kind, &yes); !s.ok()) return s;
  if (!yes) return Bad(std::string("\"") + kind + "\" must be true");
  out->kind = j.contains("end") ? ClientMessage::Kind::kEnd : ClientMessage::Kind::kCancel;
  return grpc::Status::OK;
}

grpc::Status ParseBinaryMessage(std::string_view bytes, ClientMessage* out) {
  *out = ClientMessage{};
  if (bytes.size() < 4)
    return Bad("a binary message starts with the call's 4-byte little-endian id; got " +
               std::to_string(bytes.size()) + " bytes");
  uint32_t id = 0;
  for (int i = 3; i >= 0; --i) id = (id << 8) | static_cast<unsigned char>(bytes[i]);
  if (id == 0 || id > kMaxCallId)
    return Bad("a binary message's id must be from 1 to " + std::to_string(kMaxCallId) + ", got " +
               std::to_string(id));
  out->id = id;
  out->kind = ClientMessage::Kind::kWrite;
  out->has_payload = true;
  out->payload_is_binary = true;
  out->payload.assign(bytes.substr(4));
  return grpc::Status::OK;
}

std::string FormatMessage(uint32_t id, std::string_view json) {
  std::string s;
  s.reserve(json.size() + 32);
  s += "{\"id\":";
  s += std::to_string(id);
  s += ",\"message\":";
  s += json;
  s += '}';
  return s;
}

std::string FormatBinaryMessage(uint32_t id, std::string_view bytes) {
  std::string s(4 + bytes.size(), '\0');
  for (int i = 0; i < 4; ++i) s[i] = static_cast<char>((id >> (8 * i)) & 0xff);
  s.replace(4, bytes.size(), bytes);
  return s;
}

std::string FormatStatus(uint32_t id, const grpc::Status& status) {
  nlohmann::json j = {{"id", id},
                      {"status",
                       {{"code", static_cast<int>(status.error_code())},
                        {"name", StatusCodeName(status.error_code())},
                        {"message", status.error_message()}}}};
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

const char* StatusCodeName(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK: return "OK";
    case grpc::StatusCode::CANCELLED: return "CANCELLED";
    case grpc::StatusCode::UNKNOWN: return "UNKNOWN";
    case grpc::StatusCode::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND: return "NOT_FOUND";
    case grpc::StatusCode::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::StatusCode::UNAUTHENTICATED: return "UNAUTHENTICATED";
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::StatusCode::ABORTED: return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE: return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED: return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL: return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::StatusCode::DATA_LOSS: return "DATA_LOSS";
    default: return "UNKNOWN";
  }
}

}  // namespace rheo::daemon::web
