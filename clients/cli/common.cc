// rheoctl: the helpers every command uses.
#include <google/protobuf/util/json_util.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>

#include "rheo/client/channel.h"
#include "rheoctl.h"

namespace rheoctl {
namespace {

const char* CodeName(grpc::StatusCode c) {
  switch (c) {
    case grpc::OK: return "OK";
    case grpc::CANCELLED: return "CANCELLED";
    case grpc::UNKNOWN: return "UNKNOWN";
    case grpc::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::NOT_FOUND: return "NOT_FOUND";
    case grpc::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::ABORTED: return "ABORTED";
    case grpc::OUT_OF_RANGE: return "OUT_OF_RANGE";
    case grpc::UNIMPLEMENTED: return "UNIMPLEMENTED";
    case grpc::INTERNAL: return "INTERNAL";
    case grpc::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::DATA_LOSS: return "DATA_LOSS";
    case grpc::UNAUTHENTICATED: return "UNAUTHENTICATED";
    default: return "UNKNOWN";
  }
}

}  // namespace

void PrintLineCounters(const rheo::v1::DeviceCounters& c) {
  std::printf("  serial line: lost %llu times, reconnect attempts %llu, reconnects %llu",
              (unsigned long long)c.line_losses(), (unsigned long long)c.reconnect_attempts(),
              (unsigned long long)c.reconnects());
  if (c.disconnected_s() > 0)
    std::printf("; AWAY for %.1f s, reconnect backoff %.1f s", c.disconnected_s(),
                c.reconnect_backoff_s());
  std::printf("\n");
}

int Fail(const grpc::Status& s) {
  std::cerr << CodeName(s.error_code()) << ": " << s.error_message() << "\n";
  return s.error_code() == grpc::OK ? 1 : static_cast<int>(s.error_code());
}

std::string ToJson(const google::protobuf::Message& m, bool pretty) {
  google::protobuf::util::JsonPrintOptions o;
  o.add_whitespace = pretty;
  o.preserve_proto_field_names = true;
  std::string out;
  (void)google::protobuf::util::MessageToJsonString(m, &out, o);
  if (!pretty) {
    while (!out.empty() && out.back() == '\n') out.pop_back();
  }
  return out;
}

std::shared_ptr<grpc::Channel> Connect(const Global& g) {
  rheo::client::ChannelOptions o;
  o.target = g.server;
  std::string error;
  if (!g.token.empty()) {
    o.token = g.token;
  } else if (!g.token_file.empty()) {
    o.token = rheo::client::ReadTokenFile(g.token_file, &error);
  } else if (const char* env = std::getenv("RHEO_TOKEN"); env && *env) {
    o.token = env;
  } else {
    // The local daemon's admin token, when this user can read it (else no token: the daemon
    // then answers UNAUTHENTICATED saying how to give one).
    o.token = rheo::client::ReadTokenFile(rheo::client::DefaultAdminTokenPath(g.data_dir), nullptr);
  }
  o.tls_ca_file = g.tls_ca;
  o.tls_cert_file = g.tls_cert;
  o.tls_key_file = g.tls_key;
  o.tls_server_name = g.tls_server_name;
  std::shared_ptr<grpc::Channel> channel;
  if (error.empty()) channel = rheo::client::Connect(o, &error);
  if (!channel) {
    std::cerr << "INVALID_ARGUMENT: " << error << "\n";
    std::exit(3);
  }
  return channel;
}

void SetDeadline(grpc::ClientContext& ctx, const Global& g, double default_s) {
  const double t = g.timeout_s > 0 ? g.timeout_s : default_s;
  ctx.set_deadline(std::chrono::system_clock::now() +
                   std::chrono::milliseconds(static_cast<int64_t>(t * 1000)));
}

bool LoadSketch(const std::string& path, rheo::v1::Sketch* sketch) {
  std::string data;
  if (!rheo::client::ReadWholeFile(path, data)) {
    std::cerr << "INVALID_ARGUMENT: cannot read " << path << "\n";
    return false;
  }
  size_t first = data.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && data[first] == '{') {
    if (data.find("\"strokes\"") == std::string::npos &&
        data.find("\"contour\"") != std::string::npos) {
      // Contour JSON: the numbers of the "contour" array, pairwise.
      size_t start = data.find('[', data.find("\"contour\""));
      size_t depth = 0, pos = start;
      std::string nums;
      for (; pos < data.size(); ++pos) {
        char c = data[pos];
        if (c == '[') ++depth;
        if (c == ']' && --depth == 0) break;
        nums += (c == '[' || c == ']' || c == ',') ? ' ' : c;
      }
      std::istringstream in(nums);
      double x, y;
      while (in >> x >> y) {
        auto* p = sketch->mutable_contour()->add_points();
        p->set_x(x);
        p->set_y(y);
      }
    } else {
      sketch->set_strokes_json(data);
    }
  } else {
    sketch->set_image(data);
  }
  return true;
}

bool ParseAssignments(const std::vector<std::string>& items,
                      google::protobuf::RepeatedPtrField<rheo::v1::Parameter>* out) {
  for (const std::string& item : items) {
    size_t eq = item.find('=');
    char* end = nullptr;
    double v = eq == std::string::npos ? 0 : std::strtod(item.c_str() + eq + 1, &end);
    if (eq == std::string::npos || eq == 0 || end == item.c_str() + eq + 1 || *end != '\0') {
      std::cerr << "INVALID_ARGUMENT: '" << item << "' is not name=value (e.g. k_v=200)\n";
      return false;
    }
    auto* p = out->Add();
    p->set_name(item.substr(0, eq));
    p->set_value(v);
  }
  return true;
}

}  // namespace rheoctl
