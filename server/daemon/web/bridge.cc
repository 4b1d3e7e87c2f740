#include "daemon/web/bridge.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/dynamic_message.h>
#include <google/protobuf/message.h>
#include <google/protobuf/util/json_util.h>

#include <vector>

namespace rheo::daemon::web {
namespace {

namespace pb = google::protobuf;

// The services the bridge reaches: the whole public API.
constexpr const char* kServices[] = {"rheo.v1.AuthService",   "rheo.v1.DaemonService",
                                     "rheo.v1.DeviceService", "rheo.v1.FrameService",
                                     "rheo.v1.ObjectService", "rheo.v1.RecordingService",
                                     "rheo.v1.SceneService"};

std::string Flatten(const grpc::ByteBuffer& buffer) {
  std::vector<grpc::Slice> slices;
  std::string out;
  if (!buffer.Dump(&slices).ok()) return out;
  out.reserve(buffer.Length());
  for (const grpc::Slice& s : slices)
    out.append(reinterpret_cast<const char*>(s.begin()), s.size());
  return out;
}

std::unique_ptr<pb::Message> NewMessage(const pb::Descriptor* type) {
  const pb::Message* prototype = pb::MessageFactory::generated_factory()->GetPrototype(type);
  return std::unique_ptr<pb::Message>(prototype ? prototype->New() : nullptr);
}

}  // namespace

Bridge::Bridge(std::shared_ptr<grpc::Channel> channel)
    : channel_(std::move(channel)), stub_(channel_) {
  const pb::DescriptorPool* pool = pb::DescriptorPool::generated_pool();
  for (const char* name : kServices) {
    const pb::ServiceDescriptor* service = pool->FindServiceByName(name);
    if (!service) continue;  // not compiled into this build
    for (int i = 0; i < service->method_count(); ++i) {
      const pb::MethodDescriptor* m = service->method(i);
      MethodInfo info;
      info.path = "/" + service->full_name() + "/" + m->name();
      info.input = m->input_type();
      info.output = m->output_type();
      info.client_streaming = m->client_streaming();
      info.server_streaming = m->server_streaming();
      methods_.emplace(service->full_name() + "/" + m->name(), std::move(info));
    }
  }
}

const MethodInfo* Bridge::Find(const std::string& method) const {
  auto it = methods_.find(!method.empty() && method[0] == '/' ? method.substr(1) : method);
  return it == methods_.end() ? nullptr : &it->second;
}

std::string Bridge::MethodList() const {
  std::string s;
  std::string last_service;
  for (const auto& [name, info] : methods_) {
    const std::string service = name.substr(0, name.find('/'));
    if (service != last_service) {
      if (!s.empty()) s += "; ";
      s += service + ": ";
      last_service = service;
    } else {
      s += ", ";
    }
    s += name.substr(name.find('/') + 1);
  }
  return s;
}

grpc::Status Bridge::JsonToBinary(const pb::Descriptor* type, const std::string& json,
                                  std::string* bytes) const {
  std::unique_ptr<pb::Message> m = NewMessage(type);
  if (!m) return grpc::Status(grpc::StatusCode::INTERNAL, "no message type " + type->full_name());
  pb::util::JsonParseOptions options;
  options.ignore_unknown_fields = false;
  auto status = pb::util::JsonStringToMessage(json, m.get(), options);
  if (!status.ok())
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "the request is not a valid " + type->full_name() + " (see proto/" +
                            type->file()->name() + "): " + std::string(status.message()));
  if (!m->SerializeToString(bytes))
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "the request for " + type->full_name() + " cannot be encoded");
  return grpc::Status::OK;
}

grpc::Status Bridge::BinaryToJson(const pb::Descriptor* type, const std::string& bytes,
                                  std::string* json) const {
  std::unique_ptr<pb::Message> m = NewMessage(type);
  if (!m || !m->ParseFromString(bytes))
    return grpc::Status(grpc::StatusCode::INTERNAL,
                        "the daemon's response is not a " + type->full_name());
  pb::util::JsonPrintOptions options;
  options.always_print_primitive_fields = true;
  auto status = pb::util::MessageToJsonString(*m, json, options);
  if (!status.ok())
    return grpc::Status(
        grpc::StatusCode::INTERNAL,
        "cannot write " + type->full_name() + " as JSON: " + std::string(status.message()));
  return grpc::Status::OK;
}

Call::Call(Bridge& bridge, const MethodInfo& method, uint32_t id, bool binary,
           const std::string& authorization, std::weak_ptr<CallSink> sink)
    : bridge_(bridge), method_(method), id_(id), binary_(binary), sink_(std::move(sink)) {
  if (!authorization.empty()) context_.AddMetadata("authorization", authorization);
}

Call::~Call() = default;

void Call::Start(const std::string* first, bool half_close) {
  self_ = shared_from_this();
  bridge_.live_calls_.fetch_add(1);
  bridge_.stub().PrepareBidiStreamingCall(&context_, method_.path, grpc::StubOptions(), this);
  // The hold lets reads and writes start from outside reactions (the WebSocket's threads); it is
  // released when the responses end.
  AddHold();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (first) writes_.push_back(*first);
    writes_done_wanted_ = half_close;
    StartNextWriteLocked();
  }
  StartRead(&response_);
  StartCall();
}

void Call::StartNextWriteLocked() {
  if (write_in_flight_ || reads_ended_ || writes_done_started_) return;
  if (!writes_.empty()) {
    writing_ = std::move(writes_.front());
    writes_.pop_front();
    grpc::Slice slice(writing_);
    write_buffer_ = grpc::ByteBuffer(&slice, 1);
    write_in_flight_ = true;
    if (writes_.empty() && writes_done_wanted_) {
      writes_done_started_ = true;
      StartWriteLast(&write_buffer_, grpc::WriteOptions());
    } else {
      StartWrite(&write_buffer_);
    }
  } else if (writes_done_wanted_) {
    writes_done_started_ = true;
    StartWritesDone();
  }
}

void Call::Write(std::string bytes) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (reads_ended_ || writes_done_wanted_) return;  // the call is over or half-closed
  if (!method_.client_streaming && (write_in_flight_ || !writes_.empty() || writes_done_started_)) {
    // A unary or server-streaming method takes one request.
    local_error_ = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                                method_.path.substr(1) + " takes one request, not a stream");
    context_.TryCancel();
    return;
  }
  if (writes_.size() >= kMaxQueuedWrites) {
    local_error_ = grpc::Status(
        grpc::StatusCode::RESOURCE_EXHAUSTED,
        "more than " + std::to_string(kMaxQueuedWrites) +
            " requests wait to be sent on this call; send them no faster than the daemon "
            "answers");
    context_.TryCancel();
    return;
  }
  writes_.push_back(std::move(bytes));
  StartNextWriteLocked();
}

void Call::WritesDone() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (reads_ended_ || writes_done_wanted_) return;
  writes_done_wanted_ = true;
  StartNextWriteLocked();
}

void Call::Cancel() {
  context_.TryCancel();
}

void Call::Fail(grpc::Status status) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (local_error_.ok()) local_error_ = std::move(status);
  }
  context_.TryCancel();
}

void Call::Abandon() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    sink_.reset();
  }
  context_.TryCancel();
  ReadNext();  // a response waiting for the gone session is not written anywhere
}

void Call::OnWriteDone(bool ok) {
  std::lock_guard<std::mutex> lock(mutex_);
  write_in_flight_ = false;
  if (!ok) {
    writes_.clear();  // the call is ending; its status follows in OnDone
    return;
  }
  StartNextWriteLocked();
}

void Call::OnReadDone(bool ok) {
  if (!ok) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      reads_ended_ = true;
    }
    RemoveHold();
    return;
  }
  std::string payload = Flatten(response_);
  std::string out;
  if (binary_) {
    out = std::move(payload);
  } else if (grpc::Status s = bridge_.BinaryToJson(method_.output, payload, &out); !s.ok()) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      local_error_ = s;
    }
    context_.TryCancel();
    StartRead(&response_);
    return;
  }
  std::shared_ptr<CallSink> sink;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    sink = sink_.lock();
    waiting_for_sink_ = sink != nullptr;
  }
  if (!sink) {
    StartRead(&response_);
    return;
  }
  sink->Deliver(id_, binary_, std::move(out), [self = shared_from_this()] { self->ReadNext(); });
}

void Call::ReadNext() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (reads_ended_ || !waiting_for_sink_) return;
    waiting_for_sink_ = false;
  }
  StartRead(&response_);
}

void Call::OnDone(const grpc::Status& status) {
  grpc::Status final_status = status;
  std::shared_ptr<CallSink> sink;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!local_error_.ok()) final_status = local_error_;
    sink = sink_.lock();
  }
  if (sink) sink->Finish(id_, final_status);
  bridge_.live_calls_.fetch_sub(1);
  std::shared_ptr<Call> keep = std::move(self_);  // may be the last owner: released on return
}

}  // namespace rheo::daemon::web
