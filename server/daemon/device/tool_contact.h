// The tool against the scene for one tick: the haptic renderer of the first object that has
// one, the node forces it puts on that object (held until the next tick) and the proxy. The
// device link runs it with the device's pose; an offline replay runs the same code with the
// recorded pose, which is what makes the replay bit-identical.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>

#include "common/geometry.h"
#include "common/status.h"
#include "daemon/loop/engine.h"
#include "haptics/haptics.h"

namespace rheo::daemon {

/// An object's renderer, as the loop holds it (EngineSlot::contact).
class RendererContact final : public ObjectContact {
 public:
  explicit RendererContact(haptics::Renderer r) : renderer(std::move(r)) {}
  haptics::Renderer renderer;
};

/// The lightest node of `surface` [kg] (0 when none has a mass).
double MinSurfaceMass(std::span<const std::array<int32_t, 3>> surface,
                      std::span<const double> masses);

/// Builds an object's renderer (allocates; off the loop). `surface` indexes `positions` (the
/// object's nodes, placed in the scene); `tool` is where the tool is [m]. The nodes take the
/// coupling spring as an explicit force, so with `min_node_mass` > 0 (the lightest surface
/// node's mass [kg]) the coupling stiffness is also held to k h^2 / m <= 2 (half the explicit
/// stability bound of 4), h the device tick.
Result<std::unique_ptr<ObjectContact>> MakeRendererContact(
    const haptics::RendererConfig& config, std::span<const std::array<int32_t, 3>> surface,
    std::span<const Vec3> positions, const Vec3& tool, double min_node_mass);

/// What one tick of contact gives.
struct ContactTick {
  Vec3 force = Vec3::Zero();         // on the hand (the renderer's wrench) [N]
  Vec3 torque = Vec3::Zero();        // [N m]
  Vec3 proxy = Vec3::Zero();         // [m]
  Vec3 object_force = Vec3::Zero();  // sum of the node forces put on the object [N]
  bool in_contact = false;
  bool renderer_error = false;  // the renderer's update failed: no force this tick
  uint32_t instance_id = 0;     // the object rendered against (0: none)
  double stiffness = 0.0;       // its coupling stiffness [N/m] (0: no object)
};

/// Loop thread only; never allocates.
class ToolContact {
 public:
  /// One tick: the tool at `position` with `velocity` (scene frame) against `slots`. With
  /// `object_feels` the object takes the node forces (the device displays the reaction);
  /// without, it takes none.
  ContactTick Update(std::span<EngineSlot> slots, const Vec3& position, const Vec3& velocity,
                     double dt, bool object_feels);
  /// The object in `slot` is leaving the loop: forget any pointer into it.
  void Forget(const EngineSlot& slot);

 private:
  void Release();

  sim::SimObject* object_ = nullptr;      // object holding node forces from the tool
  MultiRateObject* multirate_ = nullptr;  // or the multi-rate object holding them
  std::array<int32_t, 24> forced_nodes_{};
  int forced_count_ = 0;
};

}  // namespace rheo::daemon
