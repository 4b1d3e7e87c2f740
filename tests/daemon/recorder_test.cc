// The session recorder without gRPC: ticks run by the test thread far faster than the recorder
// writes them overflow the ring, and the recording says how many it lost (in its Recording and
// in the file's /loop channel), with the lost ticks the only gaps in /tool; and a directory with
// damaged files lists each one with what went wrong instead of failing the start.
#include "daemon/record/recorder.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <memory>

#include "daemon/loop/engine.h"
#include "daemon/loop/frame_hub.h"
#include "daemon/loop/tick_ring.h"
#include "record/mcap.h"

namespace rheo::daemon {
namespace {

namespace fs = std::filesystem;

struct TempDir {
  TempDir() {
    char tmpl[] = "/tmp/rheo-recorder-XXXXXX";
    path = ::mkdtemp(tmpl);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string path;
};

struct Rig {
  explicit Rig(const std::string& dir) : engine(Options()), hub(engine) {
    engine.AttachTickRing(ring.get());
    RecorderOptions o;
    o.dir = dir;
    o.fill_loop_status = [this](v1::LoopStatus* l) { l->set_ticks(ticks); };
    recorder = std::make_unique<Recorder>(engine, hub, *ring, o);
  }
  static EngineOptions Options() {
    EngineOptions eo;
    eo.loop.realtime_priority = false;
    eo.loop.lock_memory = false;
    eo.max_frame_vertices = 100;
    return eo;
  }
  // Ticks run here, one after the other (the engine's own thread is never started).
  void Run(uint64_t n) {
    for (uint64_t i = 0; i < n; ++i, ++ticks) {
      rt::TickInfo info;
      info.tick = ticks;
      info.dt = 1e-3;
      info.deadline_ns = info.start_ns = rt::Loop::NowNs();
      engine.TickOnce(info);
    }
  }
  Engine engine;
  FrameHub hub;  // not started: the recordings here take no frames
  std::unique_ptr<TickRing> ring = std::make_unique<TickRing>();
  std::unique_ptr<Recorder> recorder;
  uint64_t ticks = 0;
};

TEST(Recorder, AFullRingDropsTicksAndTheRecordingCountsThem) {
  TempDir dir;
  Rig rig(dir.path);
  ASSERT_TRUE(rig.recorder->Load().ok());
  auto started = rig.recorder->Start("burst", 0.0, {});
  ASSERT_TRUE(started.ok()) << started.error().message;
  // About a million ticks a second from this thread: the recorder cannot keep up.
  rig.Run(200'000);
  auto done = rig.recorder->Stop();
  ASSERT_TRUE(done.ok()) << done.error().message;
  ASSERT_EQ(done->state(), v1::RECORDING_STATE_COMPLETE) << done->error();
  EXPECT_GT(done->dropped_ticks(), 0u) << "the ring never overflowed; the test proves nothing";
  EXPECT_EQ(done->dropped_ticks(), rig.ring->dropped());
  EXPECT_GT(done->ring_peak(), TickRing::kCapacity / 2);

  auto reader = record::McapReader::OpenFile(done->file());
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  uint64_t samples = 0, gaps = 0, last = 0;
  v1::LoopSample last_loop;
  Status s = reader->ForEachMessage([&](const record::Message& m) {
    if (m.channel->topic == kToolTopic) {
      v1::ToolSample t;
      EXPECT_TRUE(t.ParseFromArray(m.data.data(), static_cast<int>(m.data.size())));
      if (samples > 0) gaps += t.tick() - last - 1;
      last = t.tick();
      ++samples;
    } else if (m.channel->topic == kLoopTopic) {
      EXPECT_TRUE(last_loop.ParseFromArray(m.data.data(), static_cast<int>(m.data.size())));
    }
    return Status::Ok();
  });
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(samples, done->message_counts().at(kToolTopic));
  // The dropped ticks are the only gaps, and the ticks after the last one recorded.
  EXPECT_EQ(gaps + (done->last_tick() - last), done->dropped_ticks());
  EXPECT_EQ(samples + done->dropped_ticks(), done->last_tick() - done->first_tick() + 1);
  EXPECT_EQ(last_loop.dropped_ticks(), done->dropped_ticks()) << "/loop's last sample";
  EXPECT_EQ(last_loop.ring_peak(), done->ring_peak());
  std::printf("%llu ticks as fast as one thread runs them: %llu recorded, %llu dropped\n",
              static_cast<unsigned long long>(rig.ticks), static_cast<unsigned long long>(samples),
              static_cast<unsigned long long>(done->dropped_ticks()));

  // The next recording starts from zero.
  ASSERT_TRUE(rig.recorder->Start("calm", 0.0, {}).ok());
  for (int i = 0; i < 50; ++i) {
    rig.Run(10);
    usleep(1000);  // the recorder keeps up with ticks at about 10 kHz
  }
  auto calm = rig.recorder->Stop();
  ASSERT_TRUE(calm.ok());
  EXPECT_EQ(calm->dropped_ticks(), 0u);
  EXPECT_EQ(calm->message_counts().at(kToolTopic), calm->last_tick() - calm->first_tick() + 1);
}

TEST(Recorder, DamagedFilesAreListedWithWhatIsWrong) {
  TempDir dir;
  {
    std::ofstream(dir.path + "/rec-junk.mcap") << "not an MCAP file";
    // A side file whose fields have the wrong types, beside an empty recording.
    std::ofstream(dir.path + "/rec-typed.json") << R"({"name": 7, "state": ["x"]})";
  }
  {
    Rig rig(dir.path);
    ASSERT_TRUE(rig.recorder->Load().ok());
    ASSERT_TRUE(rig.recorder->Start("short", 0.0, {}).ok());
    rig.Run(20);
    auto r = rig.recorder->Stop();
    ASSERT_TRUE(r.ok());
    fs::rename(r->file(), dir.path + "/rec-typed.mcap");
    fs::remove(dir.path + "/" + r->id() + ".json");
  }
  Rig rig(dir.path);
  auto found = rig.recorder->Load();
  ASSERT_TRUE(found.ok()) << found.error().message;
  EXPECT_EQ(*found, 2u);
  std::map<std::string, v1::Recording> by_id;
  for (const v1::Recording& r : rig.recorder->List()) by_id[r.id()] = r;
  ASSERT_EQ(by_id.count("rec-junk"), 1u);
  EXPECT_EQ(by_id["rec-junk"].state(), v1::RECORDING_STATE_FAILED);
  EXPECT_NE(by_id["rec-junk"].error().find("cannot be read"), std::string::npos)
      << by_id["rec-junk"].error();
  ASSERT_EQ(by_id.count("rec-typed"), 1u);
  EXPECT_EQ(by_id["rec-typed"].state(), v1::RECORDING_STATE_COMPLETE);
  EXPECT_EQ(by_id["rec-typed"].name(), "rec-typed");
  EXPECT_EQ(by_id["rec-typed"].message_counts().at(kToolTopic), 20u);
  // Neither can be exported with a path outside the directory, and both can be deleted.
  EXPECT_EQ(rig.recorder->FileFor("../rec-junk").error().code, ErrorCode::kInvalidArgument);
  EXPECT_TRUE(rig.recorder->Delete("rec-junk").ok());
  EXPECT_FALSE(fs::exists(dir.path + "/rec-junk.mcap"));
  EXPECT_EQ(rig.recorder->FileFor("rec-junk").error().code, ErrorCode::kNotFound);
}

}  // namespace
}  // namespace rheo::daemon
