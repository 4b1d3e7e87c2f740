// `rheoctl record start|stop|list|export|delete|playback`: session recordings (MCAP files on the
// daemon), and the playback of rheod --replay.
#include <google/protobuf/util/time_util.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <string>

#include "rheo/v1/recording.grpc.pb.h"
#include "rheoctl.h"

namespace rheoctl {
namespace {

using RecordingStub = rheo::v1::RecordingService::Stub;
using google::protobuf::util::TimeUtil;

const char* StateWord(rheo::v1::RecordingState s) {
  switch (s) {
    case rheo::v1::RECORDING_STATE_RECORDING: return "recording";
    case rheo::v1::RECORDING_STATE_COMPLETE: return "complete";
    case rheo::v1::RECORDING_STATE_FAILED: return "failed";
    case rheo::v1::RECORDING_STATE_TRUNCATED: return "truncated";
    default: return "unknown";
  }
}

std::string Size(uint64_t bytes) {
  char b[32];
  if (bytes >= (uint64_t{1} << 20))
    std::snprintf(b, sizeof b, "%.1f MiB", static_cast<double>(bytes) / 1048576.0);
  else
    std::snprintf(b, sizeof b, "%.1f KiB", static_cast<double>(bytes) / 1024.0);
  return b;
}

// "rec-... complete: 12.3 s, 1.2 MiB; /tool 12301, /frames 738, ...; 0 ticks dropped".
std::string Summary(const rheo::v1::Recording& r) {
  char head[256];
  std::snprintf(head, sizeof head, "%s %s: %.1f s, %s", r.id().c_str(), StateWord(r.state()),
                r.duration_s(), Size(r.bytes()).c_str());
  std::string s = head;
  std::string counts;
  for (const char* topic : {"/tool", "/frames", "/scene", "/parameters", "/commands", "/loop"}) {
    auto it = r.message_counts().find(topic);
    if (it == r.message_counts().end()) continue;
    counts += (counts.empty() ? "" : ", ") + std::string(topic) + " " + std::to_string(it->second);
  }
  if (!counts.empty()) s += "; " + counts;
  s += "; " + std::to_string(r.dropped_ticks()) + " ticks dropped";
  if (r.dropped_events() > 0) s += ", " + std::to_string(r.dropped_events()) + " events dropped";
  if (!r.error().empty()) s += "\n  " + r.error();
  return s;
}

int Start(const Global& g, const std::string& name, bool frames_given, double frames_hz,
          bool json) {
  rheo::v1::StartRecordingRequest req;
  req.set_name(name);
  if (frames_given) req.set_frames_hz(frames_hz);
  rheo::v1::Recording r;
  grpc::Status s =
      Unary<rheo::v1::RecordingService>(g, &RecordingStub::StartRecording, req, &r, 10.0);
  if (!s.ok()) return Fail(s);
  if (json) {
    std::cout << ToJson(r, true);
  } else {
    std::cout << r.id() << "\n";
    std::cerr << "recording " << r.id() << " ('" << r.name() << "') started into " << r.file()
              << (r.frames_hz() > 0 ? ", frames at " + std::to_string(int(r.frames_hz())) + " Hz"
                                    : std::string(", no frames"))
              << "; stop it with: rheoctl record stop\n";
  }
  return 0;
}

int Stop(const Global& g, bool json) {
  rheo::v1::Recording r;
  grpc::Status s = Unary<rheo::v1::RecordingService>(g, &RecordingStub::StopRecording,
                                                     rheo::v1::StopRecordingRequest(), &r, 30.0);
  if (!s.ok()) return Fail(s);
  std::cout << (json ? ToJson(r, true) : Summary(r) + "\n");
  return r.state() == rheo::v1::RECORDING_STATE_COMPLETE ? 0 : 1;
}

int List(const Global& g, bool json) {
  rheo::v1::ListRecordingsResponse r;
  grpc::Status s = Unary<rheo::v1::RecordingService>(g, &RecordingStub::ListRecordings,
                                                     rheo::v1::ListRecordingsRequest(), &r);
  if (!s.ok()) return Fail(s);
  if (json) {
    std::cout << ToJson(r, true);
    return 0;
  }
  if (r.recordings().empty()) {
    std::cout << "no recordings (start one with: rheoctl record start)\n";
    return 0;
  }
  std::printf("%-26s %-10s %-20s %9s %10s %8s  %s\n", "ID", "STATE", "STARTED (UTC)", "SECONDS",
              "SIZE", "DROPPED", "NAME");
  for (const auto& x : r.recordings()) {
    std::string started = TimeUtil::ToString(x.started()).substr(0, 19);
    std::printf("%-26s %-10s %-20s %9.1f %10s %8llu  %s\n", x.id().c_str(), StateWord(x.state()),
                started.c_str(), x.duration_s(), Size(x.bytes()).c_str(),
                static_cast<unsigned long long>(x.dropped_ticks()), x.name().c_str());
    if (!x.error().empty()) std::printf("  %s\n", x.error().c_str());
  }
  return 0;
}

// Streams the file into OUT (through OUT.part, renamed once complete) or to stdout.
int Export(const Global& g, const std::string& id, const std::string& out_path) {
  auto stub = rheo::v1::RecordingService::NewStub(Connect(g));
  grpc::ClientContext ctx;
  SetDeadline(ctx, g, 600.0);
  rheo::v1::ExportRecordingRequest req;
  req.set_id(id);
  const bool to_stdout = out_path.empty() || out_path == "-";
  const std::string part = out_path + ".part";
  std::ofstream file;
  if (!to_stdout) {
    file.open(part, std::ios::binary | std::ios::trunc);
    if (!file) {
      std::cerr << "cannot write " << part << ": " << std::strerror(errno) << "\n";
      return 1;
    }
  }
  std::ostream& out = to_stdout ? std::cout : file;
  auto reader = stub->ExportRecording(&ctx, req);
  rheo::v1::RecordingChunk c;
  uint64_t bytes = 0;
  while (reader->Read(&c)) {
    out.write(c.data().data(), static_cast<std::streamsize>(c.data().size()));
    bytes += c.data().size();
  }
  grpc::Status s = reader->Finish();
  if (!to_stdout) {
    file.close();
    if (!s.ok() || !file) {
      std::remove(part.c_str());
      if (s.ok()) {
        std::cerr << "cannot write " << part << ": " << std::strerror(errno) << "\n";
        return 1;
      }
    } else if (std::rename(part.c_str(), out_path.c_str()) != 0) {
      std::cerr << "cannot rename " << part << " to " << out_path << ": " << std::strerror(errno)
                << "\n";
      return 1;
    }
  }
  if (!s.ok()) return Fail(s);
  if (!to_stdout) std::cerr << "wrote " << bytes << " bytes to " << out_path << "\n";
  return 0;
}

int Delete(const Global& g, const std::string& id) {
  rheo::v1::DeleteRecordingRequest req;
  req.set_id(id);
  rheo::v1::DeleteRecordingResponse r;
  grpc::Status s = Unary<rheo::v1::RecordingService>(g, &RecordingStub::DeleteRecording, req, &r);
  return s.ok() ? 0 : Fail(s);
}

}  // namespace

// rheod --replay: where the playback is, and pause, play, step, seek, speed.
int Playback(const Global& g, bool pause, bool play, bool step, const double* seek,
             const double* speed, bool json) {
  rheo::v1::Playback r;
  grpc::Status s;
  if (pause || play || step || seek || speed) {
    rheo::v1::ControlPlaybackRequest req;
    if (speed) req.set_speed(*speed);
    if (seek) req.set_seek_s(*seek);
    if (pause) req.set_paused(true);
    if (play) req.set_paused(false);
    req.set_step(step);
    s = Unary<rheo::v1::RecordingService>(g, &RecordingStub::ControlPlayback, req, &r);
  } else {
    s = Unary<rheo::v1::RecordingService>(g, &RecordingStub::GetPlayback,
                                          rheo::v1::GetPlaybackRequest(), &r);
  }
  if (!s.ok()) return Fail(s);
  if (json) {
    std::cout << ToJson(r, true);
    return 0;
  }
  std::printf("%s: %s at %.2f of %.2f s (tick %llu), speed %gx; %llu frames, %llu shown\n",
              r.file().c_str(),
              r.ended()    ? "ended"
              : r.paused() ? "paused"
                           : "playing",
              r.position_s(), r.duration_s(), static_cast<unsigned long long>(r.tick()), r.speed(),
              static_cast<unsigned long long>(r.frames()),
              static_cast<unsigned long long>(r.frames_shown()));
  return 0;
}

void AddRecordCommand(CLI::App& app, const Global& g) {
  struct Args {
    std::string name, id, out;
    double frames_hz = 60.0;
    bool json = false;
  };
  auto a = std::make_shared<Args>();
  auto* record = app.add_subcommand(
      "record", "session recordings (MCAP): the tool every tick, frames, scene, commands");
  record->require_subcommand(1);
  auto* start = record->add_subcommand("start", "start recording; prints the recording's id");
  start->add_option("--name", a->name, "label (default: the id)");
  auto* frames = start
                     ->add_option("--frames-hz", a->frames_hz,
                                  "frames with positions per second, 1..1000; 0: none")
                     ->capture_default_str();
  start->add_flag("--json", a->json, "the Recording as JSON");
  start->callback([&g, a, frames] {
    g_exit_code = Start(g, a->name, frames->count() > 0, a->frames_hz, a->json);
  });
  auto* stop = record->add_subcommand("stop", "stop the running recording (summary and footer)");
  stop->add_flag("--json", a->json, "the Recording as JSON");
  stop->callback([&g, a] { g_exit_code = Stop(g, a->json); });
  auto* list = record->add_subcommand("list", "every recording with its state, size and drops");
  list->add_flag("--json", a->json, "as JSON");
  list->callback([&g, a] { g_exit_code = List(g, a->json); });
  auto* exp = record->add_subcommand("export", "download a recording's MCAP file");
  exp->add_option("ID", a->id, "recording id")->required();
  exp->add_option("--out", a->out, "output file (- for stdout)")->required();
  exp->callback([&g, a] { g_exit_code = Export(g, a->id, a->out); });
  auto* del = record->add_subcommand("delete", "delete a recording and its file");
  del->add_option("ID", a->id, "recording id")->required();
  del->callback([&g, a] { g_exit_code = Delete(g, a->id); });

  struct PlayArgs {
    bool pause = false, play = false, step = false, json = false;
    double seek = 0.0, speed = 1.0;
  };
  auto p = std::make_shared<PlayArgs>();
  auto* play = record->add_subcommand(
      "playback", "rheod --replay: where the playback is; pause, play, step, seek, speed");
  auto* pause_flag = play->add_flag("--pause", p->pause, "pause (every client sees it)");
  play->add_flag("--play", p->play, "play (at the end: from the start)")->excludes(pause_flag);
  play->add_flag("--step", p->step, "while paused: the next frame");
  auto* seek = play->add_option("--seek", p->seek, "go to this time from the first frame [s]");
  auto* speed = play->add_option("--speed", p->speed, "playback speed, (0, 100]; 1: recorded pace");
  play->add_flag("--json", p->json, "the Playback as JSON");
  play->callback([&g, p, seek, speed] {
    g_exit_code = Playback(g, p->pause, p->play, p->step, seek->count() ? &p->seek : nullptr,
                           speed->count() ? &p->speed : nullptr, p->json);
  });
}

}  // namespace rheoctl
