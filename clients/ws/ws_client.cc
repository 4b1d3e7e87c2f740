#include "rheo/ws/ws_client.h"

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <optional>

namespace rheo::ws {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

struct Client::Impl {
  net::io_context ioc;
  websocket::stream<beast::tcp_stream> ws{ioc};
  beast::flat_buffer buffer;
  bool reading = false;
  std::optional<beast::error_code> read_result;
};

Client::Client(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Client::~Client() {
  if (impl_) {
    beast::error_code ec;
    beast::get_lowest_layer(impl_->ws).socket().close(ec);
  }
}

std::unique_ptr<Client> Client::Connect(const std::string& host, int port, std::string* error,
                                        const std::string& origin, const std::string& target,
                                        int receive_buffer_bytes) {
  auto impl = std::make_unique<Impl>();
  try {
    tcp::resolver resolver(impl->ioc);
    auto results = resolver.resolve(host, std::to_string(port));
    auto& socket = beast::get_lowest_layer(impl->ws).socket();
    const tcp::endpoint endpoint = results.begin()->endpoint();
    socket.open(endpoint.protocol());
    if (receive_buffer_bytes > 0)
      socket.set_option(net::socket_base::receive_buffer_size(receive_buffer_bytes));
    socket.connect(endpoint);
    beast::get_lowest_layer(impl->ws).socket().set_option(tcp::no_delay(true));
    impl->ws.set_option(websocket::stream_base::decorator([origin](websocket::request_type& req) {
      if (!origin.empty()) req.set(http::field::origin, origin);
    }));
    impl->ws.read_message_max(256u << 20);
    websocket::response_type res;
    beast::error_code ec;
    impl->ws.handshake(res, host + ":" + std::to_string(port), target, ec);
    if (ec) {
      if (error)
        *error = "WebSocket handshake failed: " + ec.message() + " (HTTP " +
                 std::to_string(res.result_int()) + ": " + res.body() + ")";
      return nullptr;
    }
    beast::get_lowest_layer(impl->ws).expires_never();
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
  impl_->ws.binary(binary);
  impl_->ws.write(net::buffer(data), ec);
  if (ec) error_ = ec.message();
  return !ec;
}

bool Client::Read(Message* out, std::chrono::milliseconds timeout) {
  Impl& d = *impl_;
  if (!d.reading) {
    d.reading = true;
    d.read_result.reset();
    d.ws.async_read(d.buffer, [&d](beast::error_code ec, size_t) { d.read_result = ec; });
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
  out->binary = d.ws.got_binary();
  out->data = beast::buffers_to_string(d.buffer.data());
  d.buffer.consume(d.buffer.size());
  return true;
}

void Client::Close() {
  beast::error_code ec;
  impl_->ws.close(websocket::close_code::normal, ec);
}

int HttpRequest(const std::string& host, int port, const std::string& method,
                const std::string& target, std::string* body, std::string* content_type) {
  try {
    net::io_context ioc;
    beast::tcp_stream stream(ioc);
    tcp::resolver resolver(ioc);
    stream.connect(resolver.resolve(host, std::to_string(port)));
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
    beast::error_code ec;
    stream.socket().shutdown(tcp::socket::shutdown_both, ec);
    return res.result_int();
  } catch (const std::exception& e) {
    if (body) *body = e.what();
    return 0;
  }
}

}  // namespace rheo::ws
