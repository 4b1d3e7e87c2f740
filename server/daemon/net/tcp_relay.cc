#include "daemon/net/tcp_relay.h"

#include <array>
#include <thread>
#include <utility>

// After the standard headers: Debian's Boost 1.74 asio uses std::exchange without <utility>.
#include <boost/asio.hpp>

namespace rheo::daemon::net {
namespace asio = boost::asio;
using tcp = asio::ip::tcp;

namespace {

// "host:port" (host may be [v6]) into an endpoint; false when it does not parse.
bool ParseEndpoint(const std::string& s, tcp::endpoint& out) {
  const size_t colon = s.rfind(':');
  if (colon == std::string::npos) return false;
  std::string host = s.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  if (host.empty() || host == "*") host = "0.0.0.0";
  if (host == "localhost") host = "127.0.0.1";
  boost::system::error_code ec;
  const auto addr = asio::ip::make_address(host, ec);
  if (ec) return false;
  try {
    out = tcp::endpoint(addr, static_cast<unsigned short>(std::stoi(s.substr(colon + 1))));
  } catch (const std::exception&) {
    return false;
  }
  return true;
}

// One client's connection and its twin to the target; both close when either side does.
class Pipe : public std::enable_shared_from_this<Pipe> {
 public:
  Pipe(tcp::socket client, asio::io_context& io) : client_(std::move(client)), server_(io) {}
  void Start(const tcp::endpoint& target) {
    server_.async_connect(target, [self = shared_from_this()](boost::system::error_code ec) {
      if (ec) return self->Close();
      self->Pump(self->client_, self->server_, self->up_);
      self->Pump(self->server_, self->client_, self->down_);
    });
  }

 private:
  using Buffer = std::array<char, 16384>;
  void Pump(tcp::socket& from, tcp::socket& to, Buffer& buf) {
    from.async_read_some(asio::buffer(buf), [self = shared_from_this(), &from, &to, &buf](
                                                boost::system::error_code ec, size_t n) {
      if (ec) return self->Close();
      asio::async_write(to, asio::buffer(buf.data(), n),
                        [self, &from, &to, &buf](boost::system::error_code ec2, size_t) {
                          if (ec2) return self->Close();
                          self->Pump(from, to, buf);
                        });
    });
  }
  void Close() {
    boost::system::error_code ignored;
    client_.close(ignored);
    server_.close(ignored);
  }
  tcp::socket client_, server_;
  Buffer up_{}, down_{};
};

}  // namespace

struct TcpRelay::Impl {
  std::string listen, target_text;
  tcp::endpoint target;
  asio::io_context io;
  tcp::acceptor acceptor{io};
  std::thread thread;

  void Accept() {
    acceptor.async_accept([this](boost::system::error_code ec, tcp::socket s) {
      if (!acceptor.is_open()) return;
      if (!ec) std::make_shared<Pipe>(std::move(s), io)->Start(target);
      Accept();
    });
  }
};

TcpRelay::TcpRelay(std::string listen, std::string target) : impl_(std::make_unique<Impl>()) {
  impl_->listen = std::move(listen);
  impl_->target_text = std::move(target);
}

TcpRelay::~TcpRelay() {
  Stop();
}

std::string TcpRelay::Start() {
  tcp::endpoint at;
  if (!ParseEndpoint(impl_->listen, at)) return "cannot parse the address " + impl_->listen;
  if (!ParseEndpoint(impl_->target_text, impl_->target))
    return "cannot parse the address " + impl_->target_text;
  boost::system::error_code ec;
  impl_->acceptor.open(at.protocol(), ec);
  if (!ec) impl_->acceptor.set_option(tcp::acceptor::reuse_address(true), ec);
  if (!ec) impl_->acceptor.bind(at, ec);
  if (!ec) impl_->acceptor.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) return "cannot listen on " + impl_->listen + ": " + ec.message();
  impl_->Accept();
  impl_->thread = std::thread([this] {
    pthread_setname_np(pthread_self(), "rheod-relay");
    impl_->io.run();
  });
  return "";
}

int TcpRelay::port() const {
  boost::system::error_code ec;
  return impl_->acceptor.local_endpoint(ec).port();
}

void TcpRelay::Stop() {
  if (!impl_ || !impl_->thread.joinable()) return;
  asio::post(impl_->io, [this] {
    boost::system::error_code ignored;
    impl_->acceptor.close(ignored);
    impl_->io.stop();
  });
  impl_->thread.join();
}

}  // namespace rheo::daemon::net
