// The studio's files over HTTP: GET and HEAD under one folder, three.js from its npm install.
#pragma once

#include <boost/beast/http.hpp>
#include <filesystem>
#include <optional>
#include <string>

namespace rheo::daemon::web {

class StaticFiles {
 public:
  explicit StaticFiles(std::filesystem::path root);

  /// The response to one request: the file, 404 with a reason, 405 for other methods, 400 for
  /// a path that leaves the folder.
  boost::beast::http::response<boost::beast::http::string_body> Serve(
      const boost::beast::http::request<boost::beast::http::string_body>& request) const;

  /// The file a URL path maps to under the root, or nullopt for a path that is not allowed
  /// (outside the root, "..", NUL, backslash, bad percent escapes). Pure: no file access.
  static std::optional<std::filesystem::path> Resolve(const std::filesystem::path& root,
                                                      const std::string& target);
  static const char* ContentType(const std::filesystem::path& file);

 private:
  std::filesystem::path root_;
};

}  // namespace rheo::daemon::web
