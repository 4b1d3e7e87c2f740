// rheoctl: command-line client of rheod. Exit 0 on success; otherwise the gRPC status code
// (1..16) with "CODE: message" on stderr.
#include <google/protobuf/util/json_util.h>
#include <grpcpp/grpcpp.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>

#include "grpc/health/v1/health.grpc.pb.h"
#include "rheo/v1/daemon.grpc.pb.h"
#include "rheo/v1/device.grpc.pb.h"
#include "rheo/v1/frames.grpc.pb.h"
#include "rheo/v1/objects.grpc.pb.h"
#include "rheo/v1/scene.grpc.pb.h"

namespace {

struct Global {
  std::string server = "127.0.0.1:50051";
  double timeout_s = 0.0;  // 0: 5 s for quick calls, 300 s for object creation
};

const char* CodeName(grpc::StatusCode c) {
  switch (c) {
    case grpc::OK: return "OK";
    case grpc::CANCELLED: return "CANCELLED";
    case grpc::UNKNOWN: return "UNKNOWN";
    case grpc::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::NOT_FOUND: return "NOT_FOUND";
    case grpc::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::ABORTED: return "ABORTED";
    case grpc::OUT_OF_RANGE: return "OUT_OF_RANGE";
    case grpc::UNIMPLEMENTED: return "UNIMPLEMENTED";
    case grpc::INTERNAL: return "INTERNAL";
    case grpc::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::DATA_LOSS: return "DATA_LOSS";
    case grpc::UNAUTHENTICATED: return "UNAUTHENTICATED";
    default: return "UNKNOWN";
  }
}

int Fail(const grpc::Status& s) {
  std::cerr << CodeName(s.error_code()) << ": " << s.error_message() << "\n";
  return s.error_code() == grpc::OK ? 1 : static_cast<int>(s.error_code());
}

std::string ToJson(const google::protobuf::Message& m, bool pretty) {
  google::protobuf::util::JsonPrintOptions o;
  o.add_whitespace = pretty;
  o.preserve_proto_field_names = true;
  std::string out;
  (void)google::protobuf::util::MessageToJsonString(m, &out, o);
  if (!pretty) {
    while (!out.empty() && out.back() == '\n') out.pop_back();
  }
  return out;
}

std::shared_ptr<grpc::Channel> Connect(const Global& g) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(256 << 20);
  return grpc::CreateCustomChannel(g.server, grpc::InsecureChannelCredentials(), args);
}

void SetDeadline(grpc::ClientContext& ctx, const Global& g, double default_s = 5.0) {
  const double t = g.timeout_s > 0 ? g.timeout_s : default_s;
  ctx.set_deadline(std::chrono::system_clock::now() +
                   std::chrono::milliseconds(static_cast<int64_t>(t * 1000)));
}

// One unary call with the command's deadline (default_s unless --timeout is given).
template <typename Service, typename Method, typename Request, typename Response>
grpc::Status Unary(const Global& g, Method method, const Request& request, Response* response,
                   double default_s = 5.0) {
  auto stub = Service::NewStub(Connect(g));
  grpc::ClientContext ctx;
  SetDeadline(ctx, g, default_s);
  return ((*stub).*method)(&ctx, request, response);
}

void PrintPercentiles(const char* name, const rheo::v1::Percentiles& p) {
  std::printf("  %-13s p50 %8.1f us  p99 %8.1f us  p99.9 %8.1f us  max %8.1f us\n", name,
              p.p50_us(), p.p99_us(), p.p999_us(), p.max_us());
}

int ShowStatus(const Global& g, bool json) {
  rheo::v1::DaemonStatus st;
  grpc::Status s = Unary<rheo::v1::DaemonService>(g, &rheo::v1::DaemonService::Stub::GetStatus,
                                                  rheo::v1::GetStatusRequest(), &st);
  if (!s.ok()) return Fail(s);
  if (json) {
    std::cout << ToJson(st, true);
    return 0;
  }
  const auto& l = st.loop();
  std::printf("rheod %s at %s, up %.1f s, data dir %s\n", st.version().c_str(),
              st.listen_address().c_str(), st.uptime_s(), st.data_dir().c_str());
  std::printf("device: %s\n", rheo::v1::DeviceKind_Name(st.device()).c_str());
  std::printf(
      "loop: %.0f Hz, %llu ticks, %llu late, %llu overruns, %llu skipped; SCHED_FIFO %s, "
      "memory locked %s\n",
      l.rate_hz(), (unsigned long long)l.ticks(), (unsigned long long)l.late_ticks(),
      (unsigned long long)l.overruns(), (unsigned long long)l.skipped_ticks(),
      l.realtime_priority() ? "yes" : "no", l.memory_locked() ? "yes" : "no");
  PrintPercentiles("period", l.period());
  PrintPercentiles("wake latency", l.wake_latency());
  PrintPercentiles("tick work", l.work());
  if (!l.notes().empty()) std::printf("  notes: %s\n", l.notes().c_str());
  if (l.restores() > 0) {
    std::printf(
        "  restores: %llu (an object's state went non-finite or too fast and was put back to its "
        "last good state; see each object's restores in `rheoctl watch`)\n",
        (unsigned long long)l.restores());
  }
  std::printf("scene objects %u, stored objects %u, jobs %u, frame clients %u\n",
              st.scene_objects(), st.stored_objects(), st.running_jobs(), st.frame_clients());
  return 0;
}

int Watch(const Global& g, double rate, uint64_t count, bool positions) {
  auto stub = rheo::v1::FrameService::NewStub(Connect(g));
  grpc::ClientContext ctx;
  rheo::v1::WatchFramesRequest req;
  req.set_rate_hz(rate);
  req.set_max_frames(count);
  req.set_positions(positions);
  auto reader = stub->WatchFrames(&ctx, req);
  rheo::v1::Frame f;
  while (reader->Read(&f)) {
    std::cout << ToJson(f, false) << "\n";
    std::cout.flush();
  }
  grpc::Status s = reader->Finish();
  return s.ok() ? 0 : Fail(s);
}

int Health(const Global& g) {
  grpc::health::v1::HealthCheckResponse r;
  grpc::Status s = Unary<grpc::health::v1::Health>(g, &grpc::health::v1::Health::Stub::Check,
                                                   grpc::health::v1::HealthCheckRequest(), &r);
  if (!s.ok()) return Fail(s);
  std::cout << grpc::health::v1::HealthCheckResponse::ServingStatus_Name(r.status()) << "\n";
  return r.status() == grpc::health::v1::HealthCheckResponse::SERVING ? 0 : 1;
}

bool ReadFile(const std::string& path, std::string& out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::ostringstream ss;
  ss << in.rdbuf();
  out = ss.str();
  return true;
}

// A sketch file: stroke JSON, a contour JSON ({"contour": [[x, y], ...]}) or a PNG/JPEG picture.
bool LoadSketch(const std::string& path, rheo::v1::Sketch* sketch) {
  std::string data;
  if (!ReadFile(path, data)) {
    std::cerr << "INVALID_ARGUMENT: cannot read " << path << "\n";
    return false;
  }
  size_t first = data.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && data[first] == '{') {
    if (data.find("\"strokes\"") == std::string::npos &&
        data.find("\"contour\"") != std::string::npos) {
      // Contour JSON: the numbers of the "contour" array, pairwise.
      size_t start = data.find('[', data.find("\"contour\""));
      size_t depth = 0, pos = start;
      std::string nums;
      for (; pos < data.size(); ++pos) {
        char c = data[pos];
        if (c == '[') ++depth;
        if (c == ']' && --depth == 0) break;
        nums += (c == '[' || c == ']' || c == ',') ? ' ' : c;
      }
      std::istringstream in(nums);
      double x, y;
      while (in >> x >> y) {
        auto* p = sketch->mutable_contour()->add_points();
        p->set_x(x);
        p->set_y(y);
      }
    } else {
      sketch->set_strokes_json(data);
    }
  } else {
    sketch->set_image(data);
  }
  return true;
}

int ObjectCreate(const Global& g, const std::string& file, const std::string& name,
                 const rheo::v1::ContourOptions& co, const rheo::v1::MeshOptions& mo,
                 const std::string& background, bool add, bool json) {
  rheo::v1::CreateObjectRequest req;
  if (!LoadSketch(file, req.mutable_sketch())) return 3;
  if (!background.empty() &&
      !ReadFile(background, *req.mutable_sketch()->mutable_background_image())) {
    std::cerr << "INVALID_ARGUMENT: cannot read " << background << "\n";
    return 3;
  }
  req.set_name(name);
  *req.mutable_contour_options() = co;
  *req.mutable_mesh_options() = mo;
  req.set_add_to_scene(add);
  auto stub = rheo::v1::ObjectService::NewStub(Connect(g));
  grpc::ClientContext ctx;
  SetDeadline(ctx, g, 300.0);
  auto reader = stub->CreateObject(&ctx, req);
  rheo::v1::CreateObjectProgress p;
  rheo::v1::Object object;
  while (reader->Read(&p)) {
    if (p.has_object()) object = p.object();
    if (!json)
      std::fprintf(stderr, "%s %-15s %5.1f %%\n", p.job_id().c_str(), p.stage().c_str(),
                   100 * p.fraction());
  }
  grpc::Status s = reader->Finish();
  if (!s.ok()) return Fail(s);
  if (json) {
    std::cout << ToJson(object, true);
  } else {
    const auto& m = object.mesh();
    std::printf(
        "%s  %s: %u vertices, %u tetrahedra, %u surface triangles, volume %.3g m^3, "
        "min dihedral %.1f deg, watertight %s\n",
        object.id().c_str(), object.name().c_str(), m.vertex_count(), m.tetrahedron_count(),
        m.surface_triangle_count(), m.volume(), m.min_dihedral_deg(),
        m.watertight() ? "yes" : "no");
  }
  return 0;
}

int ObjectList(const Global& g, bool json) {
  auto stub = rheo::v1::ObjectService::NewStub(Connect(g));
  std::string token;
  do {
    grpc::ClientContext ctx;
    SetDeadline(ctx, g);
    rheo::v1::ListObjectsRequest req;
    req.set_page_token(token);
    rheo::v1::ListObjectsResponse resp;
    grpc::Status s = stub->ListObjects(&ctx, req, &resp);
    if (!s.ok()) return Fail(s);
    for (const auto& o : resp.objects()) {
      if (json) {
        std::cout << ToJson(o, false) << "\n";
      } else {
        std::printf("%s  %-24s %8u tets  %.3g m^3\n", o.id().c_str(), o.name().c_str(),
                    o.mesh().tetrahedron_count(), o.mesh().volume());
      }
    }
    token = resp.next_page_token();
  } while (!token.empty());
  return 0;
}

int ObjectGet(const Global& g, const std::string& id) {
  rheo::v1::GetObjectRequest req;
  req.set_id(id);
  rheo::v1::Object o;
  grpc::Status s =
      Unary<rheo::v1::ObjectService>(g, &rheo::v1::ObjectService::Stub::GetObject, req, &o);
  if (!s.ok()) return Fail(s);
  std::cout << ToJson(o, true);
  return 0;
}

int ObjectDelete(const Global& g, const std::string& id) {
  rheo::v1::DeleteObjectRequest req;
  req.set_id(id);
  rheo::v1::DeleteObjectResponse r;
  grpc::Status s =
      Unary<rheo::v1::ObjectService>(g, &rheo::v1::ObjectService::Stub::DeleteObject, req, &r);
  return s.ok() ? 0 : Fail(s);
}

int ObjectExport(const Global& g, const std::string& id, const std::string& format,
                 const std::string& out_path) {
  rheo::v1::ExportFormat f;
  std::string upper = "EXPORT_FORMAT_";
  for (char c : format) upper += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (!rheo::v1::ExportFormat_Parse(upper, &f)) {
    std::cerr
        << "INVALID_ARGUMENT: --format must be vtu, obj, ply, stl, svg, sketch or background\n";
    return 3;
  }
  auto stub = rheo::v1::ObjectService::NewStub(Connect(g));
  grpc::ClientContext ctx;
  SetDeadline(ctx, g);
  rheo::v1::ExportObjectRequest req;
  req.set_id(id);
  req.set_format(f);
  auto reader = stub->ExportObject(&ctx, req);
  std::string data;
  rheo::v1::ExportChunk c;
  while (reader->Read(&c)) data += c.data();
  grpc::Status s = reader->Finish();
  if (!s.ok()) return Fail(s);
  if (out_path.empty() || out_path == "-") {
    std::cout << data;
  } else {
    std::ofstream out(out_path, std::ios::binary);
    out << data;
    if (!out) {
      std::cerr << "cannot write " << out_path << "\n";
      return 1;
    }
  }
  return 0;
}

int Contour(const Global& g, const std::string& file, const rheo::v1::ContourOptions& co) {
  rheo::v1::ExtractContourRequest req;
  if (!LoadSketch(file, req.mutable_sketch())) return 3;
  *req.mutable_options() = co;
  rheo::v1::ContourReport r;
  grpc::Status s =
      Unary<rheo::v1::ObjectService>(g, &rheo::v1::ObjectService::Stub::ExtractContour, req, &r);
  if (!s.ok()) return Fail(s);
  std::cout << ToJson(r, true);
  return 0;
}

// "name=value" pairs into Parameter messages; false (with a message) on a malformed pair.
bool ParseAssignments(const std::vector<std::string>& items,
                      google::protobuf::RepeatedPtrField<rheo::v1::Parameter>* out) {
  for (const std::string& item : items) {
    size_t eq = item.find('=');
    char* end = nullptr;
    double v = eq == std::string::npos ? 0 : std::strtod(item.c_str() + eq + 1, &end);
    if (eq == std::string::npos || eq == 0 || end == item.c_str() + eq + 1 || *end != '\0') {
      std::cerr << "INVALID_ARGUMENT: '" << item << "' is not name=value (e.g. k_v=200)\n";
      return false;
    }
    auto* p = out->Add();
    p->set_name(item.substr(0, eq));
    p->set_value(v);
  }
  return true;
}

int SceneShow(const Global& g) {
  rheo::v1::Scene scene;
  grpc::Status s = Unary<rheo::v1::SceneService>(g, &rheo::v1::SceneService::Stub::GetScene,
                                                 rheo::v1::GetSceneRequest(), &scene);
  if (!s.ok()) return Fail(s);
  std::cout << ToJson(scene, true);
  return 0;
}

int SceneAdd(const Global& g, const std::string& id, const std::string& preset,
             const std::string& integrator, const std::vector<double>& at,
             const std::vector<std::string>& sets) {
  rheo::v1::AddToSceneRequest req;
  req.set_object_id(id);
  req.set_preset(preset);
  if (integrator == "explicit") req.set_integrator(rheo::v1::INTEGRATOR_SYMPLECTIC_EULER);
  if (integrator == "implicit") req.set_integrator(rheo::v1::INTEGRATOR_IMPLICIT);
  if (at.size() == 3) {
    req.mutable_position()->set_x(at[0]);
    req.mutable_position()->set_y(at[1]);
    req.mutable_position()->set_z(at[2]);
  }
  if (!ParseAssignments(sets, req.mutable_overrides())) return 3;
  rheo::v1::SceneObject o;
  grpc::Status s =
      Unary<rheo::v1::SceneService>(g, &rheo::v1::SceneService::Stub::AddToScene, req, &o, 30.0);
  if (!s.ok()) return Fail(s);
  std::printf("instance %u: %s as %s\n", o.instance_id(), o.object_id().c_str(),
              o.preset().c_str());
  return 0;
}

int SceneRemove(const Global& g, uint32_t instance) {
  rheo::v1::RemoveFromSceneRequest req;
  req.set_instance_id(instance);
  rheo::v1::RemoveFromSceneResponse r;
  grpc::Status s =
      Unary<rheo::v1::SceneService>(g, &rheo::v1::SceneService::Stub::RemoveFromScene, req, &r);
  return s.ok() ? 0 : Fail(s);
}

int SceneControl(const Global& g, rheo::v1::RunCommand cmd) {
  rheo::v1::ControlRequest req;
  req.set_command(cmd);
  rheo::v1::ControlResponse r;
  grpc::Status s =
      Unary<rheo::v1::SceneService>(g, &rheo::v1::SceneService::Stub::Control, req, &r);
  if (!s.ok()) return Fail(s);
  std::printf("%s at t = %.3f s\n", r.paused() ? "paused" : "running", r.sim_time());
  return 0;
}

int ParamList(const Global& g, uint32_t instance) {
  rheo::v1::ListParametersRequest req;
  req.set_instance_id(instance);
  rheo::v1::ListParametersResponse r;
  grpc::Status s =
      Unary<rheo::v1::SceneService>(g, &rheo::v1::SceneService::Stub::ListParameters, req, &r);
  if (!s.ok()) return Fail(s);
  for (const auto& p : r.parameters())
    std::printf("%-18s %12.6g %-10s [%g, %g]  %s\n", p.name().c_str(), p.value(), p.unit().c_str(),
                p.min(), p.max(), p.description().c_str());
  std::printf("presets:");
  for (const auto& p : r.presets()) std::printf(" %s", p.c_str());
  std::printf("\n");
  return 0;
}

int ParamSet(const Global& g, uint32_t instance, const std::string& preset,
             const std::vector<std::string>& sets) {
  rheo::v1::SetParametersRequest req;
  req.set_instance_id(instance);
  req.set_preset(preset);
  if (!ParseAssignments(sets, req.mutable_parameters())) return 3;
  rheo::v1::SetParametersResponse r;
  grpc::Status s =
      Unary<rheo::v1::SceneService>(g, &rheo::v1::SceneService::Stub::SetParameters, req, &r);
  return s.ok() ? 0 : Fail(s);
}

// ---- device ----

using DevStub = rheo::v1::DeviceService::Stub;

void PrintDeviceStatus(const rheo::v1::DeviceStatus& st) {
  auto v = [](const rheo::v1::Vec3& a) {
    char b[96];
    std::snprintf(b, sizeof b, "(%.4f, %.4f, %.4f)", a.x(), a.y(), a.z());
    return std::string(b);
  };
  std::printf("device %s: %s\n", rheo::v1::DeviceKind_Name(st.kind()).c_str(), st.model().c_str());
  std::printf("  connected %s, calibrated %s, emergency stop %s\n", st.connected() ? "yes" : "no",
              st.calibrated() ? "yes" : "no", st.emergency_stopped() ? "ENGAGED" : "off");
  std::string faults;
  for (const auto& f : st.faults()) faults += (faults.empty() ? "" : ", ") + f;
  std::printf("  faults: %s\n", faults.empty() ? "none" : faults.c_str());
  if (st.kind() == rheo::v1::DEVICE_KIND_NONE) return;
  std::printf("  grip %s m (device frame); proxy %s m; in contact %s (instance %u)\n",
              v(st.pose().position()).c_str(), v(st.proxy_position()).c_str(),
              st.in_contact() ? "yes" : "no", st.contact_instance_id());
  std::printf("  hand force %s N (requested %s N), object force %s N\n",
              v(st.wrench().force()).c_str(), v(st.requested_wrench().force()).c_str(),
              v(st.object_force()).c_str());
  if (st.string_tensions_size() > 0) {
    std::printf("  tensions [N]:");
    for (double t : st.string_tensions()) std::printf(" %.3f", t);
    std::printf("  (minimum %.3f)\n", st.min_tension());
  }
  std::printf(
      "  max force %.1f N, coupling stiffness %.0f N/m, tip radius %.1f mm, watchdog %.1f ms\n",
      st.max_force(), st.max_stiffness(), st.tip_radius() * 1e3, st.watchdog_timeout_ms());
  const auto& c = st.counters();
  std::printf(
      "  exchanges %llu, device errors %llu, protocol errors %llu, deadline misses %llu, watchdog "
      "trips %llu, recoveries %llu, renderer errors %llu\n",
      (unsigned long long)c.exchanges(), (unsigned long long)c.device_errors(),
      (unsigned long long)c.protocol_errors(), (unsigned long long)c.deadline_misses(),
      (unsigned long long)c.watchdog_trips(), (unsigned long long)c.recoveries(),
      (unsigned long long)c.renderer_errors());
  std::printf("  loop period p50 %.1f us, p99 %.1f us, max %.1f us; %llu late ticks\n",
              st.loop_period().p50_us(), st.loop_period().p99_us(), st.loop_period().max_us(),
              (unsigned long long)st.loop_late_ticks());
  std::printf("  lease: %s\n", st.lease_holder().empty()
                                   ? "free"
                                   : (st.lease_holder() + " (" +
                                      std::to_string(st.lease_expires_in_s()) + " s left)")
                                         .c_str());
}

int DeviceStatus(const Global& g, bool json) {
  rheo::v1::DeviceStatus st;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::GetDeviceStatus,
                                                  rheo::v1::GetDeviceStatusRequest(), &st);
  if (!s.ok()) return Fail(s);
  if (json) {
    std::cout << ToJson(st, true);
  } else {
    PrintDeviceStatus(st);
  }
  return 0;
}

int DeviceCalibrate(const Global& g, const std::string& lease) {
  rheo::v1::CalibrateRequest req;
  req.set_lease_id(lease);
  rheo::v1::CalibrateResponse r;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::Calibrate, req, &r);
  if (!s.ok()) return Fail(s);
  PrintDeviceStatus(r.status());
  return 0;
}

int DeviceEstop(const Global& g, bool clear, const std::string& lease) {
  rheo::v1::EmergencyStopRequest req;
  req.set_engage(!clear);
  req.set_lease_id(lease);
  rheo::v1::EmergencyStopResponse r;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::EmergencyStop, req, &r);
  if (!s.ok()) return Fail(s);
  PrintDeviceStatus(r.status());
  return 0;
}

int LeaseAcquire(const Global& g, const std::string& name, double duration) {
  rheo::v1::AcquireLeaseRequest req;
  req.set_client_name(name);
  req.set_duration_s(duration);
  rheo::v1::Lease l;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::AcquireLease, req, &l);
  if (!s.ok()) return Fail(s);
  std::printf("%s\n", l.lease_id().c_str());
  std::fprintf(stderr, "lease for %s, %.1f s; renew with: rheoctl device lease renew %s\n",
               l.holder().c_str(), l.expires_in_s(), l.lease_id().c_str());
  return 0;
}

int LeaseRenew(const Global& g, const std::string& id, double duration) {
  rheo::v1::RenewLeaseRequest req;
  req.set_lease_id(id);
  req.set_duration_s(duration);
  rheo::v1::Lease l;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::RenewLease, req, &l);
  if (!s.ok()) return Fail(s);
  std::printf("%s %.1f s\n", l.lease_id().c_str(), l.expires_in_s());
  return 0;
}

int LeaseRelease(const Global& g, const std::string& id) {
  rheo::v1::ReleaseLeaseRequest req;
  req.set_lease_id(id);
  rheo::v1::ReleaseLeaseResponse r;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::ReleaseLease, req, &r);
  return s.ok() ? 0 : Fail(s);
}

int DeviceHand(const Global& g, const rheo::v1::SimulatedHandRequest& req, double report_s) {
  rheo::v1::SimulatedHandResponse r;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::SimulatedHand, req, &r);
  if (!s.ok()) return Fail(s);
  if (req.has_press())
    std::printf("surface under the tool at y = %.4f m; hand target y = %.4f m (device frame)\n",
                r.surface_y(), r.target().position().y());
  if (report_s <= 0) return 0;
  // Report the contact as the hand moves: one line every 100 ms.
  const auto end = std::chrono::steady_clock::now() +
                   std::chrono::milliseconds(static_cast<int64_t>(report_s * 1000));
  while (std::chrono::steady_clock::now() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    rheo::v1::DeviceStatus st;
    s = Unary<rheo::v1::DeviceService>(g, &DevStub::GetDeviceStatus,
                                       rheo::v1::GetDeviceStatusRequest(), &st);
    if (!s.ok()) return Fail(s);
    std::printf("grip y %+.4f m  contact %-3s  hand force y %+7.3f N  object force y %+7.3f N\n",
                st.pose().position().y(), st.in_contact() ? "yes" : "no", st.wrench().force().y(),
                st.object_force().y());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Global g;
  CLI::App app{"rheoctl: talk to a running rheod"};
  app.add_option("--server", g.server, "rheod address host:port")->capture_default_str();
  app.add_option("--timeout", g.timeout_s,
                 "deadline of each call [s] (default 5, object create 300)");
  app.require_subcommand(1);

  bool json = false;
  auto* status = app.add_subcommand("status", "daemon version, loop timing, device, counts");
  status->add_flag("--json", json, "print the DaemonStatus message as JSON");

  double rate = 10;
  uint64_t count = 0;
  bool positions = false;
  auto* watch = app.add_subcommand("watch", "stream frames as JSON lines (Ctrl-C to stop)");
  watch->add_option("--rate", rate, "frames per second, 1..1000")->capture_default_str();
  watch->add_option("--count", count, "stop after this many frames (0 = never)")
      ->capture_default_str();
  watch->add_flag("--positions", positions, "include per-vertex positions");

  auto* health = app.add_subcommand("health", "standard gRPC health check");

  std::string file, name, id, format = "vtu", out_path, background;
  bool add = false;
  rheo::v1::ContourOptions co;
  rheo::v1::MeshOptions mo;
  double epsilon = 0, thickness = 0, resolution = 0, pixel_size = 0;
  auto* object = app.add_subcommand("object", "stored objects made from sketches");
  object->require_subcommand(1);
  auto* create = object->add_subcommand(
      "create", "sketch (JSON strokes, contour JSON, PNG, JPEG) -> stored solid");
  create->add_option("FILE", file, "sketch file")->required()->check(CLI::ExistingFile);
  create->add_option("--name", name, "label");
  create->add_option("--epsilon", epsilon, "vectorization tolerance [px]");
  create->add_option("--thickness", thickness, "elevation scale (default 1)");
  create->add_option("--resolution", resolution, "target edge length [m]");
  create->add_option("--pixel-size", pixel_size, "size of a sketch pixel [m/px]");
  create->add_option("--background", background, "background photo to store with the object")
      ->check(CLI::ExistingFile);
  create->add_flag("--add", add, "add the object to the scene when stored");
  create->add_flag("--json", json, "print the Object as JSON");
  auto* list = object->add_subcommand("list", "stored objects, newest first");
  list->add_flag("--json", json, "one JSON line per object");
  auto* get = object->add_subcommand("get", "one object as JSON");
  get->add_option("ID", id)->required();
  auto* del = object->add_subcommand("delete", "delete a stored object");
  del->add_option("ID", id)->required();
  auto* exp = object->add_subcommand("export", "write an object's mesh, sketch or picture");
  exp->add_option("ID", id)->required();
  exp->add_option("--format", format, "vtu, obj, ply, stl, svg, sketch, background")
      ->capture_default_str();
  exp->add_option("--out", out_path, "output file (default stdout)");
  std::string preset, integrator;
  std::vector<double> at;
  std::vector<std::string> sets;
  uint32_t instance = 0;
  auto* scene = app.add_subcommand("scene", "what is simulated, and run control");
  scene->require_subcommand(1);
  auto* scene_show = scene->add_subcommand("show", "objects in the scene with their parameters");
  auto* scene_add = scene->add_subcommand("add", "add a stored object to the scene");
  scene_add->add_option("ID", id, "stored object id")->required();
  scene_add->add_option("--preset", preset, "soft-jelly, hard-jelly, clay, organ");
  scene_add->add_option("--integrator", integrator, "explicit or implicit (default: the preset's)")
      ->check(CLI::IsMember({"explicit", "implicit"}));
  scene_add->add_option("--at", at, "centre of the rest shape: x y z [m]")->expected(3);
  scene_add->add_option("--set", sets, "parameter overrides name=value");
  auto* scene_remove = scene->add_subcommand("remove", "remove an instance from the scene");
  scene_remove->add_option("INSTANCE", instance)->required();
  auto* pause = scene->add_subcommand("pause", "stop simulated time (the loop keeps ticking)");
  auto* resume = scene->add_subcommand("resume", "restart simulated time");
  auto* reset = scene->add_subcommand("reset", "every object back to its rest shape, time 0");
  auto* step = scene->add_subcommand("step", "advance a paused scene by one tick");
  auto* param = app.add_subcommand("param", "material parameters (take effect on the next tick)");
  param->require_subcommand(1);
  auto* param_list = param->add_subcommand("list", "parameters with units and ranges, presets");
  param_list->add_option("INSTANCE", instance, "scene instance (0: the default preset)");
  auto* param_set = param->add_subcommand("set", "set parameters of one instance (0: all)");
  param_set->add_option("INSTANCE", instance)->required();
  param_set->add_option("ASSIGNMENTS", sets, "name=value ...");
  param_set->add_option("--preset", preset, "apply a preset first");

  auto* device = app.add_subcommand("device", "the haptic device: status, lease, stop, hand");
  device->require_subcommand(1);
  std::string lease_id, lease_name;
  double duration = 0, depth = 0.005, seconds = 1.0, report = -1;
  bool clear = false, release_hand = false;
  std::vector<double> hold;
  auto* dev_status = device->add_subcommand("status", "pose, forces, tensions, faults, counters");
  dev_status->add_flag("--json", json, "print the DeviceStatus message as JSON");
  auto* dev_cal = device->add_subcommand(
      "calibrate", "hold the grip at the frame centre; clears faults and the emergency stop");
  dev_cal->add_option("--lease", lease_id, "lease id (needed while someone holds the lease)");
  auto* dev_estop = device->add_subcommand(
      "estop", "emergency stop: every motor to minimum tension until the lease holder clears it");
  dev_estop->add_flag("--clear", clear, "clear the emergency stop (needs --lease)");
  dev_estop->add_option("--lease", lease_id, "lease id");
  auto* dev_lease = device->add_subcommand("lease", "the control lease (one holder at a time)");
  dev_lease->require_subcommand(1);
  auto* lease_acq = dev_lease->add_subcommand("acquire", "prints the lease id on stdout");
  lease_acq->add_option("--name", lease_name, "shown to others as the holder");
  lease_acq->add_option("--duration", duration, "lease length [s] (0: 10)");
  auto* lease_renew = dev_lease->add_subcommand("renew", "extend a lease");
  lease_renew->add_option("LEASE", lease_id)->required();
  lease_renew->add_option("--duration", duration, "new length from now [s] (0: 10)");
  auto* lease_rel = dev_lease->add_subcommand("release", "give the lease back");
  lease_rel->add_option("LEASE", lease_id)->required();
  auto* dev_push = device->add_subcommand(
      "push", "sim-spidar-g: the emulated hand presses the tool into the object below it");
  dev_push->add_option("--depth", depth, "how far below the surface the hand aims [m]")
      ->capture_default_str();
  dev_push->add_option("--seconds", seconds, "ramp time [s]")->capture_default_str();
  dev_push->add_option("--lease", lease_id, "lease id (needed while someone holds the lease)");
  dev_push->add_option("--report", report,
                       "print the contact every 100 ms for this long [s] (default: ramp + 1 s)");
  auto* dev_hand = device->add_subcommand("hand", "sim-spidar-g: hold the grip or let it go");
  dev_hand->add_option("--hold", hold, "hold at x y z, device frame [m]")->expected(3);
  dev_hand->add_flag("--release", release_hand, "let go of the grip");
  dev_hand->add_option("--lease", lease_id, "lease id");

  auto* contour = app.add_subcommand("contour", "extract the contour of a sketch (nothing stored)");
  contour->add_option("FILE", file, "sketch file")->required()->check(CLI::ExistingFile);
  contour->add_option("--epsilon", epsilon, "vectorization tolerance [px]");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (*status) return ShowStatus(g, json);
  if (*watch) return Watch(g, rate, count, positions);
  if (*health) return Health(g);
  co.set_epsilon_px(epsilon);
  mo.set_thickness(thickness);
  mo.set_resolution(resolution);
  mo.set_pixel_size(pixel_size);
  if (*create) return ObjectCreate(g, file, name, co, mo, background, add, json);
  if (*list) return ObjectList(g, json);
  if (*get) return ObjectGet(g, id);
  if (*del) return ObjectDelete(g, id);
  if (*exp) return ObjectExport(g, id, format, out_path);
  if (*contour) return Contour(g, file, co);
  if (*scene_show) return SceneShow(g);
  if (*scene_add) return SceneAdd(g, id, preset, integrator, at, sets);
  if (*scene_remove) return SceneRemove(g, instance);
  if (*pause) return SceneControl(g, rheo::v1::RUN_COMMAND_PAUSE);
  if (*resume) return SceneControl(g, rheo::v1::RUN_COMMAND_RESUME);
  if (*reset) return SceneControl(g, rheo::v1::RUN_COMMAND_RESET);
  if (*step) return SceneControl(g, rheo::v1::RUN_COMMAND_STEP);
  if (*param_list) return ParamList(g, instance);
  if (*param_set) return ParamSet(g, instance, preset, sets);
  if (*dev_status) return DeviceStatus(g, json);
  if (*dev_cal) return DeviceCalibrate(g, lease_id);
  if (*dev_estop) return DeviceEstop(g, clear, lease_id);
  if (*lease_acq) return LeaseAcquire(g, lease_name, duration);
  if (*lease_renew) return LeaseRenew(g, lease_id, duration);
  if (*lease_rel) return LeaseRelease(g, lease_id);
  if (*dev_push) {
    rheo::v1::SimulatedHandRequest req;
    req.set_lease_id(lease_id);
    req.mutable_press()->set_depth_m(depth);
    req.mutable_press()->set_seconds(seconds);
    return DeviceHand(g, req, report < 0 ? seconds + 1.0 : report);
  }
  if (*dev_hand) {
    rheo::v1::SimulatedHandRequest req;
    req.set_lease_id(lease_id);
    if (release_hand) {
      req.set_release(true);
    } else if (hold.size() == 3) {
      req.mutable_hold()->mutable_position()->set_x(hold[0]);
      req.mutable_hold()->mutable_position()->set_y(hold[1]);
      req.mutable_hold()->mutable_position()->set_z(hold[2]);
      req.mutable_hold()->mutable_orientation()->set_w(1.0);
    } else {
      std::cerr << "INVALID_ARGUMENT: give --hold x y z or --release\n";
      return 3;
    }
    return DeviceHand(g, req, 0);
  }
  return 1;
}
