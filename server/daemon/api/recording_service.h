// RecordingService (session recording into MCAP files) and what the other services hand the
// recorder: scene and parameter events from their handlers, every scene and device command
// through a server interceptor.
#pragma once

#include <grpcpp/support/server_interceptor.h>

#include "daemon/api/scene.h"
#include "daemon/api/services.h"
#include "daemon/record/recorder.h"
#include "rheo/v1/recording.grpc.pb.h"

namespace rheo::daemon {

class RecordingServiceImpl final : public v1::RecordingService::Service {
 public:
  explicit RecordingServiceImpl(const DaemonContext& ctx) : ctx_(ctx) {}
  grpc::Status StartRecording(grpc::ServerContext*, const v1::StartRecordingRequest*,
                              v1::Recording*) override;
  grpc::Status StopRecording(grpc::ServerContext*, const v1::StopRecordingRequest*,
                             v1::Recording*) override;
  grpc::Status ListRecordings(grpc::ServerContext*, const v1::ListRecordingsRequest*,
                              v1::ListRecordingsResponse*) override;
  grpc::Status ExportRecording(grpc::ServerContext*, const v1::ExportRecordingRequest*,
                               grpc::ServerWriter<v1::RecordingChunk>*) override;
  grpc::Status DeleteRecording(grpc::ServerContext*, const v1::DeleteRecordingRequest*,
                               v1::DeleteRecordingResponse*) override;
  grpc::Status GetPlayback(grpc::ServerContext*, const v1::GetPlaybackRequest*,
                           v1::Playback*) override;
  grpc::Status ControlPlayback(grpc::ServerContext*, const v1::ControlPlaybackRequest*,
                               v1::Playback*) override;

 private:
  const DaemonContext& ctx_;
};

/// The registry entry a played-back object shows as (rheod --replay): its /scene event's
/// preset, integrator, parameters, position and surface.
std::shared_ptr<SceneEntry> EntryFromSceneEvent(const v1::SceneEvent& ev);

/// A /scene event for `entry`: the object as GetScene reports it and, unless kind is
/// KIND_REMOVED, `mesh` (the stored rest shape) moved to where the entry placed it. Called under
/// the scene's mutation mutex.
v1::SceneEvent MakeSceneEvent(v1::SceneEvent::Kind kind, const SceneEntry& entry,
                              const TetMesh* mesh);
/// Hands `entry`'s arrival (with its mesh), departure or parameters to the running recording;
/// nothing when none runs. Under the scene's mutation mutex, after the loop applied the change.
/// `seq`: the engine's sequence number of the command that added, removed or changed it.
void RecordSceneAdded(const DaemonContext& ctx, const SceneEntry& entry, const TetMesh& mesh,
                      uint64_t seq);
void RecordSceneRemoved(const DaemonContext& ctx, const SceneEntry& entry, uint64_t seq);
void RecordParameters(const DaemonContext& ctx, const SceneEntry& entry, uint64_t seq);

/// Records every scene and device command (AddToScene, RemoveFromScene, SetParameters, Control,
/// Calibrate, EmergencyStop, SimulatedHand and the lease calls) as received, with the status it
/// ended with, on /commands while a recording runs. ToolStream's poses are not commands: the
/// loop's /tool samples hold what they did.
class RecordingInterceptorFactory final
    : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  explicit RecordingInterceptorFactory(Recorder* recorder) : recorder_(recorder) {}
  grpc::experimental::Interceptor* CreateServerInterceptor(
      grpc::experimental::ServerRpcInfo* info) override;

 private:
  Recorder* recorder_;
};

}  // namespace rheo::daemon
