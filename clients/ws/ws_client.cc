#include "rheo/ws/ws_client.h"

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>
#include <optional>

namespace rheo::ws {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using TlsStream = beast::ssl_stream<beast::tcp_stream>;

namespace {

// A client TLS context that verifies the server against `tls.ca_file` (and presents a client
// certificate when given). Throws on unreadable files.
std::unique_ptr<net::ssl::context> MakeContext(const Tls& tls) {
  auto ctx = std::make_unique<net::ssl::context>(net::ssl::context::tls_client);
  ctx->set_options(net::ssl::context::default_workarounds | net::ssl::context::no_sslv2 |
                   net::ssl::context::no_sslv3 | net::ssl::context::no_tlsv1 |
                   net::ssl::context::no_tlsv1_1);
  if (!tls.ca_file.empty())
    ctx->load_verify_file(tls.ca_file);
  else
    ctx->set_default_verify_paths();
  if (!tls.cert_file.empty()) {
    ctx->use_certificate_chain_file(tls.cert_file);
    ctx->use_private_key_file(tls.key_file, net::ssl::context::pem);
  }
  ctx->set_verify_mode(net::ssl::verify_peer);
  ctx->set_verify_callback(net::ssl::host_name_verification(tls.server_name));
  return ctx;
}

// SNI, then the handshake; throws on failure.
void Handshake(TlsStream& stream, const Tls& tls) {
  if (!SSL_set_tlsext_host_name(stream.native_handle(), tls.server_name.c_str()))
    throw beast::system_error(
        beast::error_code(static_cast<int>(::ERR_get_error()), net::error::get_ssl_category()));
  stream.handshake(net::ssl::stream_base::client);
}

}  // namespace

struct Client::Impl {
  net::io_context ioc;
  std::unique_ptr<net::ssl::context> tls;
  std::optional<websocket::stream<beast::tcp_stream>> plain;
  std::optional<websocket::stream<TlsStream>> secure;
  beast::flat_buffer buffer;
  bool reading = false;
  std::optional<beast::error_code> read_result;

  // `f` on whichever stream this connection has.
  template <class F>
  decltype(auto) With(F&& f) {
    return secure ? f(*secure) : f(*plain);
  }
};

Client::Client(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Client::~Client() {
  if (impl_) {
    impl_->With([](auto& ws) {
      beast::error_code ec;
      beast::get_lowest_layer(ws).socket().close(ec);
    });
  }
}

std::unique_ptr<Client> Client::Connect(const std::string& host, int port, std::string* error,
                                        const std::string& origin, const std::string& target,
                                        int receive_buffer_bytes, const Tls* tls) {
  auto impl = std::make_unique<Impl>();
  try {
    if (tls) {
      impl->tls = MakeContext(*tls);
      impl->secure.emplace(impl->ioc, *impl->tls);
    } else {
      impl->plain.emplace(impl->ioc);
    }
    tcp::resolver resolver(impl->ioc);
    auto results = resolver.resolve(host, std::to_string(port));
    const tcp::endpoint endpoint = results.begin()->endpoint();
    const bool ok = impl->With([&](auto& ws) {
      auto& socket = beast::get_lowest_layer(ws).socket();
      socket.open(endpoint.protocol());
      if (receive_buffer_bytes > 0)
        socket.set_option(net::socket_base::receive_buffer_size(receive_buffer_bytes));
      socket.connect(endpoint);
      socket.set_option(tcp::no_delay(true));
      if constexpr (std::is_same_v<std::decay_t<decltype(ws)>, websocket::stream<TlsStream>>)
        Handshake(ws.next_layer(), *tls);
      ws.set_option(websocket::stream_base::decorator([origin](websocket::request_type& req) {
        if (!origin.empty()) req.set(http::field::origin, origin);
      }));
      ws.read_message_max(256u << 20);
      websocket::response_type res;
      beast::error_code ec;
      ws.handshake(res, host + ":" + std::to_string(port), target, ec);
      if (ec) {
        if (error)
          *error = "WebSocket handshake failed: " + ec.message() + " (HTTP " +
                   std::to_string(res.result_int()) + ": " + res.body() + ")";
        return false;
      }
      beast::get_lowest_layer(ws).expires_never();
      return true;
    });
    if (!ok) return nullptr;
  } catch (const std::exception& e) {
    if (error) *error = std::string("cannot connect: ") + e.what();
    return nullptr;
  }
  return std::unique_ptr<Client>(new Client(std::move(impl)));
}

bool Client::SendText(const std::string& text) {
  return Send(text, false);
}
bool Client::SendBinary(const std::string& bytes) {
  return Send(bytes, true);
}

bool Client::Send(const std::string& data, bool binary) {
  beast::error_code ec;
  impl_->With([&](auto& ws) {
    ws.binary(binary);
    ws.write(net::buffer(data), ec);
  });
  if (ec) error_ = ec.message();
  return !ec;
}

bool Client::Read(Message* out, std::chrono::milliseconds timeout) {
  Impl& d = *impl_;
  if (!d.reading) {
    d.reading = true;
    d.read_result.reset();
    d.With([&d](auto& ws) {
      ws.async_read(d.buffer, [&d](beast::error_code ec, size_t) { d.read_result = ec; });
    });
  }
  d.ioc.restart();
  const auto until = std::chrono::steady_clock::now() + timeout;
  while (!d.read_result && std::chrono::steady_clock::now() < until) d.ioc.run_one_until(until);
  if (!d.read_result) {
    error_ = "timed out";
    return false;  // the read stays pending: the next Read continues it
  }
  d.reading = false;
  if (*d.read_result) {
    error_ = d.read_result->message();
    return false;
  }
  out->binary = d.With([](auto& ws) { return ws.got_binary(); });
  out->data = beast::buffers_to_string(d.buffer.data());
  d.buffer.consume(d.buffer.size());
  return true;
}

void Client::Close() {
  impl_->With([](auto& ws) {
    beast::error_code ec;
    ws.close(websocket::close_code::normal, ec);
  });
}

namespace {

template <class Stream>
int Exchange(Stream& stream, const std::string& host, int port, const std::string& method,
             const std::string& target, std::string* body, std::string* content_type) {
  http::request<http::string_body> req{http::string_to_verb(method), target, 11};
  req.set(http::field::host, host + ":" + std::to_string(port));
  http::write(stream, req);
  beast::flat_buffer buffer;
  http::response_parser<http::string_body> parser;
  parser.body_limit(64u << 20);
  if (method == "HEAD") parser.skip(true);
  http::read(stream, buffer, parser);
  auto res = parser.release();
  if (body) *body = res.body();
  if (content_type) *content_type = std::string(res[http::field::content_type]);
  return res.result_int();
}

}  // namespace

int HttpRequest(const std::string& host, int port, const std::string& method,
                const std::string& target, std::string* body, std::string* content_type,
                const Tls* tls) {
  try {
    net::io_context ioc;
    tcp::resolver resolver(ioc);
    const auto endpoints = resolver.resolve(host, std::to_string(port));
    int code = 0;
    beast::error_code ec;
    if (tls) {
      auto ctx = MakeContext(*tls);
      TlsStream stream(ioc, *ctx);
      beast::get_lowest_layer(stream).connect(endpoints);
      Handshake(stream, *tls);
      code = Exchange(stream, host, port, method, target, body, content_type);
      stream.shutdown(ec);
    } else {
      beast::tcp_stream stream(ioc);
      stream.connect(endpoints);
      code = Exchange(stream, host, port, method, target, body, content_type);
      stream.socket().shutdown(tcp::socket::shutdown_both, ec);
    }
    return code;
  } catch (const std::exception& e) {
    if (body) *body = e.what();
    return 0;
  }
}

}  // namespace rheo::ws
