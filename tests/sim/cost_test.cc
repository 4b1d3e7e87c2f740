// The admission cost model (sim::PredictTickCost): its terms, with coefficients given here (the
// daemon measures them at start-up; tick_cost_bench compares the model with measured ticks).
#include "sim/cost.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "sim/primitives.h"
#include "sim/sim.h"

namespace rheo::sim {
namespace {

TEST(TickCost, TetrahedraInTheLinearSystemAddTheirOwnTerms) {
  auto mesh = MakeBoxTetMesh(4, 3, 3, Vec3(0.05, 0.04, 0.04));
  ASSERT_TRUE(mesh.ok());
  const Parameters soft = FindPreset("soft-jelly")->params;
  Parameters stiff = soft;
  stiff.tet_k *= 1e3;  // shape springs too stiff to stay explicit at 1 ms
  auto object = SimObject::Create(*mesh, soft, Integrator::kImplicitEuler);
  ASSERT_TRUE(object.ok());
  auto a = (*object)->Prepare(soft, Integrator::kImplicitEuler, 1e-3);
  auto b = (*object)->Prepare(stiff, Integrator::kImplicitEuler, 1e-3);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_GT(b->implicit_tets, a->implicit_tets);

  CostCoefficients c;
  c.implicit_ns = 10.0;
  c.cg_ns = 2.0;
  c.system_ns = 30.0;
  c.system_cg_ns = 3.0;
  const Model& m = (*object)->model();
  const TickCost ca = PredictTickCost(m, *a, Integrator::kImplicitEuler, 1e-3, c);
  const TickCost cb = PredictTickCost(m, *b, Integrator::kImplicitEuler, 1e-3, c);
  EXPECT_EQ(ca.system_tets, a->implicit_tets);
  EXPECT_EQ(cb.system_tets, b->implicit_tets);
  ASSERT_EQ(ca.substeps, cb.substeps);
  ASSERT_EQ(ca.cg_iterations, cb.cg_iterations);
  // Every element: implicit_ns + iterations x cg_ns; every system tet: system_ns + iterations x
  // system_cg_ns, per substep.
  const double n = static_cast<double>(ElementCount(m));
  const double it = cb.cg_iterations;
  EXPECT_DOUBLE_EQ(cb.ns, cb.substeps * (n * (10.0 + it * 2.0) +
                                         static_cast<double>(cb.system_tets) * (30.0 + it * 3.0)));
  EXPECT_DOUBLE_EQ(
      cb.ns - ca.ns,
      cb.substeps * static_cast<double>(cb.system_tets - ca.system_tets) * (30.0 + it * 3.0));
  const std::string said = DescribeTickCost(m, cb, Integrator::kImplicitEuler);
  EXPECT_NE(said.find(std::to_string(cb.system_tets) + " tetrahedra in the linear system"),
            std::string::npos)
      << said;

  // Coefficients left at zero (an older calibration) predict what the model did before.
  CostCoefficients old = c;
  old.system_ns = old.system_cg_ns = 0.0;
  EXPECT_DOUBLE_EQ(PredictTickCost(m, *b, Integrator::kImplicitEuler, 1e-3, old).ns,
                   cb.substeps * n * (10.0 + it * 2.0));
}

TEST(TickCost, FinerMeshesAreCountedOnForMoreCgIterations) {
  // The same 10 x 1 x 1 cm bar at two refinements: the finer one's cells are half as wide (its
  // mean edge is within 2 % of half: the mix of edge directions differs a little with the count).
  auto coarse = MakeBoxTetMesh(40, 4, 4, Vec3(0.1, 0.01, 0.01));
  auto fine = MakeBoxTetMesh(80, 8, 8, Vec3(0.1, 0.01, 0.01));
  auto big = MakeBoxTetMesh(4, 3, 3, Vec3(0.1, 0.08, 0.08));
  ASSERT_TRUE(coarse.ok() && fine.ok() && big.ok());
  const Parameters p = FindPreset("organ")->params;
  auto a = SimObject::Create(*coarse, p, Integrator::kImplicitEuler);
  auto b = SimObject::Create(*fine, p, Integrator::kImplicitEuler);
  auto c = SimObject::Create(*big, p, Integrator::kImplicitEuler);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  const double sa = CgRefinementScale((*a)->model());
  const double sb = CgRefinementScale((*b)->model());
  ASSERT_GT(sa, 1.0);  // more edges across than the 17.4 of the 5k bean counted on
  EXPECT_NEAR(sb / sa, std::pow(2.0, 0.75), 0.03);
  // The same bar scaled up: as many edges across, as many iterations.
  TetMesh scaled = *coarse;
  for (Vec3& x : scaled.positions) x *= 3.0;
  auto d = SimObject::Create(scaled, p, Integrator::kImplicitEuler);
  ASSERT_TRUE(d.ok());
  EXPECT_NEAR(CgRefinementScale((*d)->model()), sa, 1e-9);
  // Coarser than the reference: the default count, not fewer.
  EXPECT_EQ(CgRefinementScale((*c)->model()), 1.0);
  EXPECT_EQ(EstimatedCgIterations(p, 1.0), 8);
  EXPECT_EQ(EstimatedCgIterations(p, 0.5), 8);
  EXPECT_EQ(EstimatedCgIterations(p, 2.0), 16);
  Parameters capped = p;
  capped.cg_max_iterations = 12;
  EXPECT_EQ(EstimatedCgIterations(capped, 2.0), 12);
  // The prediction uses it.
  CostCoefficients k;
  k.implicit_ns = 10.0;
  k.cg_ns = 2.0;
  auto prepared = (*b)->Prepare(p, Integrator::kImplicitEuler, 1e-3);
  ASSERT_TRUE(prepared.ok());
  const TickCost cost =
      PredictTickCost((*b)->model(), *prepared, Integrator::kImplicitEuler, 1e-3, k);
  EXPECT_EQ(cost.cg_iterations, EstimatedCgIterations(p, sb));
  EXPECT_GT(cost.cg_iterations, 8);
}

TEST(TickCost, LongerSubstepsAreCountedOnForMoreCgIterations) {
  EXPECT_EQ(CgSubstepScale(0.5e-3), 1.0);
  EXPECT_EQ(CgSubstepScale(1e-3), 1.0);
  EXPECT_NEAR(CgSubstepScale(2e-3), std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(CgSubstepScale(4e-3), 2.0, 1e-12);
  // A 10 ms step in 1 ms substeps and in 2 ms ones (as a multi-rate whole takes them): the 2 ms
  // substeps are counted on for sqrt(2) times the iterations.
  auto mesh = MakeBoxTetMesh(4, 3, 3, Vec3(0.05, 0.04, 0.04));
  ASSERT_TRUE(mesh.ok());
  Parameters p = FindPreset("organ")->params;
  auto object = SimObject::Create(*mesh, p, Integrator::kImplicitEuler);
  ASSERT_TRUE(object.ok());
  CostCoefficients k;
  k.implicit_ns = 10.0;
  k.cg_ns = 2.0;
  TickCost at[2];
  for (int i = 0; i < 2; ++i) {
    p.implicit_substeps = i == 0 ? 10 : 5;
    auto prepared = (*object)->Prepare(p, Integrator::kImplicitEuler, 10e-3);
    ASSERT_TRUE(prepared.ok());
    at[i] = PredictTickCost((*object)->model(), *prepared, Integrator::kImplicitEuler, 10e-3, k);
  }
  ASSERT_EQ(at[0].substeps, 10);
  ASSERT_EQ(at[1].substeps, 5);
  const double refinement = CgRefinementScale((*object)->model());
  EXPECT_EQ(at[0].cg_iterations, EstimatedCgIterations(p, refinement));
  EXPECT_EQ(at[1].cg_iterations, EstimatedCgIterations(p, refinement * std::sqrt(2.0)));
  EXPECT_GT(at[1].cg_iterations, at[0].cg_iterations);
}

}  // namespace
}  // namespace rheo::sim
