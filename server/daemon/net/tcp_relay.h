// A byte relay from a listening TCP address onto another (rheod --insecure on a non-loopback
// address: gRPC checks tokens only on credentials that are not plaintext, so the plaintext
// clients reach the checked local port through this relay, never an unchecked port).
#pragma once

#include <memory>
#include <string>

namespace rheo::daemon::net {

class TcpRelay {
 public:
  /// Listens on `listen` ("host:port", port 0 = any free) and relays every connection to
  /// `target` ("127.0.0.1:port") on a thread of its own.
  TcpRelay(std::string listen, std::string target);
  ~TcpRelay();
  /// "" when listening, else why not.
  std::string Start();
  int port() const;
  void Stop();

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace rheo::daemon::net
