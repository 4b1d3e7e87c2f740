#include "daemon/api/limits.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/reflection.h>

#include <algorithm>
#include <cstdio>
#include <map>

#include "daemon/api/auth.h"

namespace rheo::daemon {
namespace {

using google::protobuf::FieldDescriptor;
using google::protobuf::Message;

// The first string field of `m` (recursively) over its limit, with its path, or "" when none.
bool FindLongString(const Message& m, const std::string& prefix, std::string& path, size_t& size,
                    size_t& limit, std::string& start, int depth) {
  if (depth > 16) return false;  // requests nest three deep at most
  const auto* d = m.GetDescriptor();
  const auto* r = m.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const FieldDescriptor* f = d->field(i);
    const bool is_string = f->type() == FieldDescriptor::TYPE_STRING;
    const bool is_message = f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE;
    if (!is_string && !is_message) continue;
    const std::string name = prefix + f->name();
    auto check = [&](const std::string& where, const std::string& v) {
      const size_t max = StringFieldLimit(f->name());
      if (v.size() <= max) return false;
      path = where;
      size = v.size();
      limit = max;
      start = v.substr(0, 24);
      return true;
    };
    if (f->is_repeated()) {
      const int n = r->FieldSize(m, f);
      for (int k = 0; k < n; ++k) {
        const std::string where = name + "[" + std::to_string(k) + "]";
        if (is_string ? check(where, r->GetRepeatedString(m, f, k))
                      : FindLongString(r->GetRepeatedMessage(m, f, k), where + ".", path, size,
                                       limit, start, depth + 1))
          return true;
      }
    } else if (is_string) {
      if (check(name, r->GetString(m, f))) return true;
    } else if (r->HasField(m, f)) {
      if (FindLongString(r->GetMessage(m, f), name + ".", path, size, limit, start, depth + 1))
        return true;
    }
  }
  return false;
}

}  // namespace

std::string QuoteForMessage(std::string_view s, size_t max) {
  std::string out = "'";
  const size_t n = std::min(s.size(), max);
  for (size_t i = 0; i < n; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c == '\'' || c == '\\') {
      out += '\\';
      out += static_cast<char>(c);
    } else if (c < 0x20 || c >= 0x7f) {
      char b[8];
      std::snprintf(b, sizeof b, "\\x%02x", c);
      out += b;
    } else {
      out += static_cast<char>(c);
    }
  }
  out += "'";
  if (s.size() > max) out += "... (" + std::to_string(s.size()) + " bytes)";
  return out;
}

size_t StringFieldLimit(std::string_view field) {
  if (field == "strokes_json") return kMaxSketchTextBytes;
  if (field == "name" || field == "client_name" || field == "description") return kMaxNameBytes;
  return kMaxIdBytes;  // ids, lease ids, job ids, page tokens, presets, units
}

grpc::Status CheckStringLimits(const google::protobuf::Message& request) {
  std::string path, start;
  size_t size = 0, limit = 0;
  if (!FindLongString(request, "", path, size, limit, start, 0)) return grpc::Status::OK;
  return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                      path + " is " + std::to_string(size) + " bytes; the limit is " +
                          std::to_string(limit) + " (it starts " + QuoteForMessage(start, 24) +
                          "...)");
}

namespace {

struct MethodOfRequest {
  std::string name;  // "SetParameters"
  size_t max_bytes;
};

// Request type -> its method (each rheo.v1 method takes a type of its own).
const std::map<const google::protobuf::Descriptor*, MethodOfRequest>& RequestMethods() {
  static const auto* map = [] {
    auto* m = new std::map<const google::protobuf::Descriptor*, MethodOfRequest>;
    const auto* pool = google::protobuf::DescriptorPool::generated_pool();
    for (const MethodRule& rule : MethodTable()) {
      const std::string path(rule.path);  // "/pkg.Service/Method"
      const size_t slash = path.rfind('/');
      if (slash == std::string::npos || slash == 0) continue;
      const auto* service = pool->FindServiceByName(path.substr(1, slash - 1));
      const auto* method = service ? service->FindMethodByName(path.substr(slash + 1)) : nullptr;
      if (!method) continue;
      auto [it, fresh] = m->try_emplace(method->input_type(),
                                        MethodOfRequest{method->name(), rule.max_request_bytes});
      if (!fresh) it->second.max_bytes = std::min(it->second.max_bytes, rule.max_request_bytes);
    }
    return m;
  }();
  return *map;
}

std::string Bytes(size_t n) {
  char b[32];
  if (n >= (1u << 20))
    std::snprintf(b, sizeof b, "%.1f MB", n / 1048576.0);
  else if (n >= 1024)
    std::snprintf(b, sizeof b, "%.1f KB", n / 1024.0);
  else
    std::snprintf(b, sizeof b, "%zu bytes", n);
  return b;
}

}  // namespace

size_t RequestLimit(const google::protobuf::Descriptor* request_type) {
  auto it = RequestMethods().find(request_type);
  return it == RequestMethods().end() ? MethodRule{}.max_request_bytes : it->second.max_bytes;
}

grpc::Status CheckRequest(const google::protobuf::Message& request) {
  const auto& methods = RequestMethods();
  auto it = methods.find(request.GetDescriptor());
  const size_t limit = it == methods.end() ? MethodRule{}.max_request_bytes : it->second.max_bytes;
  const size_t size = request.ByteSizeLong();
  if (size > limit)
    return grpc::Status(
        grpc::StatusCode::RESOURCE_EXHAUSTED,
        (it == methods.end() ? request.GetDescriptor()->name() : it->second.name) + ": the " +
            "request is " + Bytes(size) + "; the limit for this method is " + Bytes(limit) +
            (limit < kMaxSketchRequestBytes
                 ? " (only sketches may be larger, up to " + Bytes(kMaxSketchRequestBytes) + ")"
                 : std::string(" (a sketch and its photo)")));
  return CheckStringLimits(request);
}

}  // namespace rheo::daemon
