// The studio's gateway: the daemon's web server on Boost.Beast, on threads of its own (never the
// loop's). It serves the browser studio's files (clients/web) and a WebSocket at /rpc that
// carries the rheo.v1 API through the generic bridge (bridge.h, envelope.h); over TLS (https,
// wss) when given a certificate.
#pragma once

#include <grpcpp/grpcpp.h>

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>

namespace rheo::daemon::web {

struct GatewayOptions {
  std::string address = "127.0.0.1:8080";  // host:port (port 0 = any free)
  std::filesystem::path web_root;          // clients/web: index.html, js/, node_modules/three
  int threads = 2;
  int max_connections = 256;
  size_t max_message_bytes = 64u << 20;  // a sketch with its photo
  int max_calls_per_connection = 64;
  // https and wss when a certificate is given (PEM text); with a client CA, browsers must present
  // a certificate it signed (mutual TLS).
  std::string tls_cert_pem, tls_key_pem, tls_client_ca_pem;
};

struct GatewayStats {
  int connections = 0;  // open WebSocket connections
  uint64_t messages_out = 0;
  uint64_t bytes_out = 0;
};

class Gateway {
 public:
  /// `channel`: a channel to the gRPC server (its gateway socket).
  Gateway(GatewayOptions options, std::shared_ptr<grpc::Channel> channel);
  ~Gateway();
  Gateway(const Gateway&) = delete;
  Gateway& operator=(const Gateway&) = delete;

  /// Binds and starts serving. FAILED_PRECONDITION or INVALID_ARGUMENT with a message otherwise.
  grpc::Status Start();
  /// The bound port (after Start).
  int port() const;
  /// Closes every connection and cancels their calls, then joins the threads (bounded).
  void Stop();

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace rheo::daemon::web
