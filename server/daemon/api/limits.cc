#include "daemon/api/limits.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/reflection.h>

#include <cstdio>

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

}  // namespace rheo::daemon
