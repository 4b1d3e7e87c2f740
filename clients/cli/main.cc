// rheoctl: command-line client of rheod. Exit 0 on success; otherwise the gRPC status code
// (1..16) with "CODE: message" on stderr.
#include <CLI/CLI.hpp>

#include "rheoctl.h"

namespace rheoctl {
// Stays 1 when no command ran (the parser requires one).
int g_exit_code = 1;
}  // namespace rheoctl

int main(int argc, char** argv) {
  rheoctl::Global g;
  CLI::App app{"rheoctl: talk to a running rheod"};
  app.add_option("--server", g.server, "rheod address host:port")->capture_default_str();
  app.add_option("--timeout", g.timeout_s,
                 "deadline of each call [s] (default 5, object create 300)");
  app.require_subcommand(1);
  rheoctl::AddStatusCommands(app, g);
  rheoctl::AddObjectCommand(app, g);
  rheoctl::AddSceneCommand(app, g);
  rheoctl::AddParamCommand(app, g);
  rheoctl::AddDeviceCommand(app, g);
  rheoctl::AddContourCommand(app, g);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  return rheoctl::g_exit_code;
}
