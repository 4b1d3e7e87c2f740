// A gRPC channel to rheod that carries the caller's access token on every call (and TLS when
// asked): what rheoctl, the tests and the benchmarks share.
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

namespace rheo::client {

struct ChannelOptions {
  std::string target;  // "127.0.0.1:50051", "unix:...", "host:port"
  std::string token;   // sent as "authorization: Bearer TOKEN" ("" sends none)
  // TLS: the CA that signed the daemon's certificate ("" plaintext), and for mutual TLS this
  // client's certificate and key.
  std::string tls_ca_file;
  std::string tls_cert_file;
  std::string tls_key_file;
  std::string tls_server_name;  // the name to check the certificate for ("" the target's host)
  int max_receive_bytes = 256 << 20;
};

/// The channel, or nullptr with `error` set (a TLS file that cannot be read).
std::shared_ptr<grpc::Channel> Connect(const ChannelOptions& options, std::string* error);

/// Where rheod writes its first admin token: DATA_DIR/admin.token, DATA_DIR defaulting as
/// rheod's does ($XDG_DATA_HOME/rheo, else ~/.local/share/rheo).
std::string DefaultAdminTokenPath(const std::string& data_dir = "");

/// The token in `path` (surrounding whitespace removed); "" with `error` set when it cannot be
/// read.
std::string ReadTokenFile(const std::string& path, std::string* error);
/// The whole file (binary); false when it cannot be read.
bool ReadWholeFile(const std::string& path, std::string& out);

}  // namespace rheo::client
