// Objects and scene through a real rheod: sketch upload, progress, storage across restarts,
// export, errors, and a simulated object streaming frames.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <atomic>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>
#include <vector>

#include "common/tet_mesh_io.h"
#include "rheo/v1/frames.grpc.pb.h"
#include "rheo/v1/objects.grpc.pb.h"
#include "rheo/v1/scene.grpc.pb.h"
#include "rheod_fixture.h"

namespace rheo::testing {
namespace {

using namespace std::chrono_literals;

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string SketchPath(const std::string& name) {
  return std::string(RHEO_SKETCHES) + "/" + name;
}

struct Created {
  grpc::Status status;
  std::vector<v1::CreateObjectProgress> progress;
  v1::Object object;
};

Created Create(v1::ObjectService::Stub& stub, const v1::CreateObjectRequest& req,
               std::chrono::milliseconds deadline = 120s) {
  Created c;
  grpc::ClientContext ctx;
  SetDeadline(ctx, deadline);
  auto reader = stub.CreateObject(&ctx, req);
  v1::CreateObjectProgress p;
  while (reader->Read(&p)) {
    c.progress.push_back(p);
    if (p.has_object()) c.object = p.object();
  }
  c.status = reader->Finish();
  return c;
}

// The stored objects' ids, newest first.
std::vector<std::string> ListIds(v1::ObjectService::Stub& stub) {
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::ListObjectsResponse list;
  grpc::Status s = stub.ListObjects(&ctx, {}, &list);
  EXPECT_TRUE(s.ok()) << s.error_message();
  std::vector<std::string> ids;
  for (const auto& o : list.objects()) ids.push_back(o.id());
  return ids;
}

// An object's mesh as VTU ("" after a failed expectation).
std::string ExportVtu(v1::ObjectService::Stub& stub, const std::string& id) {
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::ExportObjectRequest req;
  req.set_id(id);
  req.set_format(v1::EXPORT_FORMAT_VTU);
  auto reader = stub.ExportObject(&ctx, req);
  std::string vtu;
  v1::ExportChunk chunk;
  while (reader->Read(&chunk)) vtu += chunk.data();
  grpc::Status s = reader->Finish();
  EXPECT_TRUE(s.ok()) << s.error_message();
  return s.ok() ? vtu : std::string();
}

v1::CreateObjectRequest BeanRequest() {
  v1::CreateObjectRequest req;
  req.set_name("bean");
  req.mutable_sketch()->set_strokes_json(ReadText(SketchPath("bean.json")));
  return req;
}

TEST(RheodObjects, SketchBecomesAStoredSolidThatSurvivesARestart) {
  std::string data_dir, id;
  auto keep = std::filesystem::temp_directory_path() / "rheod-keep-XXXXXX";
  std::string keep_dir = keep.string();
  ASSERT_NE(mkdtemp(keep_dir.data()), nullptr);
  {
    RheodProcess d({"--data-dir", keep_dir});
    ASSERT_TRUE(d.started()) << d.log();
    auto stub = v1::ObjectService::NewStub(d.channel());
    Created c = Create(*stub, BeanRequest());
    ASSERT_TRUE(c.status.ok()) << c.status.error_message();
    ASSERT_GE(c.progress.size(), 3u);
    EXPECT_EQ(c.progress.front().stage(), "queued");
    EXPECT_FALSE(c.progress.front().job_id().empty());
    double last = -1;
    for (const auto& p : c.progress) {
      EXPECT_GE(p.fraction(), last) << p.stage();
      last = p.fraction();
    }
    EXPECT_EQ(c.progress.back().fraction(), 1.0);
    id = c.object.id();
    EXPECT_EQ(c.object.name(), "bean");
    EXPECT_GT(c.object.contour().contour().points_size(), 10);
    EXPECT_GT(c.object.mesh().tetrahedron_count(), 100u);
    EXPECT_TRUE(c.object.mesh().watertight());
    EXPECT_GE(c.object.mesh().min_dihedral_deg(), 5.0);
    EXPECT_NEAR(c.object.mesh().volume(), c.object.mesh().surface_volume(),
                1e-9 * c.object.mesh().volume());
    EXPECT_EQ(d.Terminate(5s), 0);
  }
  RheodProcess d({"--data-dir", keep_dir});
  ASSERT_TRUE(d.started()) << d.log();
  auto stub = v1::ObjectService::NewStub(d.channel());
  EXPECT_EQ(ListIds(*stub), std::vector<std::string>{id});
  {
    auto mesh = ReadVtu(ExportVtu(*stub, id));
    ASSERT_TRUE(mesh.ok()) << mesh.error().message;
    v1::Object o;
    grpc::ClientContext gctx;
    SetDeadline(gctx);
    v1::GetObjectRequest g;
    g.set_id(id);
    ASSERT_TRUE(stub->GetObject(&gctx, g, &o).ok());
    EXPECT_EQ(mesh->tets.size(), o.mesh().tetrahedron_count());
  }
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    v1::DeleteObjectRequest del;
    del.set_id(id);
    v1::DeleteObjectResponse r;
    ASSERT_TRUE(stub->DeleteObject(&ctx, del, &r).ok());
    grpc::ClientContext ctx2;
    SetDeadline(ctx2);
    v1::GetObjectRequest g;
    g.set_id(id);
    v1::Object o;
    EXPECT_EQ(stub->GetObject(&ctx2, g, &o).error_code(), grpc::StatusCode::NOT_FOUND);
  }
  std::filesystem::remove_all(keep_dir);
}

// SIGKILL in the middle of a mesh job: after the restart the store passes SQLite's integrity
// check, the design stored before is there and exports, and the killed job left nothing
// half-written (bench/reliability/kill9.sh does this 20 times in each of three situations).
TEST(RheodObjects, ASigkillDuringAMeshJobLosesNothingStored) {
  auto keep = std::filesystem::temp_directory_path() / "rheod-kill-XXXXXX";
  std::string keep_dir = keep.string();
  ASSERT_NE(mkdtemp(keep_dir.data()), nullptr);
  std::string id;
  {
    RheodProcess d({"--data-dir", keep_dir});
    ASSERT_TRUE(d.started()) << d.log();
    auto stub = v1::ObjectService::NewStub(d.channel());
    Created c = Create(*stub, BeanRequest());
    ASSERT_TRUE(c.status.ok()) << c.status.error_message();
    id = c.object.id();
    // A fine bean (seconds of meshing), killed as soon as the job reports a stage past the queue.
    v1::CreateObjectRequest fine = BeanRequest();
    fine.set_name("fine bean");
    fine.mutable_mesh_options()->set_resolution(0.004);
    std::atomic<bool> working{false};
    Created killed;
    std::thread job([&] {
      grpc::ClientContext ctx;
      SetDeadline(ctx, 60s);
      auto reader = stub->CreateObject(&ctx, fine);
      v1::CreateObjectProgress p;
      while (reader->Read(&p)) {
        killed.progress.push_back(p);
        if (p.stage() != "queued") working = true;
      }
      killed.status = reader->Finish();
      working = true;
    });
    for (int i = 0; i < 2000 && !working; ++i) std::this_thread::sleep_for(5ms);
    d.Signal(SIGKILL);
    job.join();
    ASSERT_FALSE(killed.progress.empty());
    std::printf("killed at stage '%s' (%.0f %%)\n", killed.progress.back().stage().c_str(),
                100.0 * killed.progress.back().fraction());
    EXPECT_FALSE(killed.status.ok()) << "the job finished before the kill";
  }
  RheodProcess d({"--data-dir", keep_dir});
  ASSERT_TRUE(d.started()) << d.log();
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open_v2((keep_dir + "/objects.db").c_str(), &db, SQLITE_OPEN_READONLY, nullptr),
            SQLITE_OK);
  std::string integrity;
  sqlite3_exec(
      db, "PRAGMA integrity_check;",
      [](void* out, int, char** values, char**) {
        *static_cast<std::string*>(out) += values[0] ? values[0] : "";
        return 0;
      },
      &integrity, nullptr);
  sqlite3_close(db);
  EXPECT_EQ(integrity, "ok");
  auto stub = v1::ObjectService::NewStub(d.channel());
  EXPECT_EQ(ListIds(*stub), std::vector<std::string>{id});
  EXPECT_TRUE(ReadVtu(ExportVtu(*stub, id)).ok());
  EXPECT_EQ(d.Terminate(5s), 0);
  std::filesystem::remove_all(keep_dir);
}

TEST(RheodObjects, BadSketchesGetTheRightCodeAndNothingStoredIsLost) {
  RheodProcess d;
  ASSERT_TRUE(d.started()) << d.log();
  auto stub = v1::ObjectService::NewStub(d.channel());
  Created good = Create(*stub, BeanRequest());
  ASSERT_TRUE(good.status.ok()) << good.status.error_message();

  v1::CreateObjectRequest empty;
  EXPECT_EQ(Create(*stub, empty).status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);

  v1::CreateObjectRequest garbage;
  garbage.mutable_sketch()->set_image(std::string("\x89PNG\r\n\x1a\n garbage", 17));
  Created g = Create(*stub, garbage);
  EXPECT_EQ(g.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << g.status.error_message();

  v1::CreateObjectRequest thick = BeanRequest();
  thick.mutable_mesh_options()->set_thickness(1000);
  Created t = Create(*stub, thick);
  EXPECT_EQ(t.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(t.status.error_message().find("thickness"), std::string::npos);

  v1::CreateObjectRequest open;
  open.mutable_sketch()->set_strokes_json(
      R"({"width": 512, "height": 512, "strokes": [[[100,100],[300,100],[300,300]]]})");
  Created o = Create(*stub, open);
  EXPECT_EQ(o.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << o.status.error_message();

  Created late = Create(*stub, BeanRequest(), 1ms);
  EXPECT_EQ(late.status.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED);

  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::ListObjectsResponse list;
  ASSERT_TRUE(stub->ListObjects(&ctx, {}, &list).ok());
  ASSERT_GE(list.objects_size(), 1);
  bool found = false;
  for (const auto& obj : list.objects()) found = found || obj.id() == good.object.id();
  EXPECT_TRUE(found) << "the good object must still be stored";
}

TEST(RheodObjects, TinyAndHugeNumbersAreSpelledInTheErrors) {
  RheodProcess d;
  ASSERT_TRUE(d.started()) << d.log();
  auto stub = v1::ObjectService::NewStub(d.channel());
  // A resolution of 1e-9 m reads as such, not as 0.000000.
  v1::CreateObjectRequest fine = BeanRequest();
  fine.mutable_mesh_options()->set_resolution(1e-9);
  Created f = Create(*stub, fine);
  EXPECT_EQ(f.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(f.status.error_message().find("got 1e-09"), std::string::npos)
      << f.status.error_message();
  EXPECT_NE(f.status.error_message().find("between 0.0005 and 0.5 m"), std::string::npos)
      << f.status.error_message();
  // Contours 1e100 and 1e300 px across: a clear refusal, not a wrapped-around count.
  auto circle = [](double diameter) {
    v1::CreateObjectRequest req;
    for (int i = 0; i < 64; ++i) {
      auto* p = req.mutable_sketch()->mutable_contour()->add_points();
      p->set_x(0.5 * diameter * (1.0 + std::cos(2 * M_PI * i / 64)));
      p->set_y(0.5 * diameter * (1.0 + std::sin(2 * M_PI * i / 64)));
    }
    return req;
  };
  Created big = Create(*stub, circle(1e100));
  EXPECT_EQ(big.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED)
      << big.status.error_code() << " " << big.status.error_message();
  EXPECT_NE(big.status.error_message().find("e+"), std::string::npos) << big.status.error_message();
  EXPECT_EQ(big.status.error_message().find("-92233720"), std::string::npos)
      << big.status.error_message();
  Created huge = Create(*stub, circle(1e300));
  EXPECT_EQ(huge.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT)
      << huge.status.error_code() << " " << huge.status.error_message();
  EXPECT_NE(huge.status.error_message().find("too large"), std::string::npos)
      << huge.status.error_message();
}

TEST(RheodObjects, MeshSizeLimitIsResourceExhaustedNamingTheLimit) {
  RheodProcess d({"--max-tets", "1000"});
  ASSERT_TRUE(d.started()) << d.log();
  auto stub = v1::ObjectService::NewStub(d.channel());
  v1::CreateObjectRequest req = BeanRequest();
  req.mutable_mesh_options()->set_resolution(0.002);
  Created c = Create(*stub, req);
  EXPECT_EQ(c.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED)
      << c.status.error_message();
}

TEST(RheodScene, GetSceneReportsSleepingAsTheFramesDo) {
  RheodProcess d;
  ASSERT_TRUE(d.started()) << d.log();
  auto objects = v1::ObjectService::NewStub(d.channel());
  auto scene = v1::SceneService::NewStub(d.channel());
  auto frames = v1::FrameService::NewStub(d.channel());
  v1::CreateObjectRequest req = BeanRequest();
  req.mutable_mesh_options()->set_resolution(0.012);
  Created c = Create(*objects, req);
  ASSERT_TRUE(c.status.ok()) << c.status.error_message();
  grpc::ClientContext actx;
  SetDeadline(actx, 30s);
  v1::AddToSceneRequest add;
  add.set_object_id(c.object.id());
  add.set_preset("hard-jelly");
  add.set_integrator(v1::INTEGRATOR_IMPLICIT);
  auto* grip = add.add_overrides();
  grip->set_name("friction");
  grip->set_value(5.0);
  auto* rest = add.add_overrides();  // at rest soon after landing
  rest->set_name("sleep_speed");
  rest->set_value(0.02);
  v1::SceneObject so;
  grpc::Status s = scene->AddToScene(&actx, add, &so);
  ASSERT_TRUE(s.ok()) << s.error_message();
  {
    grpc::ClientContext gctx;
    SetDeadline(gctx);
    v1::Scene sc;
    ASSERT_TRUE(scene->GetScene(&gctx, {}, &sc).ok());
    ASSERT_EQ(sc.objects_size(), 1);
    EXPECT_FALSE(sc.objects(0).sleeping()) << "just placed 2 cm above the floor: falling";
  }
  // Wait until the frames say it sleeps, then pause so it stays so.
  grpc::ClientContext fctx;
  SetDeadline(fctx, 30s);
  v1::WatchFramesRequest w;
  w.set_rate_hz(20);
  auto reader = frames->WatchFrames(&fctx, w);
  v1::Frame f;
  bool asleep = false;
  while (!asleep && reader->Read(&f)) asleep = f.objects_size() == 1 && f.objects(0).sleeping();
  fctx.TryCancel();
  reader->Finish();
  ASSERT_TRUE(asleep) << "the bean never settled";
  grpc::ClientContext pctx;
  SetDeadline(pctx);
  v1::ControlRequest pause;
  pause.set_command(v1::RUN_COMMAND_PAUSE);
  v1::ControlResponse pr;
  ASSERT_TRUE(scene->Control(&pctx, pause, &pr).ok());
  std::this_thread::sleep_for(300ms);  // the hub's copy is at most 100 ms old
  grpc::ClientContext gctx;
  SetDeadline(gctx);
  v1::Scene sc;
  ASSERT_TRUE(scene->GetScene(&gctx, {}, &sc).ok());
  ASSERT_EQ(sc.objects_size(), 1);
  EXPECT_TRUE(sc.objects(0).sleeping());
}

TEST(RheodScene, ObjectFallsAndStreamsTopologyOnceThenPositions) {
  RheodProcess d;
  ASSERT_TRUE(d.started()) << d.log();
  auto objects = v1::ObjectService::NewStub(d.channel());
  auto scene = v1::SceneService::NewStub(d.channel());
  auto frames = v1::FrameService::NewStub(d.channel());
  v1::CreateObjectRequest req = BeanRequest();
  req.set_add_to_scene(true);
  Created c = Create(*objects, req);
  ASSERT_TRUE(c.status.ok()) << c.status.error_message();
  ASSERT_TRUE(c.progress.back().has_scene_object());
  const uint32_t instance = c.progress.back().scene_object().instance_id();

  auto set_k_v = [&](double value, v1::SetParametersResponse* r) {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    v1::SetParametersRequest set;
    set.set_instance_id(instance);
    auto* p = set.add_parameters();
    p->set_name("k_v");
    p->set_value(value);
    return scene->SetParameters(&ctx, set, r);
  };
  // Bad parameter: named with its range; nothing changes.
  {
    v1::SetParametersResponse r;
    grpc::Status s = set_k_v(-5, &r);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(s.error_message().find("k_v"), std::string::npos) << s.error_message();
  }
  {
    v1::SetParametersResponse r;
    ASSERT_TRUE(set_k_v(321, &r).ok());
    bool seen = false;
    for (const auto& q : r.parameters())
      if (q.name() == "k_v") seen = q.value() == 321;
    EXPECT_TRUE(seen);
  }

  grpc::ClientContext ctx;
  SetDeadline(ctx, 60s);
  v1::WatchFramesRequest w;
  w.set_rate_hz(20);
  w.set_max_frames(6);
  w.set_positions(true);
  auto reader = frames->WatchFrames(&ctx, w);
  std::vector<v1::Frame> got;
  v1::Frame f;
  while (reader->Read(&f)) got.push_back(f);
  ASSERT_TRUE(reader->Finish().ok());
  ASSERT_EQ(got.size(), 6u);
  ASSERT_EQ(got[0].topology_size(), 1);
  const auto& topo = got[0].topology(0);
  EXPECT_EQ(topo.instance_id(), instance);
  EXPECT_EQ(topo.triangles_size() % 3, 0);
  EXPECT_EQ(topo.triangles_size() / 3, static_cast<int>(c.object.mesh().surface_triangle_count()));
  for (size_t i = 1; i < got.size(); ++i) EXPECT_EQ(got[i].topology_size(), 0) << "topology once";
  ASSERT_EQ(got.back().objects_size(), 1);
  EXPECT_EQ(got.back().objects(0).positions_size(), static_cast<int>(3 * topo.vertex_count()));
  // Gravity: the object is placed with its lowest point 2 cm above the floor. It has fallen by
  // the first frame, or it falls after it (a slow tick under the sanitizers); a frame taken at
  // the impact can be followed by the bounce, so the last frame need not be the lowest. The floor
  // holds it in every frame.
  auto lowest = [](const v1::ObjectState& s) {
    float m = 1e9f;
    for (int i = 1; i < s.positions_size(); i += 3) m = std::min(m, s.positions(i));
    return m;
  };
  const float y0 = lowest(got.front().objects(0));
  float y_min = y0;
  for (size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].objects_size(), 1);
    const float y = lowest(got[i].objects(0));
    y_min = std::min(y_min, y);
    EXPECT_GT(y, -0.01f) << "frame " << i << ": the floor holds the object";
    // Each frame reports the object's volume (within 10 % of the mesh's while it falls and lands
    // on the organ preset), its kinetic energy, and no restores.
    const v1::ObjectState& o = got[i].objects(0);
    EXPECT_NEAR(o.volume(), c.object.mesh().surface_volume(),
                0.1 * c.object.mesh().surface_volume())
        << "frame " << i;
    EXPECT_GE(o.kinetic_energy(), 0.0);
    EXPECT_EQ(o.restores(), 0u);
  }
  // Something in the run was moving: the fall or the landing.
  double ke_max = 0.0;
  for (const auto& g : got) ke_max = std::max(ke_max, g.objects(0).kinetic_energy());
  EXPECT_TRUE(ke_max > 0.0 || got.back().objects(0).sleeping());
  EXPECT_TRUE(y0 < 0.019f || y_min < y0) << "first frame " << y0 << ", lowest " << y_min;

  grpc::ClientContext rctx;
  SetDeadline(rctx);
  v1::RemoveFromSceneRequest rm;
  rm.set_instance_id(instance);
  v1::RemoveFromSceneResponse rr;
  ASSERT_TRUE(scene->RemoveFromScene(&rctx, rm, &rr).ok());
  grpc::ClientContext sctx;
  SetDeadline(sctx);
  v1::Scene sc;
  ASSERT_TRUE(scene->GetScene(&sctx, {}, &sc).ok());
  EXPECT_EQ(sc.objects_size(), 0);
}

TEST(RheodObjects, TheBackgroundPhotoMustBeAPictureSketchPadsCanOpen) {
  RheodProcess d;
  ASSERT_TRUE(d.started()) << d.log();
  auto stub = v1::ObjectService::NewStub(d.channel());
  v1::CreateObjectRequest req = BeanRequest();
  req.mutable_mesh_options()->set_resolution(0.012);
  std::string noise(3u << 20, '\0');
  for (size_t i = 0; i < noise.size(); ++i) noise[i] = static_cast<char>((i * 2654435761u) >> 13);
  req.mutable_sketch()->set_background_image(noise);
  Created bad = Create(*stub, req);
  EXPECT_EQ(bad.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT)
      << bad.status.error_message();
  EXPECT_NE(bad.status.error_message().find("background_image"), std::string::npos)
      << bad.status.error_message();
  // A broken PNG: the right signature, then garbage.
  std::string png = ReadText(SketchPath("bean.photo.png"));
  req.mutable_sketch()->set_background_image(png.substr(0, png.size() / 2));
  Created cut = Create(*stub, req);
  EXPECT_EQ(cut.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT)
      << cut.status.error_message();
  req.mutable_sketch()->set_background_image(png);
  Created good = Create(*stub, req);
  ASSERT_TRUE(good.status.ok()) << good.status.error_message();
  EXPECT_TRUE(good.object.has_background_image());
  // Nothing of the refused ones was stored.
  grpc::ClientContext lctx;
  SetDeadline(lctx);
  v1::ListObjectsResponse list;
  ASSERT_TRUE(stub->ListObjects(&lctx, {}, &list).ok());
  EXPECT_EQ(list.objects_size(), 1);
}

TEST(RheodObjects, TheStoreQuotaRefusesClearlyAndKeepsWhatIsStored) {
  RheodProcess d({"--store-quota", "1"});  // 1 MB: a few objects with a 150 kB photo each
  ASSERT_TRUE(d.started()) << d.log();
  auto stub = v1::ObjectService::NewStub(d.channel());
  v1::CreateObjectRequest req = BeanRequest();
  req.mutable_mesh_options()->set_resolution(0.012);
  req.mutable_sketch()->set_background_image(ReadText(SketchPath("bean.photo.png")));
  std::vector<std::string> stored;
  Created c;
  for (int i = 0; i < 20; ++i) {
    c = Create(*stub, req);
    if (!c.status.ok()) break;
    stored.push_back(c.object.id());
  }
  ASSERT_EQ(c.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED)
      << c.status.error_message();
  EXPECT_NE(c.status.error_message().find("quota"), std::string::npos) << c.status.error_message();
  EXPECT_GE(stored.size(), 2u);
  EXPECT_LE(stored.size(), 7u);
  for (const std::string& id : stored) {
    grpc::ClientContext gctx;
    SetDeadline(gctx);
    v1::GetObjectRequest g;
    g.set_id(id);
    v1::Object o;
    EXPECT_TRUE(stub->GetObject(&gctx, g, &o).ok()) << id;
  }
  // Deleting one makes room for one more.
  {
    grpc::ClientContext dctx;
    SetDeadline(dctx);
    v1::DeleteObjectRequest del;
    del.set_id(stored.front());
    v1::DeleteObjectResponse r;
    ASSERT_TRUE(stub->DeleteObject(&dctx, del, &r).ok());
  }
  EXPECT_TRUE(Create(*stub, req).status.ok());
}

TEST(RheodObjects, ARetryWithTheSameRequestIdGetsTheObjectAlreadyStored) {
  RheodProcess d;
  ASSERT_TRUE(d.started()) << d.log();
  auto stub = v1::ObjectService::NewStub(d.channel());
  v1::CreateObjectRequest req = BeanRequest();
  req.mutable_mesh_options()->set_resolution(0.012);
  req.set_request_id("pad-3-attempt-a");
  req.set_add_to_scene(true);
  Created first = Create(*stub, req);
  ASSERT_TRUE(first.status.ok()) << first.status.error_message();
  EXPECT_FALSE(first.progress.back().replayed());
  // The retry (its client never saw the answer): the same object and scene instance, built once.
  Created again = Create(*stub, req);
  ASSERT_TRUE(again.status.ok()) << again.status.error_message();
  ASSERT_FALSE(again.progress.empty());
  EXPECT_TRUE(again.progress.back().replayed());
  EXPECT_EQ(again.object.id(), first.object.id());
  EXPECT_EQ(again.progress.back().scene_object().instance_id(),
            first.progress.back().scene_object().instance_id());
  // A cut connection: the client goes away after the store stage began; the retry finds what
  // that attempt stored, or builds it if the cut came first. Either way one object, not two.
  req.set_request_id("pad-3-attempt-b");
  req.set_add_to_scene(false);
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx, 120s);
    auto reader = stub->CreateObject(&ctx, req);
    v1::CreateObjectProgress p;
    while (reader->Read(&p))
      if (p.stage() == "store") {
        ctx.TryCancel();
        break;
      }
    (void)reader->Finish();
  }
  Created retry = Create(*stub, req);
  ASSERT_TRUE(retry.status.ok()) << retry.status.error_message();
  grpc::ClientContext lctx;
  SetDeadline(lctx);
  v1::ListObjectsResponse list;
  ASSERT_TRUE(stub->ListObjects(&lctx, {}, &list).ok());
  EXPECT_EQ(list.objects_size(), 2) << "an orphan was stored";
  // A request id over 128 bytes is refused, quoting only its start.
  req.set_request_id(std::string(200, 'r'));
  Created longer = Create(*stub, req);
  EXPECT_EQ(longer.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
}

}  // namespace
}  // namespace rheo::testing
