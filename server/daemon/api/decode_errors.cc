#include "daemon/api/decode_errors.h"

#include <google/protobuf/descriptor.h>

#include <string>

namespace rheo::daemon {
namespace {

// "rheo.v1.CreateObjectRequest" for "/rheo.v1.ObjectService/CreateObject".
std::string InputTypeOf(const std::string& method) {
  const size_t slash = method.rfind('/');
  if (method.size() < 2 || slash == std::string::npos || slash == 0) return "";
  const std::string service = method.substr(1, slash - 1);
  const auto* s = google::protobuf::DescriptorPool::generated_pool()->FindServiceByName(service);
  const auto* m = s ? s->FindMethodByName(method.substr(slash + 1)) : nullptr;
  return m ? m->input_type()->full_name() : "";
}

class DecodeErrorInterceptor final : public grpc::experimental::Interceptor {
 public:
  explicit DecodeErrorInterceptor(grpc::experimental::ServerRpcInfo* info)
      : method_(info->method() ? info->method() : "") {}

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(
            grpc::experimental::InterceptionHookPoints::PRE_SEND_STATUS)) {
      const grpc::Status s = methods->GetSendStatus();
      // gRPC's own answer when the payload does not parse (our handlers always say something).
      if (s.error_code() == grpc::StatusCode::INTERNAL &&
          (s.error_message().empty() || s.error_message() == "No payload")) {
        const std::string type = InputTypeOf(method_);
        methods->ModifySendStatus(
            grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                         "the request to " + method_ + " could not be decoded" +
                             (type.empty() ? std::string() : " as a " + type) +
                             "; send that protobuf message, as proto/rheo/v1 defines it"));
      }
    }
    methods->Proceed();
  }

 private:
  std::string method_;
};

}  // namespace

grpc::experimental::Interceptor* DecodeErrorInterceptorFactory::CreateServerInterceptor(
    grpc::experimental::ServerRpcInfo* info) {
  return new DecodeErrorInterceptor(info);
}

}  // namespace rheo::daemon
