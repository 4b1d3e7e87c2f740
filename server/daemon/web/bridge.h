// The generic bridge: any rheo.v1 method called through a gRPC channel to the daemon's own
// server (its gateway socket, where tokens are checked as on every port), so the WebSocket carries
// exactly the gRPC API (its validation, limits and status codes) and nothing is implemented twice.
// Requests and responses are converted between protobuf and the standard JSON mapping with the
// descriptors compiled into the daemon.
#pragma once

#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/support/byte_buffer.h>

#include <atomic>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>

namespace google::protobuf {
class Descriptor;
}

namespace rheo::daemon::web {

struct MethodInfo {
  std::string path;  // "/rheo.v1.SceneService/GetScene"
  const google::protobuf::Descriptor* input = nullptr;
  const google::protobuf::Descriptor* output = nullptr;
  bool client_streaming = false;
  bool server_streaming = false;
};

/// Where a call's responses go (a WebSocket session). Called from gRPC's threads.
class CallSink {
 public:
  virtual ~CallSink() = default;
  /// Sends one response; `written` runs once it left (then the call reads the next one), or never
  /// when the session is gone (the call is then abandoned by the session).
  virtual void Deliver(uint32_t id, bool binary, std::string payload,
                       std::function<void()> written) = 0;
  /// The call ended with `status`; its last message.
  virtual void Finish(uint32_t id, const grpc::Status& status) = 0;
};

class Bridge;

/// One call in flight. Reads one response at a time: the next is asked for only after the
/// previous one was written to the WebSocket, so a slow browser holds back its own stream (a
/// frame stream then skips frames at the daemon, newest wins) and never grows a queue.
class Call : public grpc::ClientBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>,
             public std::enable_shared_from_this<Call> {
 public:
  /// `authorization`: "Bearer TOKEN" from the connection's auth message ("" sends none).
  Call(Bridge& bridge, const MethodInfo& method, uint32_t id, bool binary,
       const std::string& authorization, std::weak_ptr<CallSink> sink);
  ~Call() override;

  /// Starts the call; `first` is the request (unary and server-streaming calls, which are then
  /// half-closed at once) or empty for a client stream.
  void Start(const std::string* first, bool half_close);
  /// Queues the next request of a client stream (protobuf bytes). RESOURCE_EXHAUSTED cancels
  /// the call if more than kMaxQueuedWrites wait.
  void Write(std::string bytes);
  void WritesDone();
  void Cancel();
  /// Ends the call with `status` (a bad request message from the client).
  void Fail(grpc::Status status);
  /// The session is gone: cancel, and let the call finish without it.
  void Abandon();

  const MethodInfo& method() const { return method_; }
  static constexpr size_t kMaxQueuedWrites = 256;

  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override;
  void OnDone(const grpc::Status& status) override;

 private:
  void ReadNext();
  void StartNextWriteLocked();

  Bridge& bridge_;
  const MethodInfo& method_;
  const uint32_t id_;
  const bool binary_;
  std::weak_ptr<CallSink> sink_;
  grpc::ClientContext context_;
  grpc::ByteBuffer response_;
  std::shared_ptr<Call> self_;  // alive until OnDone

  std::mutex mutex_;
  std::deque<std::string> writes_;
  std::string writing_;
  grpc::ByteBuffer write_buffer_;
  bool write_in_flight_ = false;
  bool writes_done_wanted_ = false;
  bool writes_done_started_ = false;
  bool reads_ended_ = false;  // the hold on the call is released
  bool waiting_for_sink_ = false;
  grpc::Status local_error_;  // set when the bridge itself ends the call
};

class Bridge {
 public:
  explicit Bridge(std::shared_ptr<grpc::Channel> channel);

  /// "rheo.v1.SceneService/GetScene" (a leading "/" is accepted) or nullptr.
  const MethodInfo* Find(const std::string& method) const;
  /// JSON text (standard mapping) to protobuf bytes of `type`; INVALID_ARGUMENT naming the
  /// problem otherwise.
  grpc::Status JsonToBinary(const google::protobuf::Descriptor* type, const std::string& json,
                            std::string* bytes) const;
  /// protobuf bytes of `type` to JSON text (every field, lowerCamelCase names).
  grpc::Status BinaryToJson(const google::protobuf::Descriptor* type, const std::string& bytes,
                            std::string* json) const;
  /// A list of the methods for an error message.
  std::string MethodList() const;

  grpc::GenericStub& stub() { return stub_; }
  /// Calls not yet finished (for an orderly stop).
  int live_calls() const { return live_calls_.load(); }

 private:
  std::shared_ptr<grpc::Channel> channel_;
  grpc::GenericStub stub_;
  std::map<std::string, MethodInfo> methods_;
  friend class Call;  // counts itself in and out of live_calls_
  std::atomic<int> live_calls_{0};
};

}  // namespace rheo::daemon::web
