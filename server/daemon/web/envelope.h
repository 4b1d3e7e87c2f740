// The studio's WebSocket protocol: JSON envelopes around rheo.v1 calls (docs/web-protocol.md).
//
// Client to daemon, one JSON object per text message:
//   {"id": N, "method": "rheo.v1.SceneService/GetScene", "request": {...}}   open a call
//   {"id": N, "method": "rheo.v1.DeviceService/ToolStream", "stream": true}  open a client stream
//   {"id": N, "write": {...}}        the next request message of a client stream
//   {"id": N, "end": true}           no more requests (half-close)
//   {"id": N, "cancel": true}        cancel the call
// "binary": true on an open asks for responses as binary messages (4-byte little-endian id, then
// the protobuf bytes); a binary message from the client is a write in that form.
// Daemon to client: {"id": N, "message": {...}} per response, then exactly once
// {"id": N, "status": {"code": C, "name": "...", "message": "..."}}.
#pragma once

#include <grpcpp/support/status.h>

#include <cstdint>
#include <string>
#include <string_view>

namespace rheo::daemon::web {

struct ClientMessage {
  enum class Kind { kOpen, kWrite, kEnd, kCancel, kAuth };
  Kind kind = Kind::kOpen;
  uint32_t id = 0;
  std::string method;        // kOpen: "package.Service/Method"
  bool stream = false;       // kOpen: requests follow as writes
  bool binary = false;       // kOpen: responses as binary messages
  bool has_payload = false;  // kOpen with "request", or kWrite
  bool payload_is_binary = false;
  std::string payload;  // JSON text of the message, or its protobuf bytes (binary write);
                        // kAuth: the access token
};

/// Largest call id (ids are positive and fit a JavaScript number exactly).
constexpr uint32_t kMaxCallId = 0x7fffffffu;

/// Parses one text message. On failure returns INVALID_ARGUMENT saying what is wrong, and sets
/// out->id when the message carried a usable id (0 otherwise).
grpc::Status ParseTextMessage(std::string_view text, ClientMessage* out);
/// Parses one binary message (4-byte little-endian id, then protobuf bytes): a write.
grpc::Status ParseBinaryMessage(std::string_view bytes, ClientMessage* out);

/// {"id":N,"message":JSON}
std::string FormatMessage(uint32_t id, std::string_view json);
/// 4-byte little-endian id followed by `bytes`.
std::string FormatBinaryMessage(uint32_t id, std::string_view bytes);
/// {"id":N,"status":{"code":C,"name":"...","message":"..."}}
std::string FormatStatus(uint32_t id, const grpc::Status& status);
/// "INVALID_ARGUMENT" and so on.
const char* StatusCodeName(grpc::StatusCode code);

}  // namespace rheo::daemon::web
