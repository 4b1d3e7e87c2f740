// Commands into the loop from the services: submit, wait for the tick that applied them; the
// streams' hold on their token's quota.
#include "daemon/api/services.h"

namespace rheo::daemon {

grpc::Status HoldStream(const DaemonContext& ctx, grpc::ServerContext* context,
                        std::string_view method, Quotas::Stream* slot) {
  if (!ctx.quotas) return grpc::Status::OK;
  return ctx.quotas->OpenStream(context, CallerOf(context).token_name, method, slot);
}

grpc::Status QueueFull() {
  return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                      "the loop's command queue is full; retry shortly");
}

grpc::Status NotApplied(const char* what) {
  return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                      std::string("the loop did not take the ") + what + " within 2 s");
}

grpc::Status SubmitAndWait(Engine& engine, const Command& c, uint64_t* seq_out) {
  const uint64_t seq = engine.Submit(c);
  if (seq == 0) return QueueFull();
  if (seq_out) *seq_out = seq;
  if (!engine.WaitApplied(seq, kApplyTimeoutNs)) return NotApplied("command");
  return grpc::Status::OK;
}

}  // namespace rheo::daemon
