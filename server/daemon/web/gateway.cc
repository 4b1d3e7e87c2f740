#include "daemon/web/gateway.h"

#include <pthread.h>

#include <atomic>
#include <boost/asio/dispatch.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "daemon/web/bridge.h"
#include "daemon/web/envelope.h"
#include "daemon/web/static_files.h"

namespace rheo::daemon::web {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using TlsStream = beast::ssl_stream<beast::tcp_stream>;

// What the gateway keeps of an open WebSocket session, whichever its transport.
class Session {
 public:
  virtual ~Session() = default;
  virtual void Close() = 0;
};

struct Gateway::Impl {
  GatewayOptions options;
  Bridge bridge;
  StaticFiles files;
  net::io_context ioc;
  std::optional<net::ssl::context> tls;  // set: https and wss only
  std::optional<net::executor_work_guard<net::io_context::executor_type>> work;
  tcp::acceptor acceptor{ioc};
  std::vector<std::thread> threads;
  int port = 0;
  std::atomic<int> connections{0};
  std::atomic<bool> stopping{false};

  std::mutex sessions_mutex;
  std::vector<std::weak_ptr<Session>> sessions;

  Impl(GatewayOptions o, std::shared_ptr<grpc::Channel> channel)
      : options(std::move(o)), bridge(std::move(channel)), files(options.web_root) {}

  void Accept();
};

// One WebSocket connection: its calls and its single outgoing queue (one write in flight).
// Stream: beast::tcp_stream (ws) or TlsStream (wss).
template <class Stream>
class WsSession : public CallSink,
                  public Session,
                  public std::enable_shared_from_this<WsSession<Stream>> {
 public:
  WsSession(Gateway::Impl& gw, Stream&& stream) : gw_(gw), ws_(std::move(stream)) {}
  ~WsSession() override { gw_.connections.fetch_sub(1); }
  using std::enable_shared_from_this<WsSession<Stream>>::shared_from_this;

  void Run(http::request<http::string_body> request) {
    gw_.connections.fetch_add(1);
    // One write in flight per connection, and a small kernel send buffer under it: what a slow
    // viewer has not taken yet stays bounded (this buffer and its own receive window), so its
    // frame stream waits at the daemon, which skips frames for it (newest wins) instead of
    // queueing seconds of them in the socket.
    beast::error_code ec;
    auto& socket = beast::get_lowest_layer(ws_).socket();
    socket.set_option(net::socket_base::send_buffer_size(kSendBufferBytes), ec);
    socket.set_option(tcp::no_delay(true), ec);
    auto timeouts = websocket::stream_base::timeout::suggested(beast::role_type::server);
    timeouts.idle_timeout = std::chrono::seconds(30);
    timeouts.keep_alive_pings = true;  // a vanished browser is noticed within a minute
    ws_.set_option(timeouts);
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& res) { res.set(http::field::server, "rheod"); }));
    ws_.read_message_max(gw_.options.max_message_bytes);
    ws_.async_accept(request, beast::bind_front_handler(&WsSession::OnAccept, shared_from_this()));
  }

  void Close() override {
    net::post(ws_.get_executor(), [self = shared_from_this()] {
      if (self->closed_) return;
      beast::error_code ec;
      beast::get_lowest_layer(self->ws_).socket().shutdown(tcp::socket::shutdown_both, ec);
      self->Shutdown();
    });
  }

  // CallSink, from gRPC's threads.
  void Deliver(uint32_t id, bool binary, std::string payload,
               std::function<void()> written) override {
    net::post(
        ws_.get_executor(), [self = shared_from_this(), id, binary, payload = std::move(payload),
                             written = std::move(written)]() mutable {
          if (self->closed_) return;  // the call was abandoned; it finishes on its own
          self->Enqueue(binary ? FormatBinaryMessage(id, payload) : FormatMessage(id, payload),
                        binary, std::move(written));
        });
  }
  void Finish(uint32_t id, const grpc::Status& status) override {
    net::post(ws_.get_executor(), [self = shared_from_this(), id, status] {
      self->calls_.erase(id);
      if (!self->closed_) self->Enqueue(FormatStatus(id, status), false, nullptr);
    });
  }

 private:
  struct Outgoing {
    std::string data;
    bool binary = false;
    std::function<void()> written;
  };
  static constexpr int kSendBufferBytes = 64 * 1024;
  // Beyond this many queued replies the client is not reading them: it is closed, not buffered.
  static constexpr size_t kMaxQueued = 1024;

  void OnAccept(beast::error_code ec) {
    if (ec) return Shutdown();
    DoRead();
  }

  void DoRead() {
    ws_.async_read(in_, beast::bind_front_handler(&WsSession::OnRead, shared_from_this()));
  }

  void OnRead(beast::error_code ec, size_t) {
    if (ec) return Shutdown();
    const std::string data = beast::buffers_to_string(in_.data());
    in_.consume(in_.size());
    ClientMessage m;
    grpc::Status s = ws_.got_text() ? ParseTextMessage(data, &m) : ParseBinaryMessage(data, &m);
    if (!s.ok())
      Enqueue(FormatStatus(m.id, s), false, nullptr);
    else
      Handle(std::move(m));
    if (!closed_) DoRead();
  }

  void Handle(ClientMessage m) {
    if (m.kind == ClientMessage::Kind::kAuth) {
      authorization_ = "Bearer " + m.payload;  // checked by the daemon on every call
      return;
    }
    auto it = calls_.find(m.id);
    if (m.kind == ClientMessage::Kind::kOpen) {
      if (it != calls_.end())
        return Reply(m.id, grpc::StatusCode::INVALID_ARGUMENT,
                     "call id " + std::to_string(m.id) + " is still open; use a new id");
      if (static_cast<int>(calls_.size()) >= gw_.options.max_calls_per_connection)
        return Reply(m.id, grpc::StatusCode::RESOURCE_EXHAUSTED,
                     std::to_string(calls_.size()) +
                         " calls are open on this connection, the most it may have; cancel or "
                         "finish some first");
      const MethodInfo* method = gw_.bridge.Find(m.method);
      if (!method)
        return Reply(m.id, grpc::StatusCode::UNIMPLEMENTED,
                     "no method \"" + m.method + "\"; the methods are " + gw_.bridge.MethodList());
      if (method->client_streaming && !m.stream)
        return Reply(m.id, grpc::StatusCode::INVALID_ARGUMENT,
                     m.method +
                         " is a client stream: open it with \"stream\": true and send "
                         "each request as a \"write\"");
      std::string first;
      if (m.has_payload) {
        if (grpc::Status s = gw_.bridge.JsonToBinary(method->input, m.payload, &first); !s.ok())
          return Reply(m.id, s.error_code(), s.error_message());
      }
      auto call = std::make_shared<Call>(gw_.bridge, *method, m.id, m.binary, authorization_,
                                         std::weak_ptr<CallSink>(shared_from_this()));
      calls_.emplace(m.id, call);
      call->Start(m.stream ? nullptr : &first, !m.stream);
      return;
    }
    if (it == calls_.end())
      return Reply(m.id, grpc::StatusCode::NOT_FOUND,
                   "no open call " + std::to_string(m.id) + " (it ended, or was never opened)");
    Call& call = *it->second;
    switch (m.kind) {
      case ClientMessage::Kind::kWrite: {
        if (m.payload_is_binary) return call.Write(std::move(m.payload));
        std::string bytes;
        if (grpc::Status s = gw_.bridge.JsonToBinary(call.method().input, m.payload, &bytes);
            !s.ok())
          return call.Fail(s);
        return call.Write(std::move(bytes));
      }
      case ClientMessage::Kind::kEnd: return call.WritesDone();
      case ClientMessage::Kind::kCancel: return call.Cancel();
      case ClientMessage::Kind::kOpen:
      case ClientMessage::Kind::kAuth: return;
    }
  }

  void Reply(uint32_t id, grpc::StatusCode code, const std::string& message) {
    Enqueue(FormatStatus(id, grpc::Status(code, message)), false, nullptr);
  }

  void Enqueue(std::string data, bool binary, std::function<void()> written) {
    if (closed_) return;
    if (out_.size() >= kMaxQueued) {
      // Not reading its replies: close rather than buffer without bound.
      beast::error_code ec;
      beast::get_lowest_layer(ws_).socket().shutdown(tcp::socket::shutdown_both, ec);
      return Shutdown();
    }
    out_.push_back(Outgoing{std::move(data), binary, std::move(written)});
    if (out_.size() == 1) DoWrite();
  }

  void DoWrite() {
    ws_.binary(out_.front().binary);
    ws_.async_write(net::buffer(out_.front().data),
                    beast::bind_front_handler(&WsSession::OnWrite, shared_from_this()));
  }

  void OnWrite(beast::error_code ec, size_t) {
    if (ec) return Shutdown();
    std::function<void()> written = std::move(out_.front().written);
    out_.pop_front();
    if (written) written();  // the call reads its next response
    if (!out_.empty()) DoWrite();
  }

  // The connection is over: every call is cancelled and finishes without it.
  void Shutdown() {
    if (closed_) return;
    closed_ = true;
    out_.clear();
    auto calls = std::move(calls_);
    calls_.clear();
    for (auto& [id, call] : calls) call->Abandon();
  }

  Gateway::Impl& gw_;
  websocket::stream<Stream> ws_;
  beast::flat_buffer in_;
  std::deque<Outgoing> out_;
  std::map<uint32_t, std::shared_ptr<Call>> calls_;
  bool closed_ = false;
  std::string authorization_;  // "Bearer TOKEN" once the page sent {"auth": TOKEN}
};

// One HTTP connection: static files, or the upgrade to the WebSocket at /rpc. Stream:
// beast::tcp_stream (http) or TlsStream (https: the handshake first).
template <class Stream>
class HttpSession : public std::enable_shared_from_this<HttpSession<Stream>> {
  static constexpr bool kTls = std::is_same_v<Stream, TlsStream>;

 public:
  HttpSession(Gateway::Impl& gw, tcp::socket&& socket) requires(!kTls)
      : gw_(gw), stream_(std::move(socket)) {}
  HttpSession(Gateway::Impl& gw, tcp::socket&& socket, net::ssl::context& tls) requires(kTls)
      : gw_(gw), stream_(std::move(socket), tls) {}
  using std::enable_shared_from_this<HttpSession<Stream>>::shared_from_this;

  void Run() {
    net::dispatch(stream_.get_executor(), [self = shared_from_this()] {
      if constexpr (kTls) {
        beast::get_lowest_layer(self->stream_).expires_after(std::chrono::seconds(30));
        self->stream_.async_handshake(net::ssl::stream_base::server, [self](beast::error_code ec) {
          if (ec) return;  // not TLS, or a certificate refused
          self->DoRead();
        });
      } else {
        self->DoRead();
      }
    });
  }

 private:
  void DoRead() {
    parser_.emplace();
    parser_->header_limit(16 * 1024);
    parser_->body_limit(64 * 1024);
    beast::get_lowest_layer(stream_).expires_after(std::chrono::seconds(30));
    http::async_read(stream_, buffer_, *parser_,
                     beast::bind_front_handler(&HttpSession::OnRead, shared_from_this()));
  }

  void OnRead(beast::error_code ec, size_t) {
    if (ec == http::error::end_of_stream) return Close();
    if (ec) {
      // A malformed request gets a 400 saying why when the socket still works.
      if (ec.category() == http::make_error_code(http::error::bad_target).category()) {
        auto res =
            std::make_shared<http::response<http::string_body>>(http::status::bad_request, 11);
        res->set(http::field::content_type, "text/plain; charset=utf-8");
        res->body() = "bad HTTP request: " + ec.message() + "\n";
        res->keep_alive(false);
        res->prepare_payload();
        return Send(std::move(res));
      }
      return Close();
    }
    http::request<http::string_body> req = parser_->release();
    if (websocket::is_upgrade(req)) return Upgrade(std::move(req));
    auto res = std::make_shared<http::response<http::string_body>>(gw_.files.Serve(req));
    Send(std::move(res));
  }

  void Upgrade(http::request<http::string_body> req) {
    std::string refusal;
    std::string target(req.target());
    if (target.substr(0, target.find('?')) != "/rpc")
      refusal = "the WebSocket is at /rpc";
    else if (!SameOrigin(req))
      refusal = "cross-origin WebSocket refused: open the studio from this daemon's own address";
    else if (gw_.connections.load() >= gw_.options.max_connections)
      refusal = std::to_string(gw_.options.max_connections) +
                " WebSocket connections are open, the most this daemon takes (--http "
                "connections); close some viewers";
    else if (gw_.stopping.load())
      refusal = "rheod is shutting down";
    if (!refusal.empty()) {
      auto res = std::make_shared<http::response<http::string_body>>(
          target.substr(0, target.find('?')) != "/rpc" ? http::status::not_found
                                                       : http::status::forbidden,
          req.version());
      res->set(http::field::content_type, "text/plain; charset=utf-8");
      res->body() = refusal + "\n";
      res->keep_alive(false);
      res->prepare_payload();
      return Send(std::move(res));
    }
    beast::get_lowest_layer(stream_).expires_never();
    auto ws = std::make_shared<WsSession<Stream>>(gw_, std::move(stream_));
    {
      std::lock_guard<std::mutex> lock(gw_.sessions_mutex);
      auto& v = gw_.sessions;
      v.erase(std::remove_if(v.begin(), v.end(), [](auto& w) { return w.expired(); }), v.end());
      v.push_back(ws);
    }
    ws->Run(std::move(req));
  }

  // A browser names the page's origin; a page of another site may not drive this daemon. Tools
  // that send no Origin (not a browser) are let through.
  static bool SameOrigin(const http::request<http::string_body>& req) {
    auto origin = req.find(http::field::origin);
    if (origin == req.end()) return true;
    std::string o(origin->value());
    const std::string host(req[http::field::host]);
    for (const char* scheme : {"http://", "https://"})
      if (o == scheme + host) return true;
    return false;
  }

  void Send(std::shared_ptr<http::response<http::string_body>> res) {
    const bool close = res->need_eof();
    http::async_write(stream_, *res,
                      [self = shared_from_this(), res, close](beast::error_code ec, size_t) {
                        if (ec || close) return self->Close();
                        self->DoRead();
                      });
  }

  void Close() {
    if constexpr (kTls) {
      stream_.async_shutdown([self = shared_from_this()](beast::error_code) {});
    } else {
      beast::error_code ec;
      stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
    }
  }

  Gateway::Impl& gw_;
  Stream stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
};

void Gateway::Impl::Accept() {
  acceptor.async_accept(net::make_strand(ioc), [this](beast::error_code ec, tcp::socket socket) {
    if (stopping.load() || !acceptor.is_open()) return;
    if (!ec) {
      if (tls)
        std::make_shared<HttpSession<TlsStream>>(*this, std::move(socket), *tls)->Run();
      else
        std::make_shared<HttpSession<beast::tcp_stream>>(*this, std::move(socket))->Run();
    }
    Accept();
  });
}

Gateway::Gateway(GatewayOptions options, std::shared_ptr<grpc::Channel> channel)
    : impl_(std::make_unique<Impl>(std::move(options), std::move(channel))) {}

Gateway::~Gateway() {
  Stop();
}

grpc::Status Gateway::Start() {
  const std::string& address = impl_->options.address;
  const auto colon = address.rfind(':');
  if (colon == std::string::npos)
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "--http wants host:port (e.g. 127.0.0.1:8080, port 0 = any free) or off; "
                        "got \"" +
                            address + "\"");
  std::string host = address.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  int port = 0;
  try {
    port = std::stoi(address.substr(colon + 1));
  } catch (...) {
    port = -1;
  }
  if (port < 0 || port > 65535)
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "--http port must be 0..65535; got \"" + address + "\"");
  beast::error_code ec;
  tcp::resolver resolver(impl_->ioc);
  auto results = resolver.resolve(host, std::to_string(port), ec);
  if (ec || results.empty())
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "--http host \"" + host + "\" does not resolve: " + ec.message());
  tcp::endpoint endpoint = results.begin()->endpoint();
  if (!impl_->options.tls_cert_pem.empty()) {
    const GatewayOptions& o = impl_->options;
    auto& tls = impl_->tls.emplace(net::ssl::context::tls_server);
    tls.set_options(net::ssl::context::default_workarounds | net::ssl::context::no_sslv2 |
                    net::ssl::context::no_sslv3 | net::ssl::context::no_tlsv1 |
                    net::ssl::context::no_tlsv1_1 | net::ssl::context::single_dh_use);
    tls.use_certificate_chain(net::buffer(o.tls_cert_pem), ec);
    if (!ec) tls.use_private_key(net::buffer(o.tls_key_pem), net::ssl::context::pem, ec);
    if (!ec && !o.tls_client_ca_pem.empty()) {
      tls.add_certificate_authority(net::buffer(o.tls_client_ca_pem), ec);
      tls.set_verify_mode(net::ssl::verify_peer | net::ssl::verify_fail_if_no_peer_cert);
    }
    if (ec)
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          "the studio's TLS certificate or key does not load: " + ec.message() +
                              " (--tls-cert wants a PEM certificate chain, --tls-key its PEM "
                              "private key)");
  }
  auto& acc = impl_->acceptor;
  acc.open(endpoint.protocol(), ec);
  if (!ec) acc.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) acc.bind(endpoint, ec);
  if (!ec) acc.listen(net::socket_base::max_listen_connections, ec);
  if (ec)
    return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                        "cannot serve the studio on " + address + ": " + ec.message() +
                            " (another program holds the port?); choose another --http "
                            "host:port, or --http off");
  impl_->port = acc.local_endpoint().port();
  impl_->work.emplace(net::make_work_guard(impl_->ioc));
  impl_->Accept();
  for (int i = 0; i < std::max(1, impl_->options.threads); ++i)
    impl_->threads.emplace_back([this] {
      pthread_setname_np(pthread_self(), "rheod-http");  // for top -H and the benchmark
      impl_->ioc.run();
    });
  return grpc::Status::OK;
}

int Gateway::port() const {
  return impl_->port;
}

void Gateway::Stop() {
  if (!impl_ || impl_->threads.empty() || impl_->stopping.exchange(true)) return;
  net::post(impl_->ioc, [this] {
    beast::error_code ec;
    impl_->acceptor.close(ec);
  });
  {
    std::lock_guard<std::mutex> lock(impl_->sessions_mutex);
    for (auto& w : impl_->sessions)
      if (auto s = w.lock()) s->Close();
  }
  // Calls post their ends to the sessions' strands: wait until every one has finished (a
  // client-side cancel completes at once) before the threads stop.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (impl_->bridge.live_calls() > 0 && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  impl_->work.reset();
  impl_->ioc.stop();
  for (auto& t : impl_->threads) t.join();
  impl_->threads.clear();
}

}  // namespace rheo::daemon::web
