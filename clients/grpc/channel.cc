#include "rheo/client/channel.h"

#include <grpcpp/support/client_interceptor.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <vector>

namespace rheo::client {
namespace {

// Adds the token to every call's initial metadata, so no call site can forget it.
class TokenInterceptor final : public grpc::experimental::Interceptor {
 public:
  explicit TokenInterceptor(const std::string& header) : header_(header) {}
  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(
            grpc::experimental::InterceptionHookPoints::PRE_SEND_INITIAL_METADATA))
      methods->GetSendInitialMetadata()->insert({"authorization", header_});
    methods->Proceed();
  }

 private:
  const std::string& header_;
};

class TokenInterceptorFactory final : public grpc::experimental::ClientInterceptorFactoryInterface {
 public:
  explicit TokenInterceptorFactory(std::string token) : header_("Bearer " + std::move(token)) {}
  grpc::experimental::Interceptor* CreateClientInterceptor(
      grpc::experimental::ClientRpcInfo*) override {
    return new TokenInterceptor(header_);
  }

 private:
  std::string header_;  // outlives every interceptor: the channel owns the factory
};

}  // namespace

bool ReadWholeFile(const std::string& path, std::string& out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::ostringstream ss;
  ss << in.rdbuf();
  out = ss.str();
  return true;
}

std::shared_ptr<grpc::Channel> Connect(const ChannelOptions& o, std::string* error) {
  std::shared_ptr<grpc::ChannelCredentials> creds;
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(o.max_receive_bytes);
  if (o.tls_ca_file.empty()) {
    creds = grpc::InsecureChannelCredentials();
  } else {
    grpc::SslCredentialsOptions ssl;
    if (!ReadWholeFile(o.tls_ca_file, ssl.pem_root_certs)) {
      if (error) *error = "cannot read the CA certificate " + o.tls_ca_file;
      return nullptr;
    }
    if (!o.tls_cert_file.empty() && (!ReadWholeFile(o.tls_cert_file, ssl.pem_cert_chain) ||
                                     !ReadWholeFile(o.tls_key_file, ssl.pem_private_key))) {
      if (error)
        *error = "cannot read the client certificate " + o.tls_cert_file + " or its key " +
                 o.tls_key_file;
      return nullptr;
    }
    creds = grpc::SslCredentials(ssl);
    if (!o.tls_server_name.empty()) args.SetSslTargetNameOverride(o.tls_server_name);
  }
  if (o.token.empty()) return grpc::CreateCustomChannel(o.target, creds, args);
  std::vector<std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface>> chain;
  chain.push_back(std::make_unique<TokenInterceptorFactory>(o.token));
  return grpc::experimental::CreateCustomChannelWithInterceptors(o.target, creds, args,
                                                                 std::move(chain));
}

std::string DefaultAdminTokenPath(const std::string& data_dir) {
  if (!data_dir.empty()) return data_dir + "/admin.token";
  if (const char* x = std::getenv("XDG_DATA_HOME"); x && *x)
    return std::string(x) + "/rheo/admin.token";
  if (const char* h = std::getenv("HOME"); h && *h)
    return std::string(h) + "/.local/share/rheo/admin.token";
  return "./rheo-data/admin.token";
}

std::string ReadTokenFile(const std::string& path, std::string* error) {
  std::string s;
  if (!ReadWholeFile(path, s)) {
    if (error) *error = "cannot read the token file " + path;
    return "";
  }
  const auto first = s.find_first_not_of(" \t\r\n");
  const auto last = s.find_last_not_of(" \t\r\n");
  if (first == std::string::npos) {
    if (error) *error = "the token file " + path + " is empty";
    return "";
  }
  return s.substr(first, last - first + 1);
}

}  // namespace rheo::client
