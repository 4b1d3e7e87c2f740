// sim_bench bullet: btSoftBody on the same tets and dt, vs the same reference (and bullet-check).
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "bench.h"

#ifdef RHEO_HAVE_BULLET
#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>

namespace sim_bench {

// btSoftBody from the same tetrahedra (TetGen text, as Bullet reads it), same dt, same floor.
BulletRun RunBullet(const Scene& sc, double dt, double t_end, double stiffness, int bending) {
  std::ostringstream node, ele;
  node << sc.mesh.positions.size() << " 3 0 0\n";
  for (size_t i = 0; i < sc.mesh.positions.size(); ++i) {
    const Vec3& p = sc.mesh.positions[i];
    node << i << " " << p.x() << " " << p.y() + sc.drop << " " << p.z() << "\n";
  }
  ele << sc.mesh.tets.size() << " 4 0\n";
  for (size_t i = 0; i < sc.mesh.tets.size(); ++i) {
    const auto& t = sc.mesh.tets[i];
    ele << i << " " << t[0] << " " << t[1] << " " << t[2] << " " << t[3] << "\n";
  }
  btSoftBodyRigidBodyCollisionConfiguration config;
  btCollisionDispatcher dispatcher(&config);
  btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btSoftRigidDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
  world.setGravity(btVector3(0, -sc.params.gravity, 0));
  btSoftBodyWorldInfo& info = world.getWorldInfo();
  info.m_gravity = btVector3(0, -sc.params.gravity, 0);
  info.m_broadphase = &broadphase;
  info.m_dispatcher = &dispatcher;
  info.air_density = 0;
  info.water_density = 0;
  info.m_sparsesdf.Initialize();
  // A thick box rather than btStaticPlaneShape: soft-rigid SDF contact needs a convex shape.
  btBoxShape plane(btVector3(2.0, 0.5, 2.0));
  plane.setMargin(0.001);
  btTransform ground_pose;
  ground_pose.setIdentity();
  ground_pose.setOrigin(btVector3(0, -0.5, 0));
  btDefaultMotionState ms(ground_pose);
  btRigidBody ground(btRigidBody::btRigidBodyConstructionInfo(0, &ms, &plane));
  ground.setFriction(sc.params.friction);
  world.addRigidBody(&ground);
  const std::string ele_s = ele.str(), node_s = node.str();
  // CreateFromTetGenData prints its counts on stdout; the tables go there, so it is muted.
  std::fflush(stdout);
  const int saved_stdout = ::dup(1);
  const int null_fd = ::open("/dev/null", O_WRONLY);
  if (null_fd >= 0) ::dup2(null_fd, 1);
  btSoftBody* sb = btSoftBodyHelpers::CreateFromTetGenData(info, ele_s.c_str(), nullptr,
                                                           node_s.c_str(), false, true, true);
  std::fflush(stdout);
  if (saved_stdout >= 0) ::dup2(saved_stdout, 1);
  if (null_fd >= 0) ::close(null_fd);
  if (saved_stdout >= 0) ::close(saved_stdout);
  double mass = 0.0;
  for (const auto& t : sc.mesh.tets) {
    const Vec3& p0 = sc.mesh.positions[t[0]];
    mass += std::abs((sc.mesh.positions[t[1]] - p0)
                         .dot((sc.mesh.positions[t[2]] - p0).cross(sc.mesh.positions[t[3]] - p0))) /
            6.0 * sc.params.density;
  }
  sb->m_materials[0]->m_kLST = stiffness;
  sb->m_cfg.piterations = 4;
  sb->m_cfg.kDF = sc.params.friction;
  sb->m_cfg.kDP = 0.01;
  sb->m_cfg.collisions = btSoftBody::fCollision::SDF_RS;
  sb->getCollisionShape()->setMargin(0.002);  // default 0.25 m is larger than the object
  sb->setTotalMass(mass, false);              // no faces: by node, not by area
  if (bending > 0) sb->generateBendingConstraints(bending, sb->m_materials[0]);
  world.addSoftBody(sb);
  std::vector<int> top;
  double y_max = -1e30;
  for (int i = 0; i < sb->m_nodes.size(); ++i)
    y_max = std::max<double>(y_max, sb->m_nodes[i].m_x.y());
  for (int i = 0; i < sb->m_nodes.size(); ++i) {
    if (sb->m_nodes[i].m_x.y() > y_max - 0.01) top.push_back(i);
  }
  BulletRun r;
  const int64_t ticks = std::llround(t_end / dt);
  const double c0 = CpuSeconds();
  for (int64_t k = 0; k < ticks; ++k) {
    if (sc.press_force > 0) {
      const double ramp = std::min(1.0, (k * dt) / 0.1);
      for (int i : top) sb->addForce(btVector3(0, -ramp * sc.press_force / top.size(), 0), i);
    }
    const auto t0 = std::chrono::steady_clock::now();
    world.stepSimulation(dt, 0);
    r.tick_us.push_back(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  r.cpu = CpuSeconds() - c0;
  for (int i = 0; i < sb->m_nodes.size(); ++i) {
    const btVector3& p = sb->m_nodes[i].m_x;
    r.x.emplace_back(p.x(), p.y(), p.z());
  }
  world.removeSoftBody(sb);
  world.removeRigidBody(&ground);
  delete sb;
  return r;
}

int Bullet() {
  const double t_end = 0.5, dt = 1e-3;
  std::printf(
      "# Bullet btSoftBody (tetra links, same tets, same dt 1 ms, same floor) vs rheo_sim;"
      " error vs the rheo_sim reference (tick 1e-5 s) at 0.5 s / size.\n"
      "# Bullet's error includes the difference of material models, not only "
      "integration error.\n");
  std::printf("%-6s %6s %-26s %10s %12s %10s\n", "scene", "tets", "engine", "median_us", "error",
              "ratio");
  for (const Scene& sc : Scenes()) {
    const RunResult ref = RunScene(sc, kMethods[0], 1e-5, t_end);
    const double size =
        (**SimObject::Create(sc.mesh, sc.params, Integrator::kSymplecticEuler)).model().size;
    double rheo_med = 0.0;
    for (const Method& method : kMethods) {
      // Median tick time measured separately from the error run.
      Parameters p = sc.params;
      method.Apply(p);
      auto obj = SimObject::Create(sc.mesh, p, method.integrator);
      SimObject& s = **obj;
      s.Translate(Vec3(0, sc.drop, 0));
      std::vector<double> us;
      for (int k = 0; k < 500; ++k) {
        const auto t0 = std::chrono::steady_clock::now();
        s.Step(dt);
        us.push_back(
            std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0)
                .count());
      }
      const RunResult r = RunScene(sc, method, dt, t_end);
      const double med = Median(us);
      if (&method == &kMethods[0]) rheo_med = med;
      std::printf("%-6s %6zu %-26s %10.1f %12.3e %10.2f\n", sc.name, sc.mesh.tets.size(),
                  method.name, med, RmsError(r.x, ref.x, size), med / rheo_med);
    }
    for (double kl : {0.1, 0.5, 1.0}) {
      const BulletRun b = RunBullet(sc, dt, t_end, kl);
      char name[64];
      std::snprintf(name, sizeof name, "bullet kLST=%.1f", kl);
      std::printf("%-6s %6zu %-26s %10.1f %12.3e %10.2f\n", sc.name, sc.mesh.tets.size(), name,
                  Median(b.tick_us), RmsError(b.x, ref.x, size), Median(b.tick_us) / rheo_med);
    }
  }
  std::printf("# ratio = median tick time / rheo_sim symplectic-euler median tick time\n");
  return 0;
}

// Where Bullet's object ends up after a short drop (floor contact sanity check).
int BulletCheck() {
  const Scene sc = Scenes()[0];
  for (double t : {0.05, 0.1, 0.3}) {
    const BulletRun b = RunBullet(sc, 1e-3, t, 0.5);
    double lo = 1e30, hi = -1e30;
    for (const Vec3& x : b.x) {
      lo = std::min(lo, x.y());
      hi = std::max(hi, x.y());
    }
    std::printf("t=%.2f lowest %.4f highest %.4f\n", t, lo, hi);
  }
  return 0;
}

}  // namespace sim_bench
#endif
