// rheo replay FILE: re-runs a session recording offline and says how far it is from the recorded
// frames and tool forces (bit-identical on the build that recorded it).
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "commands.h"
#include "daemon/replay/replay.h"
#include "sim/params.h"

namespace rheo::tools {
namespace {

struct ReplayArgs {
  std::string file;
  std::vector<std::string> sets;
  bool check = false;
};

std::string Bits(uint64_t same, uint64_t all) {
  return std::to_string(same) + " of " + std::to_string(all) + " bit for bit";
}

int RunReplay(const ReplayArgs& a) {
  daemon::ReplayOptions options;
  for (const std::string& s : a.sets) {
    std::string name;
    double value = 0.0;
    if (!sim::ParseSetting(s, &name, &value)) {
      std::cerr << "rheo replay: --set expects name=number, got '" << s << "'\n";
      return 1;
    }
    options.set.emplace_back(name, value);
  }
  auto r = daemon::ReplayRecording(a.file, options);
  if (!r.ok()) {
    std::cerr << "rheo replay: " << r.error().message << "\n";
    return 1;
  }
  std::printf("%s: ticks %llu..%llu replayed (%llu) in %.2f s, %llu objects, %llu commands\n",
              r->file.c_str(), static_cast<unsigned long long>(r->first_tick),
              static_cast<unsigned long long>(r->last_tick),
              static_cast<unsigned long long>(r->ticks), r->wall_s,
              static_cast<unsigned long long>(r->objects),
              static_cast<unsigned long long>(r->commands));
  std::printf("frames: %s; largest position difference %.3g m (tick %llu)\n",
              Bits(r->frames_identical, r->frames_compared).c_str(), r->max_position_diff_m,
              static_cast<unsigned long long>(r->max_position_tick));
  std::printf(
      "tool: %s (%llu in contact); largest object force difference %.3g N (tick %llu), proxy "
      "%.3g m\n",
      Bits(r->samples_identical, r->samples_compared).c_str(),
      static_cast<unsigned long long>(r->contact_ticks), r->max_force_diff_n,
      static_cast<unsigned long long>(r->max_force_tick), r->max_proxy_diff_m);
  if (r->first_difference_tick != 0)
    std::printf("first difference at tick %llu\n",
                static_cast<unsigned long long>(r->first_difference_tick));
  for (const std::string& c : r->caveats) std::printf("caveat: %s\n", c.c_str());
  const bool identical = r->bit_identical();
  std::printf("replay: %s\n", identical ? "bit-identical" : "differs from the recording");
  return a.check && !identical ? 3 : 0;
}

}  // namespace

void AddReplayCommand(CLI::App& app) {
  auto a = std::make_shared<ReplayArgs>();
  CLI::App* cmd = app.add_subcommand(
      "replay",
      "re-run a session recording (.mcap from rheod) and compare it with what it recorded");
  cmd->add_option("file", a->file, "the recording (rheoctl record export ID --out FILE)")
      ->required();
  cmd->add_option("--set", a->sets,
                  "parameter value put over every object's, name=value (repeatable): a what-if "
                  "replay measured against the recording");
  cmd->add_flag("--check", a->check,
                "exit with 3 unless the replay is bit-identical (no caveats, every frame and "
                "tool sample the same)");
  cmd->callback([a]() { g_exit_code = RunReplay(*a); });
}

}  // namespace rheo::tools
