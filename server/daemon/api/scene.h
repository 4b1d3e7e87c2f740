// The daemon's view of what is in the scene (outside the loop): which stored object each
// instance came from, its material, and the surface topology that frames refer to.
#pragma once

#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/geometry.h"
#include "daemon/loop/multirate_object.h"
#include "haptics/haptics.h"
#include "sim/cost.h"
#include "sim/multirate.h"
#include "sim/params.h"
#include "sim/sim.h"

namespace rheo::daemon {

struct SceneEntry {
  uint32_t instance_id = 0;
  std::string object_id;
  std::string preset;
  sim::Integrator integrator = sim::Integrator::kSymplecticEuler;
  sim::Parameters params;           // mirror of the loop's copy, for validation and listing
  std::vector<uint32_t> triangles;  // surface, 3 per triangle
  uint32_t vertex_count = 0;
  Vec3 position = Vec3::Zero();  // centre of the rest shape [m]
  sim::TickCost cost;            // what one awake tick of it is predicted to take
  // The loop's object, for SimObject::Prepare only (const, reads what the loop never writes).
  // Owned by the loop; valid while this entry is in the registry, and used only under the
  // registry's mutation mutex, which RemoveFromScene also holds.
  const sim::SimObject* object = nullptr;
  // Stepped multi-rate (the loop's MultiRateObject; object is its whole): same lifetime and
  // locking as `object`. `cost` is then the patch's tick; the patch built at admission stays
  // here, never stepped, for the cost of later parameter changes.
  const MultiRateObject* multirate = nullptr;
  std::shared_ptr<const sim::Patch> patch_probe;
  int32_t multirate_period = 0;  // ticks per whole step
  sim::TickCost whole_cost;      // one whole step (multi-rate only)
  // The haptic renderer built for it (with a device): its configuration and the tool position
  // it started from, for the session recording (a replay builds the renderer again from them).
  bool has_contact = false;
  haptics::RendererConfig contact_config;
  Vec3 contact_tool = Vec3::Zero();
};

/// The translation that moves `mesh`'s rest-shape bounding-box centre to `target` [m].
inline Vec3 PlacementShift(const TetMesh& mesh, const Vec3& target) {
  if (mesh.positions.empty()) return Vec3::Zero();
  Vec3 lo = mesh.positions.front(), hi = lo;
  for (const Vec3& x : mesh.positions) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  return target - 0.5 * (lo + hi);
}

/// Where AddToScene puts an object by default: centred over the origin, 2 cm above the floor.
inline Vec3 DefaultPlacement(const TetMesh& mesh, double floor_height) {
  double lo = 0.0, hi = 0.0;
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    const double y = mesh.positions[i].y();
    lo = i == 0 ? y : std::min(lo, y);
    hi = i == 0 ? y : std::max(hi, y);
  }
  return Vec3(0.0, floor_height + 0.02 + 0.5 * (hi - lo), 0.0);
}

/// Mutex-protected; never touched by the loop.
class SceneRegistry {
 public:
  std::shared_ptr<const SceneEntry> Find(uint32_t id) const {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = entries_.find(id);
    return it == entries_.end() ? nullptr : it->second;
  }
  std::vector<std::shared_ptr<const SceneEntry>> All() const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<std::shared_ptr<const SceneEntry>> out;
    for (auto& [id, e] : entries_) out.push_back(e);
    return out;
  }
  uint32_t NextId() {
    std::lock_guard<std::mutex> lock(mutex_);
    return next_id_++;
  }
  void Put(std::shared_ptr<const SceneEntry> e) {
    std::lock_guard<std::mutex> lock(mutex_);
    entries_[e->instance_id] = std::move(e);
  }
  void Erase(uint32_t id) {
    std::lock_guard<std::mutex> lock(mutex_);
    entries_.erase(id);
  }
  size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return entries_.size();
  }
  /// Predicted simulation time of one tick of every object but `except` [ns].
  double predicted_ns(uint32_t except = 0) const {
    std::lock_guard<std::mutex> lock(mutex_);
    double ns = 0.0;
    for (auto& [id, e] : entries_)
      if (id != except) ns += e->cost.ns;
    return ns;
  }
  /// Objects stepped multi-rate.
  int multirate_count() const {
    std::lock_guard<std::mutex> lock(mutex_);
    int n = 0;
    for (auto& [id, e] : entries_) n += e->multirate != nullptr;
    return n;
  }
  uint64_t total_vertices() const {
    std::lock_guard<std::mutex> lock(mutex_);
    uint64_t n = 0;
    for (auto& [id, e] : entries_) n += e->vertex_count;
    return n;
  }
  /// Serialises scene mutations (add/remove/set) so validation and submission stay consistent.
  std::mutex& mutation_mutex() { return mutation_mutex_; }

 private:
  mutable std::mutex mutex_;
  std::mutex mutation_mutex_;
  std::map<uint32_t, std::shared_ptr<const SceneEntry>> entries_;
  uint32_t next_id_ = 1;
};

}  // namespace rheo::daemon
