// Test fixture shared by the device-link tests: one hard-jelly tetrahedron, 4 cm, apex up, held
// at its base, without gravity or floor, so only the tool moves it.
#pragma once

#include <algorithm>
#include <memory>

#include "common/geometry.h"
#include "sim/sim.h"

namespace rheo::testing {

inline TetMesh OneTet() {
  TetMesh m;
  m.positions = {Vec3(0, 0, 0), Vec3(0.04, 0, 0), Vec3(0, 0, 0.04), Vec3(0.01, 0.04, 0.01)};
  // Positive orientation: (p1-p0) . ((p2-p0) x (p3-p0)) > 0.
  m.tets = {{0, 2, 1, 3}};
  m.surface = {{0, 1, 2}, {0, 3, 1}, {1, 3, 2}, {0, 2, 3}};
  return m;
}

struct HeldTet {
  TetMesh mesh;
  std::unique_ptr<sim::SimObject> object;
  double min_mass = 0;  // lightest node [kg]
};

/// The tetrahedron as a simulated object; an error message instead when it cannot be built.
inline Result<HeldTet> MakeHeldTet() {
  HeldTet h;
  h.mesh = OneTet();
  auto preset = sim::FindPreset("hard-jelly");
  if (!preset.ok()) return preset.error();
  sim::Parameters p = preset->params;
  p.gravity = 0.0;
  p.floor_enabled = 0.0;
  auto obj = sim::SimObject::Create(h.mesh, p, sim::Integrator::kImplicitEuler);
  if (!obj.ok()) return obj.error();
  h.object = std::move(*obj);
  for (int32_t base : {0, 1, 2}) h.object->SetFixed(base, true);
  h.min_mass = *std::min_element(h.object->model().mass.begin(), h.object->model().mass.end());
  return h;
}

}  // namespace rheo::testing
