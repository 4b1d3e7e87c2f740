// Closed-form checks of one three-element model (eq. 2) with the nonlinear damper (eq. 3).
#include "sim/element.h"

#include <gtest/gtest.h>

#include <cmath>
#include <unsupported/Eigen/MatrixFunctions>

#include "sim/sim.h"

namespace rheo::sim {
namespace {

constexpr double kL0 = 0.1;  // rest length of the element [m]

// Two nodes on the x axis, node 0 fixed; no gravity, floor or shape terms.
Parameters ElementParams(double k_v, double c_v, double c_d) {
  Parameters p;
  p.k_v = k_v;
  p.c_v = c_v;
  p.damper_a = c_d;
  p.damper_b = 0.0;  // constant c_d = A
  p.f_min = 0.0;
  p.f_max = 1e6;
  p.volume_k = p.volume_c = p.area_k = p.tet_k = 0.0;
  p.gravity = 0.0;
  p.floor_enabled = 0.0;
  p.sleep_time = 0.0;
  p.max_substeps = 10000;
  return p;
}

std::unique_ptr<SimObject> MakeElement(const Parameters& p, double mass, Integrator integrator) {
  const Vec3 pos[2] = {Vec3(0, 0, 0), Vec3(kL0, 0, 0)};
  const double masses[2] = {mass, mass};
  const std::array<int32_t, 2> edges[1] = {{0, 1}};
  Result<Model> model = BuildModelFromParts(pos, masses, edges, {}, {});
  EXPECT_TRUE(model.ok());
  auto obj = SimObject::Create(std::move(*model), p, integrator);
  EXPECT_TRUE(obj.ok()) << (obj.ok() ? "" : obj.error().message);
  std::unique_ptr<SimObject> o = std::move(*obj);
  o->SetFixed(0, true);
  return o;
}

// Exact solution of the linear element ODE with a point mass at the free end under force F:
// state (l, v, y = a l, 1); y' = (c_d v - k_v (y - L)) / (c_v + c_d); m v' = F - T.
double CreepExact(double k_v, double c_v, double c_d, double m, double force, double t) {
  const double L = 0.5 * kL0;
  const double s = c_d / (c_v + c_d);
  Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
  a(0, 1) = 1.0;
  a(1, 1) = -s * c_v / m;
  a(1, 2) = -s * k_v / m;
  a(1, 3) = (force + s * k_v * L) / m;
  a(2, 1) = c_d / (c_v + c_d);
  a(2, 2) = -k_v / (c_v + c_d);
  a(2, 3) = k_v * L / (c_v + c_d);
  const Eigen::Vector4d s0(kL0, 0.0, L, 1.0);
  const Eigen::Matrix4d e = (a * t).exp();
  return (e * s0)(0);
}

TEST(ThreeElement, TensionMatchesEquation2Definition) {
  // f = c_d ((1 - a) dl - da l), with da from eq. 2, equals the substituted form used in code.
  const double k_v = 30, c_v = 0.7, c_d = 4.0, a = 0.43, l = 0.12, L = 0.05, dl = -0.3;
  const double da = VoigtRatioRate(k_v, c_v, c_d, a, l, L, dl);
  const double f_eq2 = c_d * ((1 - a) * dl - da * l);
  EXPECT_NEAR(ThreeElementTension(k_v, c_v, c_d, a, l, L, dl), f_eq2, 1e-12 * std::abs(f_eq2));
  // The Voigt branch carries the same force: k_v (a l - L) + c_v d(a l)/dt.
  const double f_voigt = k_v * (a * l - L) + c_v * (da * l + a * dl);
  EXPECT_NEAR(f_voigt, f_eq2, 1e-12 * std::abs(f_eq2));
}

TEST(ThreeElement, CreepUnderConstantForceMatchesClosedForm) {
  const double k_v = 20.0, c_v = 0.5, c_d = 4.0, m = 0.01, force = 0.3;
  // Plain symplectic Euler and the variant with the damper diagonal implicit.
  for (double implicit_damping : {0.0, 1.0}) {
    Parameters p = ElementParams(k_v, c_v, c_d);
    p.implicit_damping = implicit_damping;
    auto obj = MakeElement(p, m, Integrator::kSymplecticEuler);
    obj->SetExternalForce(1, Vec3(force, 0, 0));
    const double h = 2e-7;
    double t = 0.0;
    for (double check : {0.05, 0.2, 0.5, 1.0}) {
      while (t < check - 0.5 * h) {
        obj->Step(h);
        t += h;
      }
      const double got = obj->positions()[1].x() - kL0;
      const double want = CreepExact(k_v, c_v, c_d, m, force, t) - kL0;
      EXPECT_NEAR(got, want, 1e-4 * std::abs(want))
          << "t = " << t << " implicit_damping " << implicit_damping;
    }
  }
  // The closed form tends to the classical creep law of the massless element,
  // F/k_v (1 - exp(-k_v t/c_v)) + F t/c_d, as the end mass vanishes.
  for (double t_c : {0.05, 0.5}) {
    const double massless = CreepExact(k_v, c_v, c_d, 1e-7, force, t_c) - kL0;
    const double classical = force / k_v * (1 - std::exp(-k_v * t_c / c_v)) + force * t_c / c_d;
    EXPECT_NEAR(massless, classical, 1e-4 * classical);
  }
}

TEST(ThreeElement, CreepWithImplicitIntegratorMatchesClosedForm) {
  const double k_v = 20.0, c_v = 0.5, c_d = 4.0, m = 0.01, force = 0.3;
  Parameters p = ElementParams(k_v, c_v, c_d);
  p.cg_tolerance = 1e-12;
  auto obj = MakeElement(p, m, Integrator::kImplicitEuler);
  obj->SetExternalForce(1, Vec3(force, 0, 0));
  const double h = 2e-7;
  const int steps = static_cast<int>(std::lround(0.5 / h));
  for (int k = 0; k < steps; ++k) obj->Step(h);
  const double got = obj->positions()[1].x() - kL0;
  const double want = CreepExact(k_v, c_v, c_d, m, force, steps * h) - kL0;
  EXPECT_NEAR(got, want, 1e-4 * std::abs(want));
}

TEST(ThreeElement, RelaxationUnderHeldExtensionMatchesClosedForm) {
  const double k_v = 50.0, c_v = 0.2, c_d = 1.3, eps = 0.1;
  const Parameters p = ElementParams(k_v, c_v, c_d);
  for (Integrator integrator : {Integrator::kSymplecticEuler, Integrator::kImplicitEuler}) {
    auto obj = MakeElement(p, 0.01, integrator);
    obj->SetFixed(1, true);
    obj->SetNodeState(1, Vec3(kL0 * (1 + eps), 0, 0), Vec3::Zero());
    const double l = kL0 * (1 + eps), L = 0.5 * kL0;
    const double f0 = c_d / (c_v + c_d) * k_v * (0.5 * l - L);
    const double rate = k_v / (c_v + c_d);
    const double dt = 1e-3;
    for (int k = 1; k <= 100; ++k) {
      obj->Step(dt);
      const double t = k * dt;
      const double a = obj->voigt_ratios()[0];
      const double got = ThreeElementTension(k_v, c_v, c_d, a, l, L, 0.0);
      const double want = f0 * std::exp(-rate * t);
      ASSERT_NEAR(got, want, 1e-4 * std::abs(want)) << IntegratorName(integrator) << " t=" << t;
    }
  }
}

TEST(NonlinearDamper, ViscositySwitchesAtFminAndFmax) {
  Parameters p;
  p.damper_a = 40.0;
  p.damper_b = 0.8;
  p.f_min = 0.5;
  p.f_max = 2.5;
  const double c_max = 40.0 * std::exp(-0.8 * 0.5);
  const double c_min = 40.0 * std::exp(-0.8 * 2.5);
  EXPECT_DOUBLE_EQ(DamperViscosity(p, 0.0), c_max);
  EXPECT_DOUBLE_EQ(DamperViscosity(p, 0.49), c_max);
  EXPECT_DOUBLE_EQ(DamperViscosity(p, -0.3), c_max);  // compression: force magnitude
  EXPECT_NEAR(DamperViscosity(p, 0.5), c_max, 1e-12);
  EXPECT_NEAR(DamperViscosity(p, 1.7), 40.0 * std::exp(-0.8 * 1.7), 1e-12);
  EXPECT_NEAR(DamperViscosity(p, 2.5), c_min, 1e-12);
  EXPECT_DOUBLE_EQ(DamperViscosity(p, 2.51), c_min);
  EXPECT_DOUBLE_EQ(DamperViscosity(p, 100.0), c_min);
  // Monotone non-increasing in |f|.
  double prev = DamperViscosity(p, 0.0);
  for (double f = 0.0; f < 4.0; f += 0.01) {
    const double c = DamperViscosity(p, f);
    EXPECT_LE(c, prev + 1e-15);
    prev = c;
  }
}

TEST(NonlinearDamper, SteadyCreepRateFollowsEquation3InSimulation) {
  // Under a held force F the element creeps at dl/dt = F / c_d(F) once the Voigt part settles.
  Parameters p = ElementParams(40.0, 0.2, 1.0);
  p.damper_a = 3.0;
  p.damper_b = 1.5;
  p.f_min = 0.2;
  p.f_max = 0.8;
  for (double force : {0.1, 0.5, 1.5}) {
    auto obj = MakeElement(p, 1e-3, Integrator::kSymplecticEuler);
    obj->SetExternalForce(1, Vec3(force, 0, 0));
    for (int k = 0; k < 3000; ++k) obj->Step(1e-4);
    const double x0 = obj->positions()[1].x();
    for (int k = 0; k < 1000; ++k) obj->Step(1e-4);
    const double rate = (obj->positions()[1].x() - x0) / 0.1;
    const double want = force / DamperViscosity(p, force);
    EXPECT_NEAR(rate, want, 2e-3 * want) << "F = " << force;
  }
}

}  // namespace
}  // namespace rheo::sim
