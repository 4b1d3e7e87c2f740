// The table test: every rheo.v1 method, found by reflection over the services' descriptors, gets
// every string and bytes field at 1 MB and every number at NaN, inf, 0, -1 and 1e300 (one field
// at a time, nested messages and oneofs included), and an undecodable payload. Each answer must
// be a clear status code with a short message, the daemon must keep running, and its loop must
// keep its rate.
#include <google/protobuf/descriptor.h>
#include <google/protobuf/dynamic_message.h>
#include <google/protobuf/message.h>
#include <grpcpp/generic/generic_stub.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <thread>

#include "rheo/v1/auth.pb.h"
#include "rheo/v1/daemon.grpc.pb.h"
#include "rheo/v1/device.grpc.pb.h"
#include "rheo/v1/frames.grpc.pb.h"
#include "rheo/v1/objects.grpc.pb.h"
#include "rheo/v1/scene.grpc.pb.h"
#include "rheod_fixture.h"

namespace rheo::testing {
namespace {

using namespace std::chrono_literals;
namespace pb = google::protobuf;

constexpr size_t kMaxMessage = 600;  // a short message: what a person reads, not an echo

struct Answer {
  grpc::Status status;
  int responses = 0;
};

void* Tag(intptr_t i) {
  return reinterpret_cast<void*>(i);
}

// One call of any method through the generic stub: the payload, half-close, read up to two
// responses (then cancel: a stream that answers is fine), the status.
Answer Call(grpc::GenericStub& stub, const std::string& method, const std::string& payload,
            std::chrono::milliseconds deadline) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + deadline);
  grpc::CompletionQueue cq;
  auto call = stub.PrepareCall(&ctx, method, &cq);
  void* got = nullptr;
  bool ok = false;
  Answer a;
  call->StartCall(Tag(1));
  cq.Next(&got, &ok);
  if (ok) {
    grpc::Slice slice(payload);
    grpc::ByteBuffer buffer(&slice, 1);
    call->Write(buffer, Tag(2));
    cq.Next(&got, &ok);
    call->WritesDone(Tag(3));
    cq.Next(&got, &ok);
    for (;;) {
      grpc::ByteBuffer in;
      call->Read(&in, Tag(4));
      cq.Next(&got, &ok);
      if (!ok) break;
      if (++a.responses >= 2) {
        ctx.TryCancel();
        break;
      }
    }
  }
  call->Finish(&a.status, Tag(5));
  cq.Next(&got, &ok);
  cq.Shutdown();
  while (cq.Next(&got, &ok)) {
  }
  return a;
}

// A field path from the request down to one scalar field, with the messages on the way.
using Path = std::vector<const pb::FieldDescriptor*>;

void ScalarFields(const pb::Descriptor* d, Path prefix, int depth, std::vector<Path>* out) {
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    Path p = prefix;
    p.push_back(f);
    if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE) {
      if (depth < 4 && f->message_type()->full_name().rfind("rheo.", 0) == 0)
        ScalarFields(f->message_type(), p, depth + 1, out);
      continue;
    }
    out->push_back(p);
  }
}

// The message at the end of `path` (minus its last field), created on the way.
pb::Message* Reach(pb::Message* m, const Path& path) {
  for (size_t i = 0; i + 1 < path.size(); ++i) {
    const pb::Reflection* r = m->GetReflection();
    m = path[i]->is_repeated() ? r->AddMessage(m, path[i]) : r->MutableMessage(m, path[i]);
  }
  return m;
}

std::string PathName(const Path& p) {
  std::string s;
  for (const auto* f : p) s += (s.empty() ? "" : ".") + f->name();
  return s;
}

// Sets the last field of `path` in `m` to `value` (numbers) or `text` (strings, bytes).
void SetLast(pb::Message* m, const pb::FieldDescriptor* f, double value, const std::string& text) {
  const pb::Reflection* r = m->GetReflection();
  const bool rep = f->is_repeated();
  auto clamp_int = [&](double lo, double hi) {
    if (std::isnan(value)) return 0.0;
    return std::clamp(value, lo, hi);
  };
  switch (f->cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_STRING:
      rep ? r->AddString(m, f, text) : r->SetString(m, f, text);
      break;
    case pb::FieldDescriptor::CPPTYPE_DOUBLE:
      rep ? r->AddDouble(m, f, value) : r->SetDouble(m, f, value);
      break;
    case pb::FieldDescriptor::CPPTYPE_FLOAT:
      rep ? r->AddFloat(m, f, static_cast<float>(value))
          : r->SetFloat(m, f, static_cast<float>(value));
      break;
    case pb::FieldDescriptor::CPPTYPE_INT32: {
      const auto v = static_cast<int32_t>(clamp_int(INT32_MIN, INT32_MAX));
      rep ? r->AddInt32(m, f, v) : r->SetInt32(m, f, v);
      break;
    }
    case pb::FieldDescriptor::CPPTYPE_INT64: {
      const auto v = static_cast<int64_t>(clamp_int(-9.2e18, 9.2e18));
      rep ? r->AddInt64(m, f, v) : r->SetInt64(m, f, v);
      break;
    }
    case pb::FieldDescriptor::CPPTYPE_UINT32: {
      // -1 as the wire has it: the largest value.
      const auto v = value < 0 ? UINT32_MAX : static_cast<uint32_t>(clamp_int(0, UINT32_MAX));
      rep ? r->AddUInt32(m, f, v) : r->SetUInt32(m, f, v);
      break;
    }
    case pb::FieldDescriptor::CPPTYPE_UINT64: {
      const auto v = value < 0 ? UINT64_MAX : static_cast<uint64_t>(clamp_int(0, 1.8e19));
      rep ? r->AddUInt64(m, f, v) : r->SetUInt64(m, f, v);
      break;
    }
    case pb::FieldDescriptor::CPPTYPE_ENUM: {
      const int v = value < 0 ? -1 : (value > 1e3 || std::isnan(value) ? 99 : 0);
      rep ? r->AddEnumValue(m, f, v) : r->SetEnumValue(m, f, v);
      break;
    }
    case pb::FieldDescriptor::CPPTYPE_BOOL:
      rep ? r->AddBool(m, f, value != 0) : r->SetBool(m, f, value != 0);
      break;
    default: break;
  }
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class RheodTable : public ::testing::TestWithParam<const char*> {};

// With each kind of device: the device methods take other paths with each.
INSTANTIATE_TEST_SUITE_P(Devices, RheodTable, ::testing::Values("sim-spidar-g", "network", "none"));

TEST_P(RheodTable, EveryMethodEveryFieldAtItsWorstGetsAClearShortAnswer) {
  // No calls-per-second limit: every case must reach its handler (the limits have a test of
  // their own, rheod_limits_test).
  RheodProcess d({"--device", GetParam(), "--watchdog-timeout", "100", "--limit-calls", "0"});
  ASSERT_TRUE(d.started()) << d.log();
  // One small object stored and in the scene, so that handlers get past "the scene is empty".
  {
    auto objects = v1::ObjectService::NewStub(d.channel());
    v1::CreateObjectRequest req;
    req.mutable_sketch()->set_strokes_json(ReadText(std::string(RHEO_SKETCHES) + "/bean.json"));
    req.mutable_mesh_options()->set_resolution(0.012);
    req.set_add_to_scene(true);
    grpc::ClientContext ctx;
    SetDeadline(ctx, 120s);
    auto reader = objects->CreateObject(&ctx, req);
    v1::CreateObjectProgress p;
    while (reader->Read(&p)) {
    }
    ASSERT_TRUE(reader->Finish().ok());
  }
  const double before = LoopTickRate(d, 2s);

  grpc::GenericStub stub(d.channel());
  // Touch one message of each file, so its descriptors are linked in and registered.
  for (const pb::Descriptor* any :
       {v1::GetStatusRequest::descriptor(), v1::WatchFramesRequest::descriptor(),
        v1::GetSceneRequest::descriptor(), v1::CreateObjectRequest::descriptor(),
        v1::ToolInput::descriptor()})
    ASSERT_NE(any, nullptr);
  const pb::DescriptorPool* pool = pb::DescriptorPool::generated_pool();
  ASSERT_NE(v1::Identity::descriptor(), nullptr);  // links auth.proto's descriptors here
  const std::vector<std::string> services = {"rheo.v1.DaemonService", "rheo.v1.FrameService",
                                             "rheo.v1.SceneService",  "rheo.v1.ObjectService",
                                             "rheo.v1.DeviceService", "rheo.v1.AuthService"};
  const std::set<grpc::StatusCode> clear = {
      grpc::StatusCode::OK,
      grpc::StatusCode::CANCELLED,  // we cancel a stream after two responses
      grpc::StatusCode::INVALID_ARGUMENT,
      grpc::StatusCode::NOT_FOUND,
      grpc::StatusCode::ALREADY_EXISTS,
      grpc::StatusCode::PERMISSION_DENIED,
      grpc::StatusCode::RESOURCE_EXHAUSTED,
      grpc::StatusCode::FAILED_PRECONDITION,
      grpc::StatusCode::OUT_OF_RANGE,
      grpc::StatusCode::UNAUTHENTICATED,
  };
  const std::string mega(1u << 20, 'x');
  const double kInf = std::numeric_limits<double>::infinity();
  const std::vector<double> numbers = {std::nan(""), kInf, -kInf, 0.0, -1.0, 1e300};
  int methods = 0, cases = 0;
  std::map<int, int> by_code;
  for (const std::string& name : services) {
    const pb::ServiceDescriptor* service = pool->FindServiceByName(name);
    ASSERT_NE(service, nullptr) << name;
    for (int i = 0; i < service->method_count(); ++i) {
      const pb::MethodDescriptor* method = service->method(i);
      const std::string path = "/" + name + "/" + method->name();
      ++methods;
      const pb::Message* prototype =
          pb::MessageFactory::generated_factory()->GetPrototype(method->input_type());
      ASSERT_NE(prototype, nullptr) << path;
      std::vector<Path> fields;
      ScalarFields(method->input_type(), {}, 0, &fields);
      auto check = [&](const std::string& what, const std::string& payload) {
        const Answer a = Call(stub, path, payload, 20s);
        ++cases;
        ++by_code[a.status.error_code()];
        EXPECT_TRUE(clear.count(a.status.error_code()))
            << path << " " << what << ": code " << a.status.error_code() << " "
            << a.status.error_message().substr(0, 300);
        if (!a.status.ok() && a.status.error_code() != grpc::StatusCode::CANCELLED) {
          EXPECT_FALSE(a.status.error_message().empty()) << path << " " << what;
          EXPECT_LE(a.status.error_message().size(), kMaxMessage)
              << path << " " << what << ": " << a.status.error_message().substr(0, 300);
        }
      };
      // Undecodable: a length-delimited field 1 claiming more bytes than follow. (A stream of
      // requests, ToolStream's, cannot be checked so: gRPC's streaming Read reports a message
      // it cannot decode as the end of the stream, which the handler cannot tell from a client
      // that closed; it ends the stream.)
      if (!method->client_streaming()) {
        const Answer a = Call(stub, path, std::string("\x0a\xff\xff\xff\x0f", 5), 20s);
        ++cases;
        EXPECT_EQ(a.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT)
            << path << " undecodable: " << a.status.error_message();
        EXPECT_NE(a.status.error_message().find("could not be decoded as a " +
                                                method->input_type()->full_name()),
                  std::string::npos)
            << a.status.error_message();
      }
      for (const Path& field : fields) {
        const pb::FieldDescriptor* last = field.back();
        const bool text = last->cpp_type() == pb::FieldDescriptor::CPPTYPE_STRING;
        if (text) {
          std::unique_ptr<pb::Message> m(prototype->New());
          SetLast(Reach(m.get(), field), last, 0, mega);
          check(PathName(field) + " = 1 MB", m->SerializeAsString());
          continue;
        }
        if (last->cpp_type() == pb::FieldDescriptor::CPPTYPE_BOOL) continue;
        for (double v : numbers) {
          std::unique_ptr<pb::Message> m(prototype->New());
          SetLast(Reach(m.get(), field), last, v, "");
          std::ostringstream what;
          what << PathName(field) << " = " << v;
          check(what.str(), m->SerializeAsString());
        }
      }
    }
  }
  EXPECT_EQ(methods, 29);
  std::ostringstream codes;
  for (auto [code, n] : by_code) codes << " code " << code << ": " << n;
  std::printf("--device %s: %d methods, %d cases;%s\n", GetParam(), methods, cases,
              codes.str().c_str());
  // Still running, still at rate.
  std::string detail;
  const double after = LoopTickRate(d, 3s, &detail);
  // The loop keeps running near the rate it had: a handler that wedged or starved it would take
  // it far below. Not a timing target: the loop skips the ticks it is late for, and the old
  // bound (97 %) left no room for the other tests sharing CI's two cores (a sanitizer build's
  // loop runs at about 150 ticks/s, moving more).
  const double keep = kSanitizerBuild ? 0.5 : 0.75;
  EXPECT_TRUE(after >= 990.0 || after >= keep * before)
      << "before " << before << " ticks/s, after " << after << " (" << detail << ")";
  EXPECT_EQ(d.WaitForExit(0ms), -1) << "rheod exited: " << d.log();
}

}  // namespace
}  // namespace rheo::testing
