// Length limits on the strings a client sends, checked in one place, and the one way an error
// message quotes client input (short, escaped).
#pragma once

#include <google/protobuf/message.h>
#include <grpcpp/support/status.h>

#include <cstddef>
#include <string>
#include <string_view>

namespace rheo::daemon {

/// Ids, lease ids, job ids and page tokens [bytes]. The daemon's own are far shorter.
inline constexpr size_t kMaxIdBytes = 128;
/// Names a person gives: client_name, object names [bytes].
inline constexpr size_t kMaxNameBytes = 200;
/// Sketch text (strokes_json) is limited with the sketch's bytes (32 MB), not here.
inline constexpr size_t kMaxSketchTextBytes = 32u << 20;

/// At most `max` bytes of `s`, quoted and escaped (control and non-ASCII bytes as \xNN), with
/// "... (N bytes)" when cut: safe to put into any error message.
std::string QuoteForMessage(std::string_view s, size_t max = 40);

/// The limit for a string field named `field` (the proto field name) [bytes].
size_t StringFieldLimit(std::string_view field);

/// Walks every string field of `request` and of the messages inside it: INVALID_ARGUMENT naming
/// the first field over its limit, the limit and the start of the value; OK otherwise.
grpc::Status CheckStringLimits(const google::protobuf::Message& request);

/// The check every handler makes first, on every request message it reads: the message's size
/// against its method's limit in the role table (RESOURCE_EXHAUSTED naming the method, the size
/// and the limit; unknown fields count), then CheckStringLimits.
grpc::Status CheckRequest(const google::protobuf::Message& request);
/// The limit CheckRequest applies to a request of this type (its method's entry) [bytes].
size_t RequestLimit(const google::protobuf::Descriptor* request_type);

}  // namespace rheo::daemon
