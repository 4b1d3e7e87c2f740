#include "daemon/web/static_files.h"

#include <fstream>
#include <sstream>

namespace rheo::daemon::web {

namespace http = boost::beast::http;

StaticFiles::StaticFiles(std::filesystem::path root) : root_(std::move(root)) {}

std::optional<std::filesystem::path> StaticFiles::Resolve(const std::filesystem::path& root,
                                                          const std::string& target) {
  std::string path = target.substr(0, target.find_first_of("?#"));
  if (path.empty() || path[0] != '/') return std::nullopt;
  // Percent-decoding (RFC 3986 section 2.1).
  std::string decoded;
  for (size_t i = 0; i < path.size(); ++i) {
    char c = path[i];
    if (c == '%') {
      if (i + 2 >= path.size() || !std::isxdigit(static_cast<unsigned char>(path[i + 1])) ||
          !std::isxdigit(static_cast<unsigned char>(path[i + 2])))
        return std::nullopt;
      c = static_cast<char>(std::stoi(path.substr(i + 1, 2), nullptr, 16));
      i += 2;
    }
    if (c == '\0' || c == '\\') return std::nullopt;
    decoded += c;
  }
  if (decoded == "/") decoded = "/index.html";
  // Every segment must be a plain name: no "..", no ".", no empty ones in the middle.
  std::filesystem::path rel;
  size_t start = 1;
  while (start <= decoded.size()) {
    size_t end = decoded.find('/', start);
    if (end == std::string::npos) end = decoded.size();
    std::string segment = decoded.substr(start, end - start);
    if (segment.empty() || segment == "." || segment == "..") return std::nullopt;
    rel /= segment;
    start = end + 1;
  }
  // three.js comes from its npm install: /vendor/three/... is node_modules/three/...
  auto it = rel.begin();
  if (it != rel.end() && *it == "vendor") {
    std::filesystem::path mapped = "node_modules";
    for (++it; it != rel.end(); ++it) mapped /= *it;
    auto first = std::next(mapped.begin());
    if (first == mapped.end() || *first != "three") return std::nullopt;  // only three.js
    rel = mapped;
  } else if (it != rel.end() && *it == "node_modules") {
    return std::nullopt;  // the rest of the npm install is not served
  }
  return root / rel;
}

const char* StaticFiles::ContentType(const std::filesystem::path& file) {
  const std::string ext = file.extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "text/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".json" || ext == ".map") return "application/json";
  if (ext == ".svg") return "image/svg+xml";
  if (ext == ".png") return "image/png";
  if (ext == ".jpg" || ext == ".jpeg") return "image/jpeg";
  if (ext == ".ico") return "image/x-icon";
  if (ext == ".wasm") return "application/wasm";
  return "application/octet-stream";
}

http::response<http::string_body> StaticFiles::Serve(
    const http::request<http::string_body>& req) const {
  auto text = [&](http::status status, std::string body) {
    http::response<http::string_body> res{status, req.version()};
    res.set(http::field::server, "rheod");
    res.set(http::field::content_type, "text/plain; charset=utf-8");
    res.keep_alive(req.keep_alive());
    res.body() = std::move(body);
    res.prepare_payload();
    return res;
  };
  if (req.method() != http::verb::get && req.method() != http::verb::head) {
    auto res = text(http::status::method_not_allowed, "only GET and HEAD are served here\n");
    res.set(http::field::allow, "GET, HEAD");
    return res;
  }
  const std::string target(req.target());
  std::optional<std::filesystem::path> file = Resolve(root_, target);
  if (!file) return text(http::status::bad_request, "not a file path: " + target + "\n");
  std::error_code ec;
  if (!std::filesystem::is_regular_file(*file, ec)) {
    if (target.rfind("/vendor/three/", 0) == 0)
      return text(http::status::not_found,
                  "three.js is not installed: run `npm ci` in clients/web (scripts/install-deps "
                  "does)\n");
    return text(http::status::not_found, "no such file: " + target + "\n");
  }
  std::ifstream in(*file, std::ios::binary);
  std::ostringstream body;
  body << in.rdbuf();
  if (!in) return text(http::status::internal_server_error, "cannot read " + target + "\n");
  http::response<http::string_body> res{http::status::ok, req.version()};
  res.set(http::field::server, "rheod");
  res.set(http::field::content_type, ContentType(*file));
  res.set(http::field::cache_control, "no-cache");
  res.set("X-Content-Type-Options", "nosniff");
  res.keep_alive(req.keep_alive());
  res.body() = body.str();
  res.prepare_payload();
  if (req.method() == http::verb::head) res.body().clear();
  return res;
}

}  // namespace rheo::daemon::web
