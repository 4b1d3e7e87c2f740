// DaemonService: the daemon's status (loop timing, counts, capabilities).
#include <algorithm>
#include <cmath>

#include "daemon/api/convert.h"
#include "daemon/api/services.h"
#include "daemon/record/recorder.h"

namespace rheo::daemon {

void FillLoopStatus(const DaemonContext& ctx, v1::LoopStatus* l) {
  const rt::Loop& loop = ctx.engine->loop();
  const rt::LoopStats& s = loop.stats();
  l->set_rate_hz(1e9 / static_cast<double>(loop.options().period_ns));
  l->set_ticks(s.ticks.load());
  l->set_late_ticks(s.late_ticks.load());
  l->set_overruns(s.overruns.load());
  l->set_skipped_ticks(s.skipped_ticks.load());
  FillPercentiles(s.period, l->mutable_period());
  FillPercentiles(s.wake_latency, l->mutable_wake_latency());
  FillPercentiles(s.work, l->mutable_work());
  l->set_realtime_priority(loop.environment().realtime);
  l->set_memory_locked(loop.environment().memory_locked);
  l->set_notes(loop.environment().notes);
  l->set_commands_applied(ctx.engine->commands_applied());
  l->set_commands_rejected(ctx.engine->commands_rejected());
  l->set_restores(ctx.engine->restores());
  l->set_predicted_sim_us(ctx.scene->predicted_ns() * 1e-3);
  // 0: no admission by cost (--sim-budget 0).
  l->set_sim_budget_us(std::isfinite(ctx.sim_budget_ns) ? ctx.sim_budget_ns * 1e-3 : 0.0);
  l->set_unstable_objects(ctx.engine->unstable_objects());
}

grpc::Status DaemonServiceImpl::GetStatus(grpc::ServerContext*, const v1::GetStatusRequest* req,
                                          v1::DaemonStatus* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  out->set_version(ctx_.version);
  out->set_uptime_s(
      std::chrono::duration<double>(std::chrono::steady_clock::now() - ctx_.started).count());
  out->set_listen_address(ctx_.listen_address);
  out->set_data_dir(ctx_.data_dir);
  FillLoopStatus(ctx_, out->mutable_loop());
  out->set_device(ctx_.device);
  if (ctx_.device_link) {
    out->add_capabilities("device");
    const ToolTelemetry t = ctx_.engine->tool();
    out->set_device_connected(t.connected);
    FillDeviceCounters(t, out->mutable_device_counters());
  }
  out->set_frame_clients(static_cast<uint32_t>(ctx_.hub->clients()));
  out->set_scene_objects(static_cast<uint32_t>(ctx_.scene->size()));
  if (auto n = ctx_.store->Count(); n.ok()) out->set_stored_objects(static_cast<uint32_t>(*n));
  out->set_running_jobs(static_cast<uint32_t>(ctx_.jobs->in_flight()));
  if (ctx_.quotas) {
    const QuotaLimits& q = ctx_.quotas->limits();
    const QuotaStats st = ctx_.quotas->stats();
    v1::Limits* lim = out->mutable_limits();
    lim->set_calls_per_s(q.calls_per_s);
    lim->set_burst(q.burst);
    lim->set_streams(static_cast<uint32_t>(q.streams));
    lim->set_jobs(static_cast<uint32_t>(q.jobs));
    lim->set_stream_idle_s(q.stream_idle.count() * 1e-3);
    lim->set_refused_calls(st.refused_rate);
    lim->set_refused_streams(st.refused_streams);
    lim->set_refused_jobs(st.refused_jobs);
    lim->set_idle_streams_ended(st.idle_cancelled);
    lim->set_open_streams(static_cast<uint32_t>(std::max(0, st.open_streams)));
  }
  for (const char* c : {"loop", "frames", "sketch", "mesh", "store", "sim"})
    out->add_capabilities(c);
  if (ctx_.recorder) out->add_capabilities("record");
  return grpc::Status::OK;
}

}  // namespace rheo::daemon
