#include "daemon/loop/multirate_object.h"

#include <pthread.h>

#include <algorithm>
#include <chrono>

namespace rheo::daemon {

Result<std::unique_ptr<MultiRateObject>> MultiRateObject::Create(
    std::unique_ptr<sim::SimObject> whole, int32_t period, const sim::PatchOptions& options,
    const Vec3& focus) {
  if (!whole) return InvalidArgument("no object to step");
  if (whole->integrator() == sim::Integrator::kSymplecticEuler)
    return InvalidArgument(
        "multi-rate stepping needs the implicit integrator: an explicit whole step over many "
        "ticks costs as many substeps as the ticks it covers");
  auto mr = sim::MultiRate::Create(std::move(whole), period, options);
  if (!mr.ok()) return mr.error();
  std::unique_ptr<MultiRateObject> o(new MultiRateObject(std::move(*mr)));
  auto patch = o->mr_.BuildPatch(focus);
  if (!patch.ok()) return patch.error();
  o->patch_out_ = std::move(*patch);
  o->replace_out_ = true;
  o->focus_ = focus;
  o->tick_s_ = options.tick;
  o->whole_substeps_.store(o->mr_.whole_substeps());
  o->since_sync_ = period - 1;  // the first tick takes the first patch in
  o->sleeping_out_ = o->mr_.whole().sleeping();
  o->kinetic_energy_out_ = o->mr_.whole().kinetic_energy();
  o->thread_ = std::thread([p = o.get()] { p->Run(); });
  return o;
}

MultiRateObject::~MultiRateObject() {
  stop_.store(true, std::memory_order_release);
  phase_.store(kStop, std::memory_order_release);
  phase_.notify_one();
  if (thread_.joinable()) thread_.join();
  delete params_in_;
  delete params_requested_;
}

bool MultiRateObject::AddLoad(const sim::NodeLoad& load) {
  if (load_count_ >= kMaxLoads) return false;
  loads_[load_count_++] = load;
  return true;
}

sim::PreparedParameters* MultiRateObject::RequestParameters(sim::PreparedParameters* params) {
  sim::PreparedParameters* earlier = params_requested_;
  params_requested_ = params;
  return earlier;
}

sim::StepResult MultiRateObject::Tick(double dt) {
  if (++since_sync_ >= mr_.period()) {
    if (phase_.load(std::memory_order_acquire) == kDone) {
      // The whole's results: its new state (the patch follows it, or is swapped for the one
      // built around the focus; patch_out_ then holds the old patch, freed on the whole's
      // thread), what it reports.
      // A patch that waited since the last sync (untouched) takes the whole's state entire.
      mr_.Sync(patch_out_, replace_out_, /*refresh=*/!stepped_since_sync_);
      stepped_since_sync_ = false;
      if (replace_out_) {
        rebuilds_.fetch_add(1, std::memory_order_relaxed);
        const sim::Patch* p = mr_.patch();
        patch_inner_.store(p ? p->inner_nodes() : 0, std::memory_order_relaxed);
        patch_tets_.store(p ? static_cast<int32_t>(p->object().model().tets.size()) : 0,
                          std::memory_order_relaxed);
      }
      whole_sleeping_ = sleeping_out_;
      kinetic_energy_ = kinetic_energy_out_;
      // What the next step needs.
      focus_in_ = focus_;
      reset_in_ = reset_requested_;
      reset_requested_ = false;
      params_in_ = params_requested_;
      params_requested_ = nullptr;
      wants_patch_in_ = reset_in_ || params_in_ != nullptr || mr_.WantsPatch(focus_);
      since_sync_ = 0;
      boundary_held_ = false;
      syncs_.fetch_add(1, std::memory_order_relaxed);
      phase_.store(kRunning, std::memory_order_release);
      phase_.notify_one();
    } else {
      late_ticks_.fetch_add(1, std::memory_order_relaxed);
      // The whole is late. Under the hand the patch goes on, its boundary held where the whole
      // was last seen plus one period of its motion.
      if (!boundary_held_ && load_count_ > 0) {
        mr_.HoldPatchBoundary();
        boundary_held_ = true;
      }
    }
  }
  // Untouched, the patch waits: the frames show the whole, and at the next sync the patch takes
  // the whole's state. Stepped on its own, its inner nodes would fall away from a boundary that
  // moves only at syncs (a dropped 15k-tet bean's patch then needed 10 substeps and 190 CG
  // iterations a tick), and it would cost the loop a tick's work for nothing.
  if (load_count_ == 0) {
    mr_.IdleTick(dt);
    sleeping_ = whole_sleeping_;
    return sim::StepResult{};
  }
  stepped_since_sync_ = true;
  const sim::StepResult r =
      mr_.FastTick(std::span<const sim::NodeLoad>(loads_.data(), load_count_), dt);
  if (r.restored) patch_restores_.fetch_add(1, std::memory_order_relaxed);
  // Asleep when the whole was at its last step and the patch is now (or there is none).
  sleeping_ = whole_sleeping_ && (r.sleeping || mr_.patch() == nullptr);
  return r;
}

void MultiRateObject::Run() {
  // Named for top -H and perf: started from a gRPC handler, it had inherited "grpcpp_sync_ser".
  pthread_setname_np(pthread_self(), "rheo-whole");
  for (;;) {
    phase_.wait(kDone, std::memory_order_acquire);
    if (stop_.load(std::memory_order_acquire)) return;
    // What the loop gave back, freed here.
    patch_out_.reset();
    replace_out_ = false;
    sim::SimObject& whole = mr_.whole();
    const bool forced = reset_in_ || params_in_ != nullptr;
    if (params_in_) {
      // Validated by the service; an error leaves the old parameters.
      (void)mr_.SetParameters(params_in_->params);
      delete params_in_;
      params_in_ = nullptr;
    }
    if (reset_in_) whole.Reset();
    const auto t0 = std::chrono::steady_clock::now();
    // The whole steps over its period, not over the window: a window longer than the period
    // (the whole ran late) is its load's average all the same, but a step over it would be
    // longer than the substeps were chosen for (at 470 ms windows a soft bean's 4 substeps took
    // 680 ms and exploded, making the next window longer still). A whole that cannot keep up
    // runs behind real time instead, and says by how much (whole_lag_s).
    const double window = mr_.window_duration();
    const double step = window > 0.0 ? mr_.period() * tick_s_ : 0.0;
    const sim::StepResult r = mr_.StepWhole(step);
    lag_s_ += window - step;
    whole_lag_s_.store(lag_s_, std::memory_order_relaxed);
    const int64_t ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0)
            .count();
    whole_step_ns_.store(ns, std::memory_order_relaxed);
    if (ns > whole_step_max_ns_.load(std::memory_order_relaxed))
      whole_step_max_ns_.store(ns, std::memory_order_relaxed);
    whole_window_s_.store(window, std::memory_order_relaxed);
    if (r.restored) {
      // The step did not hold (a drop onto the floor, most often): finer substeps from now on,
      // down to a quarter of the tick.
      whole_restores_.fetch_add(1, std::memory_order_relaxed);
      mr_.RefineWholeSubsteps(4 * mr_.period());
    }
    whole_substeps_.store(mr_.whole_substeps(), std::memory_order_relaxed);
    if (wants_patch_in_) {
      auto p = mr_.BuildPatch(focus_in_);
      if (p.ok()) {
        patch_out_ = std::move(*p);
        replace_out_ = true;
      } else if (forced) {
        replace_out_ = true;  // no node near the tool: the stale patch goes, none replaces it
      }
    }
    sleeping_out_ = whole.sleeping();
    kinetic_energy_out_ = whole.kinetic_energy();
    uint32_t running = kRunning;
    // Not over a stop the destructor set meanwhile.
    phase_.compare_exchange_strong(running, kDone, std::memory_order_release,
                                   std::memory_order_relaxed);
  }
}

MultiRateStats MultiRateObject::stats() const {
  MultiRateStats s;
  s.syncs = syncs_.load(std::memory_order_relaxed);
  s.late_ticks = late_ticks_.load(std::memory_order_relaxed);
  s.rebuilds = rebuilds_.load(std::memory_order_relaxed);
  s.whole_restores = whole_restores_.load(std::memory_order_relaxed);
  s.patch_restores = patch_restores_.load(std::memory_order_relaxed);
  s.whole_step_ns = whole_step_ns_.load(std::memory_order_relaxed);
  s.whole_step_max_ns = whole_step_max_ns_.load(std::memory_order_relaxed);
  s.whole_window_s = whole_window_s_.load(std::memory_order_relaxed);
  s.whole_lag_s = whole_lag_s_.load(std::memory_order_relaxed);
  s.whole_substeps = whole_substeps_.load(std::memory_order_relaxed);
  s.patch_inner_nodes = patch_inner_.load(std::memory_order_relaxed);
  s.patch_tets = patch_tets_.load(std::memory_order_relaxed);
  s.period = mr_.period();
  return s;
}

}  // namespace rheo::daemon
