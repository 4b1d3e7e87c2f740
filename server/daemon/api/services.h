// gRPC service implementations. They validate, translate and queue; the work happens elsewhere.
#pragma once

#include <atomic>
#include <chrono>
#include <map>
#include <mutex>
#include <set>
#include <string>

#include "daemon/api/auth.h"
#include "daemon/api/lease.h"
#include "daemon/api/limits.h"
#include "daemon/api/object_builder.h"
#include "daemon/api/quota.h"
#include "daemon/api/scene.h"
#include "daemon/device/device_link.h"
#include "daemon/jobs/jobs.h"
#include "daemon/loop/engine.h"
#include "daemon/loop/frame_hub.h"
#include "daemon/store/store.h"
#include "rheo/v1/auth.grpc.pb.h"
#include "rheo/v1/daemon.grpc.pb.h"
#include "rheo/v1/device.grpc.pb.h"
#include "rheo/v1/frames.grpc.pb.h"
#include "rheo/v1/objects.grpc.pb.h"
#include "rheo/v1/scene.grpc.pb.h"
#include "sim/cost.h"

namespace rheo::daemon {

class Recorder;         // daemon/record/recorder.h
class RecordingPlayer;  // daemon/replay/player.h

/// One event of an object-creation job: progress, or the error that ended it.
struct JobEvent {
  static JobEvent Progress(v1::CreateObjectProgress p) { return {std::move(p), std::nullopt, {}}; }
  static JobEvent Failed(Error e) { return {{}, std::move(e), {}}; }

  v1::CreateObjectProgress progress;
  std::optional<Error> error;
  /// With the "done" event: the mesh just stored, so add_to_scene need not read it back.
  std::shared_ptr<const TetMesh> mesh;
};

/// What the services share: set once at startup, read-only afterwards.
struct DaemonContext {
  Engine* engine = nullptr;
  FrameHub* hub = nullptr;
  std::string version;
  std::string listen_address;
  std::string data_dir;
  v1::DeviceKind device = v1::DEVICE_KIND_NONE;
  DeviceLink* device_link = nullptr;  // null with --device none
  LeaseManager* leases = nullptr;
  TokenRegistry* tokens = nullptr;
  Quotas* quotas = nullptr;  // per-token limits; null: none
  std::chrono::steady_clock::time_point started;
  std::atomic<bool>* shutting_down = nullptr;
  Store* store = nullptr;
  SceneRegistry* scene = nullptr;
  JobPool<JobEvent>* jobs = nullptr;
  BuildLimits build_limits;
  std::chrono::seconds job_timeout{120};
  // Admission by cost: the tick's cost model on this machine (measured at start-up) and the
  // share of each tick the simulation of the whole scene may take [ns].
  sim::CostCoefficients tick_cost;
  double sim_budget_ns = 600'000.0;
  Recorder* recorder = nullptr;  // session recording; null: none
  // rheod --replay: the recording played back into the frame hub (the loop then simulates
  // nothing, and the scene follows the recording); null otherwise.
  RecordingPlayer* player = nullptr;
};

/// Puts `list` over `p` by name, then checks the whole set and the solver settings the 1 kHz
/// loop takes (INVALID_ARGUMENT naming the parameter).
Status ApplyParameterList(sim::Parameters& p,
                          const google::protobuf::RepeatedPtrField<v1::Parameter>& list);

/// While rheod plays back (ctx.player): one step of the paused playback; FAILED_PRECONDITION
/// while it plays.
grpc::Status StepPlayback(const DaemonContext& ctx);

/// FAILED_PRECONDITION for a request that would change the scene while rheod plays back a
/// recording (rheod --replay); OK otherwise.
grpc::Status RefuseWhilePlayingBack(const DaemonContext& ctx, const char* what);

/// What a frame carries besides the objects' states: each object's surface (topology), its
/// positions, as floats or quantized.
struct FrameContent {
  bool topology = false;
  bool positions = false;
  bool quantized = false;
};
/// The loop frame `f` as WatchFrames sends it (and /frames records it); dropped_frames is the
/// caller's.
void FillFrame(const DaemonContext& ctx, const LoopFrame& f, const FrameContent& what,
               v1::Frame* out);
/// The loop's health as GetStatus reports it.
void FillLoopStatus(const DaemonContext& ctx, v1::LoopStatus* out);

/// Counts a stream against its caller's token for as long as `slot` lives (RESOURCE_EXHAUSTED
/// past the limit); the handler touches the slot on every message it reads or writes.
grpc::Status HoldStream(const DaemonContext& ctx, grpc::ServerContext* context,
                        std::string_view method, Quotas::Stream* slot);

/// How long a service waits for the loop to apply a command it submitted [ns].
inline constexpr int64_t kApplyTimeoutNs = 2'000'000'000;
/// The loop's command queue refused a command (RESOURCE_EXHAUSTED, retry).
grpc::Status QueueFull();
/// The loop did not apply `what` within kApplyTimeoutNs (UNAVAILABLE).
grpc::Status NotApplied(const char* what);
/// Submits a command that owns no memory and waits until the loop applied it.
grpc::Status SubmitAndWait(Engine& engine, const Command& c, uint64_t* seq = nullptr);

/// Builds the simulation of a stored object and hands it to the loop (AddToScene, and
/// CreateObject with add_to_scene). `fresh` is the object's mesh when the caller has just built
/// and stored it (used as it is); null loads it from the store.
grpc::Status AddObjectToScene(const DaemonContext& ctx, const v1::AddToSceneRequest& request,
                              const TetMesh* fresh, v1::SceneObject* out);

class AuthServiceImpl final : public v1::AuthService::Service {
 public:
  explicit AuthServiceImpl(const DaemonContext& ctx) : ctx_(ctx) {}
  grpc::Status WhoAmI(grpc::ServerContext*, const v1::WhoAmIRequest*, v1::Identity*) override;
  grpc::Status CreateToken(grpc::ServerContext*, const v1::CreateTokenRequest*,
                           v1::CreateTokenResponse*) override;
  grpc::Status ListTokens(grpc::ServerContext*, const v1::ListTokensRequest*,
                          v1::ListTokensResponse*) override;
  grpc::Status RevokeToken(grpc::ServerContext*, const v1::RevokeTokenRequest*,
                           v1::RevokeTokenResponse*) override;
  grpc::Status ListAudit(grpc::ServerContext*, const v1::ListAuditRequest*,
                         v1::ListAuditResponse*) override;

 private:
  const DaemonContext& ctx_;
};

class DaemonServiceImpl final : public v1::DaemonService::Service {
 public:
  explicit DaemonServiceImpl(const DaemonContext& ctx) : ctx_(ctx) {}
  grpc::Status GetStatus(grpc::ServerContext*, const v1::GetStatusRequest*,
                         v1::DaemonStatus* out) override;

 private:
  const DaemonContext& ctx_;
};

class FrameServiceImpl final : public v1::FrameService::Service {
 public:
  explicit FrameServiceImpl(const DaemonContext& ctx) : ctx_(ctx) {}
  grpc::Status WatchFrames(grpc::ServerContext* context, const v1::WatchFramesRequest* request,
                           grpc::ServerWriter<v1::Frame>* writer) override;

 private:
  const DaemonContext& ctx_;
};

class SceneServiceImpl final : public v1::SceneService::Service {
 public:
  explicit SceneServiceImpl(const DaemonContext& ctx) : ctx_(ctx) {}
  grpc::Status GetScene(grpc::ServerContext*, const v1::GetSceneRequest*, v1::Scene*) override;
  grpc::Status AddToScene(grpc::ServerContext*, const v1::AddToSceneRequest*,
                          v1::SceneObject*) override;
  grpc::Status RemoveFromScene(grpc::ServerContext*, const v1::RemoveFromSceneRequest*,
                               v1::RemoveFromSceneResponse*) override;
  grpc::Status SetParameters(grpc::ServerContext*, const v1::SetParametersRequest*,
                             v1::SetParametersResponse*) override;
  grpc::Status ListParameters(grpc::ServerContext*, const v1::ListParametersRequest*,
                              v1::ListParametersResponse*) override;
  grpc::Status Control(grpc::ServerContext*, const v1::ControlRequest*,
                       v1::ControlResponse*) override;

 private:
  const DaemonContext& ctx_;
};

class ObjectServiceImpl final : public v1::ObjectService::Service {
 public:
  explicit ObjectServiceImpl(const DaemonContext& ctx) : ctx_(ctx) {}
  grpc::Status CreateObject(grpc::ServerContext*, const v1::CreateObjectRequest*,
                            grpc::ServerWriter<v1::CreateObjectProgress>*) override;
  grpc::Status CancelJob(grpc::ServerContext*, const v1::CancelJobRequest*,
                         v1::CancelJobResponse*) override;
  grpc::Status ExtractContour(grpc::ServerContext*, const v1::ExtractContourRequest*,
                              v1::ContourReport*) override;
  grpc::Status ListObjects(grpc::ServerContext*, const v1::ListObjectsRequest*,
                           v1::ListObjectsResponse*) override;
  grpc::Status GetObject(grpc::ServerContext*, const v1::GetObjectRequest*, v1::Object*) override;
  grpc::Status DeleteObject(grpc::ServerContext*, const v1::DeleteObjectRequest*,
                            v1::DeleteObjectResponse*) override;
  grpc::Status ExportObject(grpc::ServerContext*, const v1::ExportObjectRequest*,
                            grpc::ServerWriter<v1::ExportChunk>*) override;

 private:
  // A retry of a CreateObject whose first attempt stored its object (request_id): the answer.
  grpc::Status Replay(const StoredObject& stored, const v1::CreateObjectRequest& request,
                      grpc::ServerWriter<v1::CreateObjectProgress>* writer);

  const DaemonContext& ctx_;
  std::mutex requests_mutex_;
  std::set<std::string> requests_in_flight_;       // CreateObject request ids being built
  std::map<std::string, std::string> job_owners_;  // job id -> token name, while it runs
};

class DeviceServiceImpl final : public v1::DeviceService::Service {
 public:
  explicit DeviceServiceImpl(const DaemonContext& ctx) : ctx_(ctx) {}
  grpc::Status GetDeviceStatus(grpc::ServerContext*, const v1::GetDeviceStatusRequest*,
                               v1::DeviceStatus*) override;
  grpc::Status Calibrate(grpc::ServerContext*, const v1::CalibrateRequest*,
                         v1::CalibrateResponse*) override;
  grpc::Status AcquireLease(grpc::ServerContext*, const v1::AcquireLeaseRequest*,
                            v1::Lease*) override;
  grpc::Status RevokeLease(grpc::ServerContext*, const v1::RevokeLeaseRequest*,
                           v1::RevokeLeaseResponse*) override;
  grpc::Status RenewLease(grpc::ServerContext*, const v1::RenewLeaseRequest*, v1::Lease*) override;
  grpc::Status ReleaseLease(grpc::ServerContext*, const v1::ReleaseLeaseRequest*,
                            v1::ReleaseLeaseResponse*) override;
  grpc::Status EmergencyStop(grpc::ServerContext*, const v1::EmergencyStopRequest*,
                             v1::EmergencyStopResponse*) override;
  grpc::Status ToolStream(grpc::ServerContext*,
                          grpc::ServerReaderWriter<v1::ToolFeedback, v1::ToolInput>*) override;
  grpc::Status SimulatedHand(grpc::ServerContext*, const v1::SimulatedHandRequest*,
                             v1::SimulatedHandResponse*) override;

 private:
  const DaemonContext& ctx_;
};

}  // namespace rheo::daemon
