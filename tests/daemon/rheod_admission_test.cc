// Admission by cost: scene changes and parameter sets that would not fit the 1 ms tick are
// refused with the prediction and the budget, the loop keeps its rate meanwhile (and beside
// streams that never read), and an object that keeps needing restores is stopped and reported
// instead of restored forever.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <thread>
#include <vector>

#include "rheo/v1/daemon.grpc.pb.h"
#include "rheo/v1/frames.grpc.pb.h"
#include "rheo/v1/objects.grpc.pb.h"
#include "rheo/v1/scene.grpc.pb.h"
#include "rheod_fixture.h"

namespace rheo::testing {
namespace {

using namespace std::chrono_literals;

// The loop keeps its rate: at least 990 ticks a second, or, on a machine that itself stalls the
// process (a shared host skips a few percent of periods whatever the daemon does), at least 97 %
// of the rate measured in the same daemon just before the hostile requests. A starved loop
// (1 to 300 ticks a second before these limits) fails either way.
bool KeepsItsRate(double after, double before) {
  // A sanitizer build's loop runs far below its rate; there: still ticking near what it did.
  return after >= 990.0 || after >= (kSanitizerBuild ? 0.5 : 0.97) * before;
}

// Stores the bean sample at `resolution` [m] and returns its object id.
std::string StoreBean(RheodProcess& d, double resolution) {
  return StoreSketchFile(d, std::string(RHEO_SKETCHES) + "/bean.json", resolution);
}

grpc::Status Add(RheodProcess& d, const std::string& id, v1::Integrator integrator,
                 std::vector<std::pair<std::string, double>> overrides, v1::SceneObject* out,
                 v1::MultiRateMode multi_rate = v1::MULTI_RATE_MODE_AUTO) {
  auto scene = v1::SceneService::NewStub(d.channel());
  grpc::ClientContext ctx;
  SetDeadline(ctx, 60s);
  v1::AddToSceneRequest add;
  add.set_object_id(id);
  add.set_integrator(integrator);
  add.set_multi_rate(multi_rate);
  for (auto& [name, value] : overrides) {
    auto* o = add.add_overrides();
    o->set_name(name);
    o->set_value(value);
  }
  return scene->AddToScene(&ctx, add, out);
}

grpc::Status Set(RheodProcess& d, uint32_t instance,
                 std::vector<std::pair<std::string, double>> values) {
  auto scene = v1::SceneService::NewStub(d.channel());
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::SetParametersRequest req;
  req.set_instance_id(instance);
  for (auto& [name, value] : values) {
    auto* p = req.add_parameters();
    p->set_name(name);
    p->set_value(value);
  }
  v1::SetParametersResponse r;
  return scene->SetParameters(&ctx, req, &r);
}

v1::DaemonStatus Status(RheodProcess& d) {
  auto stub = v1::DaemonService::NewStub(d.channel());
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::DaemonStatus st;
  EXPECT_TRUE(stub->GetStatus(&ctx, {}, &st).ok());
  return st;
}

TEST(RheodAdmission, StarvingSettingsAndAnOversizedObjectAreRefusedWhileTheLoopKeepsItsRate) {
  // What fits the tick depends on how fast this build simulates: about 30 times slower under a
  // sanitizer, where the daemon measures it so and would refuse even the default bean. The
  // optimised build's stage of scripts/test runs this test.
  if (kSanitizerBuild) GTEST_SKIP() << "admission by cost is a property of the optimised build";
  // 90 % of the tick rather than the default 60 %: the cost model is measured at start-up, and on
  // a machine busy with other work it came out 40 % high (38.9 against 27.9 ns per element and
  // substep), which put the default bean (about 0.54 ms) over 0.6 ms. Everything this test
  // expects to be refused is predicted at several times the budget.
  RheodProcess d({"--sim-budget", "90"});
  ASSERT_TRUE(d.started()) << d.log();
  // The bean at the daemon's default resolution: symplectic Euler (soft jelly's own) would need
  // about 44 substeps a tick; left to the daemon, the implicit integrator is chosen.
  const std::string id = StoreBean(d, 0.0);
  ASSERT_FALSE(id.empty());
  v1::SceneObject so;
  grpc::Status s = Add(d, id, v1::INTEGRATOR_UNSPECIFIED, {}, &so, v1::MULTI_RATE_MODE_OFF);
  ASSERT_TRUE(s.ok()) << s.error_message();
  EXPECT_EQ(so.integrator(), v1::INTEGRATOR_IMPLICIT);
  EXPECT_GT(so.predicted_tick_us(), 0.0);
  EXPECT_LT(so.predicted_tick_us(), Status(d).loop().sim_budget_us());

  std::string detail;
  const double before = LoopTickRate(d, 3s, &detail);

  // Asked for explicitly, the symplectic one does not fit: refused, naming time and budget.
  v1::SceneObject refused;
  s = Add(d, id, v1::INTEGRATOR_SYMPLECTIC_EULER, {}, &refused);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_NE(s.error_message().find("ms of simulation in each 1 ms tick"), std::string::npos)
      << s.error_message();
  EXPECT_NE(s.error_message().find("--sim-budget"), std::string::npos) << s.error_message();

  // The settings that took the loop to 1 tick a second: each outside the loop's ranges.
  for (auto [name, value] : std::vector<std::pair<std::string, double>>{
           {"implicit_substeps", 1000}, {"cg_max_iterations", 10000}, {"cg_tolerance", 1e-14}}) {
    s = Set(d, so.instance_id(), {{name, value}});
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << name;
    EXPECT_NE(s.error_message().find("range the 1 kHz loop takes"), std::string::npos)
        << s.error_message();
  }
  // Inside every range, together still too much: refused by cost.
  s = Set(d, so.instance_id(),
          {{"implicit_substeps", 16}, {"cg_max_iterations", 200}, {"cg_tolerance", 1e-10}});
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_NE(s.error_message().find("16 substeps"), std::string::npos) << s.error_message();

  // A finer mesh of the same bean, multi-rate stepping declined: refused by cost, with the
  // other object counted.
  const std::string fine = StoreBean(d, 0.004);
  ASSERT_FALSE(fine.empty());
  s = Add(d, fine, v1::INTEGRATOR_IMPLICIT, {}, &refused, v1::MULTI_RATE_MODE_OFF);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_NE(s.error_message().find("the rest of the scene takes"), std::string::npos)
      << s.error_message();

  // Nothing changed: one object, at its old settings, and the loop at rate.
  auto scene = v1::SceneService::NewStub(d.channel());
  grpc::ClientContext gctx;
  SetDeadline(gctx);
  v1::Scene sc;
  ASSERT_TRUE(scene->GetScene(&gctx, {}, &sc).ok());
  ASSERT_EQ(sc.objects_size(), 1);
  for (const auto& p : sc.objects(0).parameters())
    if (p.name() == "implicit_substeps") {
      EXPECT_EQ(p.value(), 1.0);
    }
  const std::string before_detail = detail;
  const double after = LoopTickRate(d, 3s, &detail);
  EXPECT_TRUE(KeepsItsRate(after, before))
      << "before: " << before << " ticks/s (" << before_detail << "); after: " << after
      << " ticks/s (" << detail << ")";
  EXPECT_EQ(Status(d).loop().predicted_sim_us(), so.predicted_tick_us());

  // By default the fine bean is not refused: it runs multi-rate (the nodes nearest the press
  // point every tick, the whole every 10 ticks on its own thread), and the loop keeps its rate.
  v1::SceneObject mr;
  s = Add(d, fine, v1::INTEGRATOR_IMPLICIT, {}, &mr);
  ASSERT_TRUE(s.ok()) << s.error_message();
  ASSERT_TRUE(mr.has_multi_rate());
  EXPECT_EQ(mr.multi_rate().period_ticks(), 10u);
  EXPECT_GT(mr.multi_rate().patch_inner_nodes(), 0u);
  EXPECT_LE(mr.multi_rate().patch_inner_nodes(), 64u);
  EXPECT_GT(mr.multi_rate().predicted_whole_step_ms(), 0.0);
  // A whole predicted over its period at the tick's substeps takes 2 ms ones (5 a step), and
  // falls behind less. Predicted over the period even at 2 ms, it was over it at 1 ms.
  const uint32_t whole_substeps = mr.multi_rate().whole_substeps();
  if (mr.multi_rate().predicted_whole_step_ms() > 10.0)
    EXPECT_EQ(whole_substeps, 5u) << mr.multi_rate().DebugString();
  else
    EXPECT_TRUE(whole_substeps == 5u || whole_substeps == 10u) << mr.multi_rate().DebugString();
  EXPECT_LT(mr.predicted_tick_us() + so.predicted_tick_us(), Status(d).loop().sim_budget_us());
  // A second one is refused: each whole takes a core.
  v1::SceneObject second;
  s = Add(d, fine, v1::INTEGRATOR_IMPLICIT, {}, &second);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_NE(s.error_message().find("one object at a time runs multi-rate"), std::string::npos)
      << s.error_message();
  const double with_mr = LoopTickRate(d, 3s, &detail);
  EXPECT_TRUE(KeepsItsRate(with_mr, before))
      << "before: " << before << " ticks/s; with the multi-rate object: " << with_mr << " ticks/s ("
      << detail << ")";
  grpc::ClientContext g2;
  SetDeadline(g2);
  ASSERT_TRUE(scene->GetScene(&g2, {}, &sc).ok());
  ASSERT_EQ(sc.objects_size(), 2);
  for (const auto& o : sc.objects()) {
    if (o.instance_id() != mr.instance_id()) continue;
    // The whole's 10 ms steps of this 15k-tet bean take several times their period on this
    // machine (the CG needs more iterations at longer substeps), so the whole runs behind real
    // time; it still steps, and says by how much it is behind.
    const v1::MultiRate& m = o.multi_rate();
    std::printf("multi-rate bean: %s\n", m.ShortDebugString().c_str());
    EXPECT_GE(m.syncs(), 3u) << m.DebugString();
    EXPECT_GE(m.whole_substeps(), 4u);
    EXPECT_GT(m.whole_step_ms(), 0.0);
    if (m.whole_step_ms() > m.period_ticks()) {
      EXPECT_GT(m.whole_lag_ms(), 0.0) << m.DebugString();
      EXPECT_GT(m.late_ticks(), 0u) << m.DebugString();
    }
    EXPECT_FALSE(o.unstable());
  }

  // A whole that keeps up at the tick's substeps keeps them: the default bean, asked to run
  // multi-rate in place of the fine one.
  {
    grpc::ClientContext rctx;
    SetDeadline(rctx);
    v1::RemoveFromSceneRequest rm;
    rm.set_instance_id(mr.instance_id());
    v1::RemoveFromSceneResponse rr;
    ASSERT_TRUE(scene->RemoveFromScene(&rctx, rm, &rr).ok());
  }
  v1::SceneObject coarse;
  s = Add(d, id, v1::INTEGRATOR_IMPLICIT, {}, &coarse, v1::MULTI_RATE_MODE_ON);
  ASSERT_TRUE(s.ok()) << s.error_message();
  ASSERT_TRUE(coarse.has_multi_rate());
  const v1::MultiRate& cm = coarse.multi_rate();
  std::printf("multi-rate default bean: %s\n", cm.ShortDebugString().c_str());
  // Predicted at about 2.4 ms a step in this build: within its period, so it keeps the tick's.
  EXPECT_LE(cm.predicted_whole_step_ms(), 10.0) << cm.DebugString();
  EXPECT_EQ(cm.whole_substeps(), 10u) << cm.DebugString();
}

// The daemon's resident memory [kB] (VmRSS of /proc/PID/status; 0 when unreadable).
long RssKb(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::atol(line.c_str() + 6);
  return 0;
}

// Stalled clients: 16 WatchFrames streams at 250 Hz with positions that never read a frame.
// gRPC's flow control holds each at its window: the daemon's memory stays bounded (it grew by
// 131 MB before the loop locked its memory on fault only: each stream's thread stack had been
// locked whole) and the loop keeps its rate; a client reading beside them gets its frames.
TEST(RheodAdmission, StreamsThatNeverReadNeitherGrowTheDaemonNorSlowTheLoop) {
  RheodProcess d({"--http", "off", "--stream-idle", "0"});
  ASSERT_TRUE(d.started()) << d.log();
  const std::string id = StoreBean(d, 0.006);
  ASSERT_FALSE(id.empty());
  v1::SceneObject so;
  ASSERT_TRUE(Add(d, id, v1::INTEGRATOR_IMPLICIT, {}, &so).ok());
  const double before = LoopTickRate(d, 1s);
  const long rss_before = RssKb(d.pid());
  auto frames = v1::FrameService::NewStub(d.channel());
  constexpr int kStalled = 16;
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<std::unique_ptr<grpc::ClientReader<v1::Frame>>> stalled;
  v1::WatchFramesRequest w;
  w.set_rate_hz(250);
  w.set_positions(true);
  for (int i = 0; i < kStalled; ++i) {
    contexts.push_back(std::make_unique<grpc::ClientContext>());
    stalled.push_back(frames->WatchFrames(contexts.back().get(), w));  // and never Read
  }
  // A reader beside them, for 3 s at 60 Hz.
  grpc::ClientContext rctx;
  SetDeadline(rctx, 20s);
  v1::WatchFramesRequest r;
  r.set_rate_hz(60);
  r.set_positions(true);
  r.set_max_frames(180);
  auto reader = frames->WatchFrames(&rctx, r);
  int read = 0;
  v1::Frame f;
  const auto t0 = std::chrono::steady_clock::now();
  std::string detail;
  double during = 0.0;
  std::thread rate([&] { during = LoopTickRate(d, 2s, &detail); });
  while (reader->Read(&f)) ++read;
  const double read_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  rate.join();
  EXPECT_TRUE(reader->Finish().ok());
  const long rss_after = RssKb(d.pid());
  std::printf(
      "%d stalled streams: loop %.0f -> %.0f ticks/s (%s); reader %d frames in %.2f s; rheod RSS "
      "%ld -> %ld kB\n",
      kStalled, before, during, detail.c_str(), read, read_s, rss_before, rss_after);
  EXPECT_TRUE(KeepsItsRate(during, before)) << during << " against " << before;
  EXPECT_EQ(read, 180);
  EXPECT_LT(read_s, kSanitizerBuild ? 15.0 : 6.0);
  // Each stalled stream holds at most its flow-control window and the frame it is writing. (Not
  // in a sanitizer build: ASan keeps freed memory in its quarantine, up to 256 MB, so its RSS
  // grew by 100 MB with every frame's buffers.)
  if (!kSanitizerBuild) {
    EXPECT_LT(rss_after - rss_before, 16 * 1024) << "kB";
  }
  for (auto& c : contexts) c->TryCancel();
  for (auto& s : stalled) (void)s->Finish();
  EXPECT_EQ(d.Terminate(10s), 0) << d.log();
}

TEST(RheodAdmission, AnObjectThatKeepsExplodingIsStoppedAndReportedNotRestoredForever) {
  RheodProcess d;
  ASSERT_TRUE(d.started()) << d.log();
  const std::string id = StoreBean(d, 0.018);  // coarse: its sane settings fit the tick with room
  ASSERT_FALSE(id.empty());
  // Symplectic Euler held to one substep a tick, far below what the springs need: cheap, so
  // admitted, but its state blows up again and again.
  v1::SceneObject so;
  grpc::Status s =
      Add(d, id, v1::INTEGRATOR_SYMPLECTIC_EULER, {{"k_v", 1e5}, {"max_substeps", 1}}, &so);
  ASSERT_TRUE(s.ok()) << s.error_message();
  std::string before_detail;
  const double before = LoopTickRate(d, 1s, &before_detail);  // while it explodes
  auto frames = v1::FrameService::NewStub(d.channel());
  grpc::ClientContext fctx;
  SetDeadline(fctx, 20s);
  v1::WatchFramesRequest w;
  w.set_rate_hz(20);
  auto reader = frames->WatchFrames(&fctx, w);
  v1::Frame f;
  bool stopped = false;
  while (reader->Read(&f))
    if (f.objects_size() == 1 && f.objects(0).unstable()) {
      stopped = true;
      break;
    }
  ASSERT_TRUE(stopped) << "never stopped; restores " << f.objects(0).restores();
  const uint64_t restores = f.objects(0).restores();
  EXPECT_GE(restores, 5u);
  fctx.TryCancel();
  while (reader->Read(&f)) {
  }
  (void)reader->Finish();
  EXPECT_TRUE(d.WaitForLog("stopped: its state was restored 5 times", 5s)) << d.log();
  // Stopped means not stepped: no more restores, and reported in status and scene.
  std::this_thread::sleep_for(500ms);
  v1::DaemonStatus st = Status(d);
  EXPECT_EQ(st.loop().unstable_objects(), 1u);
  EXPECT_EQ(st.loop().restores(), restores);
  std::string detail;
  const double after = LoopTickRate(d, 3s, &detail);
  EXPECT_TRUE(KeepsItsRate(after, before))
      << "before: " << before << " ticks/s (" << before_detail << "); after: " << after
      << " ticks/s (" << detail << ")";
  {
    auto scene = v1::SceneService::NewStub(d.channel());
    grpc::ClientContext gctx;
    SetDeadline(gctx);
    v1::Scene sc;
    ASSERT_TRUE(scene->GetScene(&gctx, {}, &sc).ok());
    ASSERT_EQ(sc.objects_size(), 1);
    EXPECT_TRUE(sc.objects(0).unstable());
  }
  // Sane parameters give it a new chance: it runs again, without restores.
  s = Set(d, so.instance_id(), {{"k_v", 100}, {"max_substeps", 64}});
  ASSERT_TRUE(s.ok()) << s.error_message();
  std::this_thread::sleep_for(1s);
  st = Status(d);
  EXPECT_EQ(st.loop().unstable_objects(), 0u);
  EXPECT_LE(st.loop().restores(), restores + 1);
}

}  // namespace
}  // namespace rheo::testing
