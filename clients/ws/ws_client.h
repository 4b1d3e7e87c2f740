// A C++ client of the studio's WebSocket protocol (server/daemon/web/envelope.h): what the
// gateway's tests and the many-viewers benchmark use to talk to rheod exactly as a browser does.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

namespace rheo::ws {

struct Message {
  bool binary = false;
  std::string data;
};

/// wss:// and https:// instead of ws:// and http://.
struct Tls {
  std::string ca_file;    // PEM CA the server's certificate must chain to
  std::string cert_file;  // a client certificate and its key (mutual TLS), or empty
  std::string key_file;
  std::string server_name = "localhost";  // sent as SNI and checked against the certificate
};

class Client {
 public:
  /// Connects to ws://host:port/rpc (`target` may name another path; wss:// with `tls`).
  /// `origin`, when not empty, is sent as the Origin header as a browser would. nullptr with
  /// `error` set on failure (the HTTP status and body of a refused upgrade among it).
  /// `receive_buffer_bytes` > 0 fixes the socket's receive buffer (a viewer on a slow link).
  static std::unique_ptr<Client> Connect(const std::string& host, int port, std::string* error,
                                         const std::string& origin = "",
                                         const std::string& target = "/rpc",
                                         int receive_buffer_bytes = 0, const Tls* tls = nullptr);
  ~Client();

  bool SendText(const std::string& text);
  bool SendBinary(const std::string& bytes);
  /// Waits up to `timeout` for the next message. False on timeout, close or error (`error()`).
  bool Read(Message* out, std::chrono::milliseconds timeout);
  /// Closes with a normal close frame.
  void Close();
  const std::string& error() const { return error_; }

  struct Impl;

 private:
  explicit Client(std::unique_ptr<Impl> impl);
  bool Send(const std::string& data, bool binary);
  std::unique_ptr<Impl> impl_;
  std::string error_;
};

/// One HTTP/1.1 GET (or another method) on host:port (https with `tls`); returns the status code
/// (0 on error, the reason in `body`) and fills `body`.
int HttpRequest(const std::string& host, int port, const std::string& method,
                const std::string& target, std::string* body, std::string* content_type = nullptr,
                const Tls* tls = nullptr);

}  // namespace rheo::ws
