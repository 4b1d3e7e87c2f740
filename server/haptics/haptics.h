// Haptic rendering of a spherical tool tip against a deforming closed triangle surface:
// a proxy (god-object) that never enters the surface, a virtual coupling between the device and
// the proxy, and the reaction on the object's contact nodes. Pure: no threads, I/O or globals.
//
// Stability condition (documented here, enforced by Renderer):
//   A sampled virtual spring K with virtual damper B, displayed through a device whose mechanism
//   has physical viscous damping b and is updated every T seconds with zero-order hold, is passive
//   (Colgate & Schenkel 1997) when
//       b > K T / 2 + |B|      i.e.     K < K_stable = 2 (b - |B|) / T.
//   Passivity of the device side makes the loop stable with any passive hand. The coupling
//   stiffness actually used is
//       k = min(requested coupling_stiffness, DeviceLimits::max_stiffness,
//               stability_margin * 2 (damping - coupling_damping) / tick)
//   and the coupling force is clamped to max_force [N] and slewed by at most max_force_rate [N/s].
//   The coupling damper B acts on the proxy-device relative velocity and is what damps the
//   object side: with B = 0 at the bound, a lightly damped object keeps a limit cycle (measured in
//   tests/haptics/closed_loop_test.cc); B of about 0.2 b removes it. The object side sees the same
//   spring: a simulation integrating explicitly with step h and node mass m needs k h^2 / m < 4
//   (see Renderer::effective_stiffness()).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "common/geometry.h"
#include "common/status.h"
#include "haptics/projection.h"
#include "haptics/surface_grid.h"

namespace rheo::haptics {

/// Limits of the haptic device, from the device's configuration.
struct DeviceLimits {
  double max_force = 10.0;         ///< largest force magnitude sent to the device [N], (0, 1000]
  double max_stiffness = 5000.0;   ///< largest coupling stiffness the device may display [N/m],
                                   ///< (0, 1e6]
  double max_force_rate = 2000.0;  ///< largest change of force per second [N/s], (0, 1e7]
  double damping = 2.0;  ///< physical viscous damping of the mechanism (b above) [N s/m], (0, 1e3]
  double tick = 1e-3;    ///< nominal control period T [s], [1e-5, 0.1]
};

/// Rendering parameters. Every field has a validated range; see Validate().
struct RendererConfig {
  DeviceLimits device;
  double tool_radius = 3e-3;        ///< radius of the spherical tool tip [m], (0, 0.1]
  double coupling_stiffness = 1e6;  ///< requested coupling spring [N/m], (0, 1e7]; clamped to
                                    ///< the device and stability limits
  double coupling_damping = 0.4;    ///< coupling damper B [N s/m], [0, device.damping);
                                    ///< about 0.2 device.damping
  double stability_margin = 1.0;    ///< fraction of K_stable allowed, (0, 1]
  double static_friction = 0.0;     ///< static friction coefficient, [0, 2]
  double dynamic_friction = 0.0;    ///< dynamic friction coefficient, [0, static_friction]
  double max_step = 2e-3;           ///< largest proxy displacement per tick [m], (0, 0.1]
  double max_surface_speed = 0.5;   ///< bound on surface vertex speed, used to size the search
                                    ///< margin of the incrementally re-binned grid [m/s], [0, 100]
  /// Faces re-binned per tick, round robin, [1, 1e8]. The search margin is max_surface_speed x
  /// (faces / rebin_faces_per_tick) ticks: raise this for large, fast-moving surfaces.
  int32_t rebin_faces_per_tick = 1024;
  double cell_size = 0.0;  ///< grid cell edge [m]; 0 picks one from the surface, else (0, 1]

  /// Checks every field; the error names the field, its value and its range.
  Status Validate() const;
};

/// Device tool state in the world frame of the surface.
struct DeviceState {
  Vec3 position = Vec3::Zero();  ///< tool tip centre [m]
  Vec3 velocity = Vec3::Zero();  ///< tool tip velocity [m/s]
};

/// A force applied to one node of the simulated object.
struct NodeForce {
  int32_t node = 0;           ///< index into the positions passed to Update
  Vec3 force = Vec3::Zero();  ///< [N]
};

/// Force and torque for the device, at the tool tip centre.
struct Wrench {
  Vec3 force = Vec3::Zero();   ///< [N]
  Vec3 torque = Vec3::Zero();  ///< [N m]; zero for a sphere tip, whose contact force passes through
                               ///< its centre
};

/// What one tick produces. node_forces points into the Renderer and stays valid until the next
/// Update; the sum of node_forces equals -wrench.force (equal and opposite).
struct ContactOutput {
  Wrench wrench;                           ///< to send to the device
  std::span<const NodeForce> node_forces;  ///< reaction on the object (at most 3 x 8 entries)
  Vec3 proxy = Vec3::Zero();               ///< proxy (god-object) centre [m]
  Vec3 contact_normal = Vec3::Zero();      ///< unit outward normal at the contact, zero if none
  bool in_contact = false;                 ///< the surface holds the proxy off the device (the
                                           ///< proxy touches it, or ran out of max_step sliding)
  bool sliding = false;                    ///< the proxy slid along the surface this tick
  int32_t contact_faces = 0;               ///< faces touching the proxy
  int32_t candidate_faces = 0;             ///< faces examined by the local search this tick
};

/// Renders one tool against one closed surface. Create() allocates everything; Update() does not
/// allocate, and touches only the faces near the tool plus a fixed budget of faces re-binned.
class Renderer {
 public:
  /// Builds the renderer for `triangles` (indices into the node positions, outward by the
  /// right-hand rule, forming a closed 2-manifold) at the node positions `positions` (the whole
  /// node array of the simulated object; nodes not on the surface are ignored).
  /// The proxy starts at `tool`; a tool inside the surface puts it on the nearest surface point.
  static Result<Renderer> Create(const RendererConfig& config,
                                 std::span<const std::array<int32_t, 3>> triangles,
                                 std::span<const Vec3> positions, const Vec3& tool);

  /// One tick: the device state, the current node positions (same size as at Create) and the
  /// elapsed time since the previous tick [s], (0, 0.1]. Only the error path allocates (its
  /// message). @pre surface vertices move slower than config().max_surface_speed.
  Result<ContactOutput> Update(const DeviceState& device, std::span<const Vec3> positions,
                               double dt);

  /// Coupling stiffness in use after the device and stability limits [N/m].
  double effective_stiffness() const { return k_; }
  /// The passivity bound 2 (b - |B|) / T for this configuration [N/m].
  double stability_bound() const { return k_stable_; }
  const RendererConfig& config() const { return config_; }
  int32_t face_count() const { return static_cast<int32_t>(tris_.size()); }

 private:
  Renderer() = default;

  RendererConfig config_;
  double k_ = 0.0;                            // effective coupling stiffness [N/m]
  double k_stable_ = 0.0;                     // passivity bound [N/m]
  std::vector<std::array<int32_t, 3>> tris_;  // faces (m)
  int32_t node_count_ = 0;                    // size of the positions span

  // Topology (built once).
  std::vector<std::array<int32_t, 3>> adj_;  // face across edge (v_i, v_i+1) of each face (m)
  std::vector<int32_t> vf_offset_;           // vertex -> faces CSR offsets (node_count + 1)
  std::vector<int32_t> vf_faces_;            // vertex -> faces CSR entries (3 m)

  internal::SurfaceGrid grid_;  // local search structure, re-binned round robin
  double time_ = 0.0;           // accumulated time [s]

  static constexpr int kMaxContactFaces = 8;
  // Linearised non-penetration constraint of one face at the proxy: n . y >= c keeps y at least
  // tool_radius away from the face (a supporting plane of face + ball).
  struct Plane {
    Vec3 n = Vec3::Zero();      // unit normal, from the closest point towards the proxy
    double c = 0.0;             // offset [m]
    double gap = 0.0;           // distance - tool_radius at the linearisation point [m]
    Vec3 point = Vec3::Zero();  // closest point on the face [m]
    Vec3 bary = Vec3::Zero();   // its barycentric coordinates
    int32_t face = -1;
    uint8_t feature = 0;  // internal::Feature
  };
  struct Anchor {
    int32_t face = -1;
    Vec3 bary = Vec3::Zero();  // barycentric coordinates of the contact point
  };

  // Internal steps of Update (renderer.cc).
  // Linearises the candidates at p, dropping for the rest of the tick those with a larger gap.
  int32_t Evaluate(std::span<const Vec3> x, const Vec3& p, double prune_gap);
  bool Inside(std::span<const Vec3> x, const Vec3& p, int32_t closest) const;
  Vec3 FaceNormal(std::span<const Vec3> x, int32_t f) const;
  Vec3 PseudoNormal(std::span<const Vec3> x, const Plane& pl) const;
  bool Depenetrate(std::span<const Vec3> x, Vec3& p, double keep);
  int32_t Touching(std::array<internal::HalfSpace, kMaxContactFaces>& h, double gap_limit,
                   std::array<int32_t, kMaxContactFaces>* which, int32_t* nwhich) const;
  Vec3 MoveProxy(std::span<const Vec3> x, const Vec3& from, const Vec3& target, const Vec3& device,
                 bool* touched);
  void DistributeReaction(std::span<const Vec3> x, const Vec3& object_force);

  // Per-tick scratch, sized at Create.
  std::vector<int32_t> candidates_;     // faces near the tool (capacity m)
  std::vector<Plane> planes_;           // constraint of each near face (capacity m)
  std::vector<NodeForce> node_forces_;  // output (capacity 3 kMaxContactFaces)

  // Proxy state.
  Vec3 proxy_ = Vec3::Zero();                     // [m]
  Vec3 force_ = Vec3::Zero();                     // last force sent to the device [N]
  bool stuck_ = true;                             // static-friction state
  std::array<Anchor, kMaxContactFaces> anchors_;  // contact points of the last contact tick
  int32_t anchor_count_ = 0;
  bool anchored_ = false;              // in contact last tick: carry the proxy with the surface
  Vec3 anchor_offset_ = Vec3::Zero();  // proxy minus the first anchor's point [m]
};

}  // namespace rheo::haptics
