// A request gRPC cannot decode into its protobuf message never reaches a handler: gRPC answers
// INTERNAL with an empty message. This server interceptor turns that answer into
// INVALID_ARGUMENT naming the method and the message it expects.
#pragma once

#include <grpcpp/support/server_interceptor.h>

namespace rheo::daemon {

class DecodeErrorInterceptorFactory final
    : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  grpc::experimental::Interceptor* CreateServerInterceptor(
      grpc::experimental::ServerRpcInfo* info) override;
};

}  // namespace rheo::daemon
